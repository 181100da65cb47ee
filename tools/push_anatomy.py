"""Anatomy of a forward push on the standing simulated robot, period by period:
``python tools/push_anatomy.py --push 85 [--bow-gain 30 --bow-max 0.3] [--every 6]``.

The robot stands in its home posture through the full pipeline (default balancer) and gets one
0.2 s push on the torso at 1 s, as ``hubo sim --push N``. Each printed row: the time, the centre
of mass and the capture point (x + v / omega, omega = sqrt(g / 0.65 m)) ahead of the right
sole's toe edge (mm, the simulator's CoM; negative = behind it), the CoM speed, the two feet's
centre of pressure from the ankle F/T sensors ahead of the ankles (mm; the toe edge is
``feet.forward_m + length_m / 2`` = 130 mm), the right sole's and the torso's pitch (deg), the
limiter's clamps, the soft stopper's mode and the trunk bow.

``--bow-gain K`` adds a hip strategy for the experiment (not part of the pipeline): both hip
pitches bow the trunk forward (the ankles and knees with them so that the model's CoM stays
over the feet, 1.258 / 0.028 / 0.287 rad per rad of bow) at K rad/s per metre of the capture
point monitor's excess over ``--bow-start`` metres inside its shrunk support, at most
``--bow-rate`` rad/s and ``--bow-max`` rad (``--rise U``: the legs also rise, knees
straightening, U units of RISE_JOINTS_RAD per rad of bow); it needs the robot file's
``walking`` limit set (legs 2.6 rad/s, 150 rad/s^2), which the run then uses. The soft
stopper is off with it (its capture-point stop would hold the bow).
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import polars as pl

from hubo_cli.control.capture_point import CapturePointMonitor
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.target import Target
from hubo_cli.experiments.standing import StandTarget
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.session import RunSetup, run

# joint offsets per rad of trunk bow (hip pitch, knee, ankle pitch), solved on the model so that
# the torso pitches forward by 1 rad with the CoM's x and height unchanged (pinocchio)
BOW_JOINTS_RAD = {"HP": -1.258, "KN": -0.028, "AP": 0.287}
# ... and a rise on the legs: the knees straighten with the torso upright and the CoM's x kept
# (the neck rises 0.139 m per unit)
RISE_JOINTS_RAD = {"HP": 1.185, "KN": -2.185, "AP": 1.0}
OMEGA_1_S = math.sqrt(9.81 / 0.65)


class PushAnatomy(Target):
    """Stand (``stand``), optionally bow on the capture point, and record one row per period."""

    def __init__(self, stand: StandTarget, model, toe_m: float, bow_gain: float,
                 bow_start_m: float, bow_rate_rad_s: float, bow_max_rad: float,
                 rise_per_bow: float = 0.0) -> None:
        self.stand, self.toe_m = stand, toe_m
        self.log_columns = (*stand.log_columns, "bow_rad")
        self.bow_gain, self.bow_start_m = bow_gain, bow_start_m
        self.bow_rate_rad_s, self.bow_max_rad = bow_rate_rad_s, bow_max_rad
        self.bow_rad = 0.0
        self.per_bow_rad = {name: BOW_JOINTS_RAD[name] + rise_per_bow * RISE_JOINTS_RAD[name]
                            for name in BOW_JOINTS_RAD}
        self.period_s = model.control_period_s
        self.joints = {name: [model.joint_names.index(side + name) for side in "RL"]
                       for name in BOW_JOINTS_RAD}
        self.rows: list[dict] = []
        self.last_x_m: float | None = None

    def attach(self, world, modules, store) -> None:
        self.stand.attach(world, modules, store)
        self.monitor = next(m for m in modules if isinstance(m, CapturePointMonitor))

    def __call__(self, t_s: float, state):
        q, info = self.stand(t_s, state)
        q = q.copy()
        if self.bow_gain and state.time_s > 0.1:
            excess_m = self.monitor.outside_m + self.bow_start_m
            rate = min(self.bow_rate_rad_s, max(0.0, self.bow_gain * excess_m))
            self.bow_rad = min(self.bow_rad + rate * self.period_s, self.bow_max_rad)
        for name, per_rad in self.per_bow_rad.items():
            q[self.joints[name]] += per_rad * self.bow_rad
        self._record(t_s, state)
        return q, info | {"bow_rad": self.bow_rad}

    def _record(self, t_s: float, state) -> None:
        T_world_sole = self.truth.frame_pose("right_sole")
        toe_world_m = T_world_sole[:3, :3] @ np.array([self.toe_m, 0.0, 0.0]) + T_world_sole[:3, 3]
        x_m = float(self.truth.com_world_m()[0] - toe_world_m[0])
        v_m_s = 0.0 if self.last_x_m is None else (x_m - self.last_x_m) / self.period_s
        self.last_x_m = x_m
        fz = state.ft["right-ankle"][2] + state.ft["left-ankle"][2]
        my = state.ft["right-ankle"][4] + state.ft["left-ankle"][4]
        R_torso = state.truth.T_world_torso[:3, :3]
        self.rows.append({
            "t_s": round(t_s, 3), "com_mm": 1e3 * x_m, "v_m_s": v_m_s,
            "cp_mm": 1e3 * (x_m + v_m_s / OMEGA_1_S),
            "cop_mm": -1e3 * my / fz if fz > 1.0 else math.nan,
            "sole_deg": math.degrees(math.atan2(T_world_sole[0, 2], T_world_sole[2, 2])),
            "torso_deg": math.degrees(math.atan2(R_torso[0, 2], R_torso[2, 2])),
            "bow_rad": self.bow_rad})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--push", type=float, default=85.0, help="forward push (N), 0.2 s at 1 s")
    parser.add_argument("--duration", type=float, default=4.0, help="simulated time (s)")
    parser.add_argument("--bow-gain", type=float, default=0.0,
                        help="hip strategy: bow rate (rad/s) per metre of capture-point excess")
    parser.add_argument("--bow-start", type=float, default=0.06,
                        help="bow once the capture point is within this (m) of the shrunk edge")
    parser.add_argument("--bow-rate", type=float, default=1.0, help="largest bow rate (rad/s)")
    parser.add_argument("--bow-max", type=float, default=0.3, help="largest bow (rad)")
    parser.add_argument("--rise", type=float, default=0.0,
                        help="with the bow, rise on the legs by this many units per rad of bow")
    parser.add_argument("--every", type=int, default=6, help="print every n-th period")
    parser.add_argument("--out", default=None, help="run folder")
    args = parser.parse_args(argv)
    model = load_model("as-built", "walking" if args.bow_gain else "table4")
    q_home = home_posture(model)
    n = int(round(args.duration / model.control_period_s))
    stand = StandTarget(q_home, n, np.array([args.push, 0.0, 0.0]), 1.0, 0.2)
    feet = model.feet
    target = PushAnatomy(stand, model, feet.forward_m + feet.length_m / 2, args.bow_gain,
                         args.bow_start, args.bow_rate, args.bow_max, args.rise)
    setup = RunSetup(command="sim", model=model, driver="sim", out=args.out,
                     safety=SafetyProfile(estop=not args.bow_gain),
                     duration_s=n * model.control_period_s, q_start_rad=q_home)
    # this diagnosis measures the true push: it takes the simulator itself (a target gets the
    # scene's actions only)
    done = run(setup, target, on_start=lambda t, loop: setattr(t, "truth", loop.driver.world))
    rows = pl.DataFrame(target.rows)
    log = pl.read_csv(done.run_dir / "log.csv")
    wanted = ("t_s", "limiter_clamped_count", "limiter_ankle_clamped_count", "estop_mode_code",
              "cp_outside_m", "tilt_deg")  # no estop column without the soft stopper
    log = log.select([c for c in wanted if c in log.columns]).with_columns(pl.col("t_s").round(3))
    table = rows.join(log, on="t_s", how="left")
    with pl.Config(tbl_rows=-1, tbl_cols=-1, tbl_width_chars=200, float_precision=2):
        print(table.filter(pl.col("t_s") >= 0.95)[::args.every])
    clamped = int((table["limiter_clamped_count"].fill_null(0) > 0).sum())
    worst_tilt = float(table["tilt_deg"].fill_null(0.0).max())
    print(f"push {args.push:g} N: fell {stand.fell} (torso tilt up to {worst_tilt:.1f} deg), "
          f"feet moved {1e3 * stand.max_foot_shift_m:.1f} mm, periods with a limiter clamp "
          f"{clamped}, largest bow {target.bow_rad:.2f} rad")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
