"""``hubo fk`` and ``hubo ik``: forward and inverse kinematics of one limb."""

from __future__ import annotations

import click
import numpy as np
from rich.table import Table

from hubo_cli.cli.options import force_option
from hubo_cli.cli.output import console, fmt_q, print_json, warn
from hubo_cli.errors import InputError
from hubo_cli.kinematics.poses import MAX_INPUT_MAGNITUDE
from hubo_cli.model import LIMB_NAMES, TOOL_NAMES

LIMB = click.Choice(LIMB_NAMES)
PARAMS = click.option("--params", type=click.Choice(["as-built", "table1"]), default="as-built",
                      show_default=True, help="Kinematic parameter set.")
LIMITS = click.option("--limits", type=click.Choice(["table4", "team-code"]), default="table4",
                      show_default=True, help="Joint limit set.")
TOOL = click.option("--tool", type=click.Choice(TOOL_NAMES), default="hand", show_default=True,
                    help="Arm end frame (legs always end at the sole).")
JSON = click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
# negative joint values such as -0.99 must reach the arguments, not the option parser
NUMBERS_OK = {"ignore_unknown_options": True}


def _finite(option: str, values) -> None:
    """Refuse NaN, infinity and magnitudes no joint angle or length can have."""
    array = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(array)):
        raise InputError(f"{option} contains NaN or infinity", hint="give finite numbers")
    if np.any(np.abs(array) > MAX_INPUT_MAGNITUDE):
        raise InputError(f"{option} contains a number beyond {MAX_INPUT_MAGNITUDE:,.0f} "
                         f"({np.max(np.abs(array)):g})",
                         hint="joints are radians, positions millimetres")


def _pose_lines(T: np.ndarray) -> list[str]:
    from hubo_cli.geometry import matrix_to_rpy

    roll, pitch, yaw = np.degrees(matrix_to_rpy(T[:3, :3]))
    x, y, z = T[:3, 3] * 1000.0
    rows = [" ".join(f"{v:+.6f}" for v in row) for row in T[:3, :3]]
    return [f"position (mm)     x {x:+.3f}  y {y:+.3f}  z {z:+.3f}",
            f"roll-pitch-yaw    {roll:+.3f} {pitch:+.3f} {yaw:+.3f} deg (R = Rz Ry Rx)",
            f"rotation          {rows[0]}", f"                  {rows[1]}",
            f"                  {rows[2]}"]


def _pose_json(T: np.ndarray) -> dict:
    from hubo_cli.geometry import matrix_to_rpy

    return {"T": T, "position_mm": T[:3, 3] * 1000.0,
            "rpy_deg": np.degrees(matrix_to_rpy(T[:3, :3]))}


@click.command(context_settings=NUMBERS_OK)
@click.argument("limb", type=LIMB)
@click.argument("q", nargs=6, type=float)
@PARAMS
@TOOL
@JSON
def fk(limb: str, q: tuple[float, ...], params: str, tool: str, as_json: bool) -> None:
    """End-effector pose of LIMB for joints Q1..Q6 (rad), in the neck frame.

    Example: hubo fk right-arm -0.9914 -0.3651 -0.8339 -1.1618 -1.6542 0.8894 --tool drill
    """
    from hubo_cli.kinematics import get_limb

    _finite("Q1..Q6", q)
    chain = get_limb(limb, tool, params)
    T = chain.fk(np.array(q))
    outside = [f"{name} {v:+.3f} rad (limits {lo:+.2f} .. {hi:+.2f})" for name, v, lo, hi in
               zip(chain.spec.joints, q, chain.lower_rad, chain.upper_rad, strict=True)
               if not lo <= v <= hi]
    if as_json:
        print_json({"limb": limb, "tool": tool, "params": params, "q_rad": q,
                    "within_limits": not outside, **_pose_json(T)})
        return
    console.print(f"{limb} ({tool if 'arm' in limb else 'sole'}, {params}), q = {fmt_q(q)} rad")
    for line in _pose_lines(T):
        console.print(line)
    if outside:  # the pose is computed all the same: the robot could not take it
        warn("beyond the joint limits (the robot cannot take this pose): " + ", ".join(outside))


def _goal_from_options(matrix, xyz, rpy) -> np.ndarray:
    from hubo_cli.geometry import rpy_to_matrix
    from hubo_cli.kinematics.poses import is_rigid_transform, make_transform

    if matrix and (xyz is not None or rpy is not None):
        raise InputError("--matrix and --xyz/--rpy both give the goal",
                         hint="give the goal once: --matrix (16 numbers) or --xyz [--rpy]")
    if matrix:
        _finite("--matrix", matrix)
        T = np.array(matrix, dtype=float).reshape(4, 4)
        if not is_rigid_transform(T):
            raise InputError("--matrix is not a rigid transform",
                             hint="give 16 numbers row-major: an orthonormal rotation, metres, "
                                  "last row 0 0 0 1")
        return T
    if xyz is None:
        raise InputError("no goal given", hint="use --xyz X Y Z (mm) [--rpy R P Y (deg)], "
                                               "--matrix (16 numbers), or --batch IN.csv")
    rpy = rpy or (0.0, 0.0, 0.0)
    _finite("--xyz", xyz)
    _finite("--rpy", rpy)
    T = make_transform(rpy_to_matrix(*np.radians(rpy)), np.array(xyz) / 1000.0)
    if not np.all(np.isfinite(T)):
        raise InputError("the goal contains NaN or infinity", hint="give finite numbers")
    return T


@click.command(context_settings=NUMBERS_OK)
@click.argument("limb", type=LIMB)
@click.option("--matrix", nargs=16, type=float, default=None,
              help="Goal pose T_N_E, 16 numbers row-major, metres.")
@click.option("--xyz", nargs=3, type=float, default=None, help="Goal position X Y Z in mm.")
@click.option("--rpy", nargs=3, type=float, default=None,
              help="Goal roll pitch yaw in degrees (R = Rz Ry Rx); default 0 0 0.")
@click.option("--prev", nargs=6, type=float, default=None,
              help="Previous joints (rad): choose the solution closest to them.")
@click.option("--all", "show_all", is_flag=True, help="List all eight candidates.")
@click.option("--batch", "batch_in", type=click.Path(dir_okay=False), default=None,
              help="Solve every row of a CSV (columns T00..T33, optional qprev1..qprev6).")
@click.option("--out", "batch_out", type=click.Path(dir_okay=False), default=None,
              help="Output CSV for --batch (an existing file is not overwritten without "
                   "--force).")
@force_option
@PARAMS
@LIMITS
@TOOL
@JSON
def ik(limb, matrix, xyz, rpy, prev, show_all, batch_in, batch_out, force, params, limits,
       tool, as_json) -> None:
    """Joints that put LIMB's end frame at a goal pose in the neck frame.

    Prints the chosen joints, the status (exact, capped, held, unreachable) and the residual
    error. Exit code 0 when a solution was found (exact or capped), 5 otherwise. With
    --batch: every row gets a line in --out (never the input file); exit code 2 when any row
    was invalid (each is named by line and field on stderr; the others are still solved), else 0.

    Example: hubo ik right-arm --xyz 484 -170 75 --rpy 0 0 0 --tool drill
    """
    from hubo_cli.kinematics import get_limb

    solver = get_limb(limb, tool, params, limits)
    if batch_in and (matrix or xyz is not None or rpy is not None or prev is not None):
        raise InputError("--batch takes its goals (and previous joints) from the CSV",
                         hint="leave out --matrix, --xyz, --rpy and --prev with --batch")
    if prev is not None:
        _finite("--prev", prev)
    if batch_in:
        _batch(solver, batch_in, batch_out, force, as_json)
        return
    T = _goal_from_options(matrix, xyz, rpy)
    result = solver.solve(T, None if prev is None else np.array(prev))
    candidates = solver.candidates(T, prev) if show_all else []
    if as_json:
        print_json({
            "limb": limb, "tool": tool, "params": params, "limits": limits, "goal": T,
            "q_rad": result.q_rad, "status": result.status,
            "position_error_m": result.position_error_m,
            "rotation_error_rad": result.rotation_error_rad,
            "candidates": [{"q_rad": c.q_rad, "within_limits": c.within_limits,
                            "exact": c.exact, "position_error_m": c.position_error_m,
                            "rotation_error_rad": c.rotation_error_rad} for c in candidates],
        })
    else:
        style = {"exact": "green", "capped": "yellow"}.get(result.status, "red")
        console.print(f"q = {fmt_q(result.q_rad)} rad   [{style}]{result.status}[/]   "
                      f"error {result.position_error_m * 1000:.3g} mm, "
                      f"{np.degrees(result.rotation_error_rad):.3g} deg")
        if candidates:
            table = Table("#", "q (rad)", "in limits", "reaches goal", "error (mm)")
            for k, c in enumerate(candidates):
                table.add_row(str(k), fmt_q(c.q_rad), "yes" if c.within_limits else "no",
                              "yes" if c.exact else "no", f"{c.position_error_m * 1000:.3g}")
            console.print(table)
    if result.status not in ("exact", "capped"):
        raise SystemExit(5)


def _batch(solver, batch_in: str, batch_out: str | None, force: bool, as_json: bool) -> None:
    from hubo_cli.cli.output import warn
    from hubo_cli.kinematics.batch_csv import solve_csv

    if not batch_out:
        raise InputError("--batch needs --out OUT.csv", hint="add --out results.csv")
    report = solve_csv(solver, batch_in, batch_out, force=force)
    for line, reason in report.bad_lines[:20]:
        warn(f"{batch_in}:{line}: {reason}")
    if len(report.bad_lines) > 20:
        warn(f"... and {len(report.bad_lines) - 20} more bad rows")
    rate = report.rows / report.seconds if report.seconds > 0 else float("inf")
    summary = {"rows": report.rows, "solved": report.solved, "bad_rows": len(report.bad_lines),
               "status_counts": report.status_counts, "seconds": report.seconds,
               "rows_per_s": rate, "out": batch_out}
    if as_json:
        print_json(summary)
    else:
        counts = ", ".join(f"{k} {v}" for k, v in report.status_counts.items() if v)
        console.print(f"{report.rows} rows -> {batch_out} in {report.seconds:.2f} s "
                      f"({rate:,.0f} rows/s): {counts}")
    if report.invalid:
        raise SystemExit(InputError.exit_code)  # the good rows are written; the bad are named
