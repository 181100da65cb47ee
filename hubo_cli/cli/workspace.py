"""``hubo workspace-map``: where can the tool reach, and where should the robot stand."""

from __future__ import annotations

import time

import click

from hubo_cli.cli.output import console, err_console, fmt_q, print_json


def _ordered_range(ctx, param, value):
    """A range option's A B as given, A <= B (A A for one value); reversed is a usage error
    (click's exit 2), never swapped silently."""
    if value is not None and value[0] > value[1]:
        raise click.BadParameter(f"{value[0]:g} {value[1]:g} is reversed: give the smaller "
                                 f"value first ({value[1]:g} {value[0]:g})")
    return value


def _progress_bar():
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(TextColumn("{task.description}"), BarColumn(),
                    TextColumn("{task.percentage:>3.0f}%"), TimeElapsedColumn(),
                    console=err_console, transient=True,
                    disable=not err_console.is_terminal)


def _print_map(wmap, paper_pts) -> None:
    from hubo_cli.workspace import PAPER_BEST

    w, g, r = wmap.widest, wmap.widest_grid, wmap.best_rectangle
    mm = 1000.0
    out = console.print
    out(f"[bold]{wmap.arm} arm[/]: {wmap.tool}, {wmap.params} lengths, {wmap.limits} limits, "
        f"orientation {wmap.orientation}")
    out(f"  {wmap.grid.points:,} points at {wmap.grid.resolution_m * mm:g} mm in "
        f"{wmap.seconds:.2f} s")
    paper = wmap.paper_setup  # the paper's figures only apply to the drill at the wall
    out("                          best      grid" + ("     paper" if paper else ""))
    for label, best, grid, key in (
            ("wall distance (mm)", w.wall_distance_m, g.wall_distance_m, "wall_distance_mm"),
            ("segment width (mm)", w.width_m, g.width_m, "width_mm"),
            ("height above neck (mm)", w.z_m, g.z_m, "height_mm")):
        tail = f"    {PAPER_BEST[key]:6.0f}" if paper else ""
        out(f"  {label:<22}{best * mm:6.1f}    {grid * mm:6.1f}{tail}")
    out(f"  segment y {w.y_min_m * mm:+.1f} .. {w.y_max_m * mm:+.1f} mm, IK branch {w.branch}")
    out(f"  joints at min y   {fmt_q(w.q_min_rad)} rad")
    out(f"  joints at max y   {fmt_q(w.q_max_rad)} rad")
    if r.area_m2 > 0:
        out(f"  largest rectangle {r.width_m * mm:.0f} x {r.height_m * mm:.0f} mm at x = "
            f"{r.wall_distance_m * mm:.0f} mm")
        out(f"    y {r.y_min_m * mm:+.0f} .. {r.y_max_m * mm:+.0f} mm, "
            f"z {r.z_min_m * mm:+.0f} .. {r.z_max_m * mm:+.0f} mm, IK branch {r.branch}")
    else:
        out("  largest rectangle: none with an area (one height or distance was mapped)")
    for name, p in zip(("far right", "far left"), paper_pts, strict=False):
        x, y, z = p["position_mm"]
        state = (f"reachable (branch {', '.join(map(str, p['branches']))})" if p["reachable"]
                 else "NOT reachable")
        out(f"  paper's {name} end ({x:.1f}, {y:.1f}, {z:.1f}) mm: {state}")


@click.command("workspace-map")
@click.option("--arm", type=click.Choice(["right", "left", "both"]), default="right",
              show_default=True, help="Which arm to map (the left arm is computed, not mirrored).")
@click.option("--tool", type=click.Choice(["drill", "hand", "none"]), default="drill",
              show_default=True, help="End-effector frame whose position is mapped.")
@click.option("--orientation", default="wall", show_default=True,
              help="Tool orientation: 'wall' (tool x straight ahead, orthogonal to a wall facing "
                   "the robot) or 'roll,pitch,yaw' in degrees, each within ±360 (R = Rz Ry Rx).")
@click.option("--params", type=click.Choice(["as-built", "table1"]), default="as-built",
              show_default=True, help="Kinematic parameter set.")
@click.option("--limits", type=click.Choice(["table4", "team-code"]), default="table4",
              show_default=True, help="Joint limit set (team-code: arm joint 5 >= -2.0 rad).")
@click.option("--resolution", type=float, default=5.0, show_default=True, metavar="MM",
              help="Grid step in x, y and z (mm); the grid has at most 20 million points.")
@click.option("--x-range", nargs=2, type=float, default=(300.0, 650.0), show_default=True,
              metavar="A B", callback=_ordered_range,
              help="Wall distances from the neck to search (mm, within ±1000: the arms reach "
                   "630 at most); A A for one.")
@click.option("--z-range", nargs=2, type=float, default=None, metavar="A B",
              callback=_ordered_range,
              help="Heights above the neck to search (mm, within ±1000); A A pins the segment "
                   "to one height. "
                   "Default: every height the arm reaches.")
@click.option("--no-refine", is_flag=True,
              help="Report the grid's answer only (skip the sub-millimetre zoom).")
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="Run folder (default runs/<time>-workspace-map).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def workspace_map(arm, tool, orientation, params, limits, resolution, x_range, z_range,
                  no_refine, out, as_json) -> None:
    """Map where the tool reaches at a fixed orientation; find the best wall distance.

    For every wall distance x, finds the widest horizontal segment reachable on one IK branch
    (so the drill sweeps it without flipping the arm) and the largest reachable rectangle, then
    reports the distance with the widest segment (paper IV: 390 mm at 484 mm, 75 mm above the
    neck). Writes workspace.npz, summary.json and two plots into the run folder.
    """
    from hubo_cli.runs import reserved_run_dir

    with reserved_run_dir("workspace-map", out) as run:  # a bad --out fails before computing
        _workspace_map(run, arm, tool, orientation, params, limits, resolution, x_range,
                       z_range, no_refine, as_json)


def _workspace_map(run, arm, tool, orientation, params, limits, resolution, x_range, z_range,
                   no_refine, as_json) -> None:
    from hubo_cli.plots.workspace import plot_fig4, plot_widths
    from hubo_cli.runs import write_json
    from hubo_cli.workspace import compute_map
    from hubo_cli.workspace.files import paper_points, save_npz, summary

    arms = ["right", "left"] if arm == "both" else [arm]
    t0 = time.perf_counter()
    maps = []
    with _progress_bar() as bar:
        tasks: dict[str, int] = {}

        def progress(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done)

        for name in arms:
            maps.append(compute_map(name, tool, orientation, params, limits, resolution / 1000.0,
                                    (x_range[0] / 1000.0, x_range[1] / 1000.0),
                                    refine=not no_refine, progress=progress,
                                    z_range_m=z_range and (z_range[0] / 1000.0,
                                                           z_range[1] / 1000.0)))
    seconds = time.perf_counter() - t0
    data = summary(maps, seconds)
    save_npz(maps, run / "workspace.npz")
    plots = [run / f"workspace-fig4-{m.arm}.png" for m in maps] + [run / "width-vs-distance.png"]
    data["files"] = ["workspace.npz", "summary.json", *(p.name for p in plots)]
    write_json(run / "summary.json", data)  # before the plots: a reuse clears what it lists
    for m, path in zip(maps, plots, strict=False):
        plot_fig4(m, path)
    plot_widths(maps, plots[-1])
    if as_json:
        print_json({**data, "run_dir": str(run), "plots": [str(p) for p in plots]})
        return
    for m in maps:
        _print_map(m, paper_points(m))
    console.print(f"run folder: {run}")
    console.print(f"  workspace.npz, summary.json, {', '.join(p.name for p in plots)}")
