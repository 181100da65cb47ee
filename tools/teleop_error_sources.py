"""Where a teleop hand's error comes from, period by period, on generated operator streams.

Each stream is followed by ``stream_runs.follow_generated`` (the teleop target and the
trajectory generator alone, ideal driver). Every operating period and per hand, over the time
the goal is reachable (the summary's ``reachable_*`` figures), the hand's pose error against
the operator's goal splits into:

- *target*: the IK's target (the forward kinematics of the arm's joint target, lifted by the
  legs' target) against the goal: what the tracking law asked for (the orientation filter,
  the reach and collision-room relaxations, the joint margins);
- *tracking*: the measured hand against that target: the trajectory generator's lag;
- *filter*: the smoothed orientation (``orientation_time_constant_s``) against the goal's.

It also gives the share of the time the target was moved by the collision room or held at the
reach limit, and the share of the squared position error that fell in periods where a joint of
the arm accelerated toward its target at (95 % of) its acceleration limit: error a tracker that
moves each joint time-optimally toward its own target cannot take out (only trading one joint
against another, or knowing the stroke in advance, can).

    python tools/teleop_error_sources.py [--count 50] [--speed 0.25] [--duration 1.5]
    python tools/teleop_error_sources.py --seeds 9001 9002 --duration 8

(``--count N``: the first N streams of tests/test_teleop_streams.py's draw for that speed, its
first 50 at 0.25 m/s and its last 10 above.)
"""

from __future__ import annotations

import argparse

import numpy as np

from hubo_cli.control.keys import TRACKER_STATES
from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.kinematics.dh import pose_error
from hubo_cli.teleop.stream_runs import GENERATED_SETS, follow_generated

FIGURES = ("position_mm", "rotation_deg", "target_position_mm", "target_rotation_deg",
           "tracking_position_mm", "tracking_rotation_deg", "filter_rotation_deg")


def error_sources(seed: int, settings: StreamSettings) -> dict[str, dict]:
    """Per arm: the RMS over the reachable time of each part of the error (:data:`FIGURES`),
    ``room_share`` and ``limit_share`` (of the reachable time and of the operating time), and
    ``at_acceleration_limit_share`` (of the squared position error)."""
    rows: dict[str, list] = {}

    def observe(target, t_s):
        if target.phase != "operate":
            return
        lift_target, lift_measured = (target.body.lift_of(target.q_target),
                                      target.body.lift_of(target.q_measured_rad))
        trackers = target.store.get(TRACKER_STATES) or {}
        for arm in target.arms:
            goal = target.goals.get(arm)
            if goal is None or not target.mapper.is_calibrated(target.hand_of(arm)):
                continue
            limb, sl = target.body.arms[arm], target.slices[arm]
            T_target = limb.fk(target.q_target[sl]).copy()
            T_target[2, 3] += lift_target
            T_actual = limb.fk(target.q_measured_rad[sl]).copy()
            T_actual[2, 3] += lift_measured
            T_filtered = goal.copy()
            R_smoothed = target.reach[arm].R_smoothed
            if R_smoothed is not None:
                T_filtered[:3, :3] = R_smoothed
            state = trackers.get(arm)
            chasing = state is not None and bool(np.any(
                (np.abs(state.a_rad_s2) > 0.95 * state.limits.acceleration_rad_s2)
                & (np.sign(state.a_rad_s2) == np.sign(target.q_out[sl] - state.q_rad))))
            hand = target.hands[arm]
            rows.setdefault(arm, []).append((
                hand.reachable, *pose_error(T_actual, goal), *pose_error(T_target, goal),
                *pose_error(T_actual, T_target), pose_error(T_filtered, goal)[1],
                target.room is not None and arm in target.room.moved, hand.at_limit, chasing))

    follow_generated(seed, settings, observe)
    out = {}
    for arm, arm_rows in rows.items():
        a = np.array(arm_rows, dtype=float)
        ok = a[:, 0] > 0.5
        if not ok.any():
            out[arm] = None
            continue
        rms = np.sqrt(np.mean(a[ok, 1:8] ** 2, axis=0))
        scale = [1e3, np.degrees(1.0)] * 3 + [np.degrees(1.0)]
        figures = {name: float(v * s) for name, v, s in zip(FIGURES, rms, scale, strict=True)}
        squared = a[ok, 1] ** 2
        figures.update(
            reachable_share=float(ok.mean()), room_share=float(a[ok, 8].mean()),
            limit_share=float(a[:, 9].mean()),
            at_acceleration_limit_share=float(np.sum(squared * a[ok, 10]) / np.sum(squared))
            if squared.sum() > 0 else 0.0)
        out[arm] = figures
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=50)
    parser.add_argument("--seeds", type=int, nargs="*")
    parser.add_argument("--speed", type=float, default=0.25)
    parser.add_argument("--duration", type=float, default=1.5)
    args = parser.parse_args()
    seeds = args.seeds or GENERATED_SETS[0.25 if args.speed <= 0.25 else 0.6][:args.count]
    settings = StreamSettings(duration_s=args.duration, max_speed_m_s=args.speed)
    hands = []
    for seed in seeds:
        for arm, f in error_sources(seed, settings).items():
            if f is None:
                continue
            hands.append(f)
            print(f"seed {seed} {arm}: position {f['position_mm']:.1f} mm (target "
                  f"{f['target_position_mm']:.2f}, tracking {f['tracking_position_mm']:.1f}; "
                  f"{100 * f['at_acceleration_limit_share']:.0f} % of it at the acceleration "
                  f"limit), orientation {f['rotation_deg']:.1f} deg (target "
                  f"{f['target_rotation_deg']:.1f}, of it the filter "
                  f"{f['filter_rotation_deg']:.1f}; tracking {f['tracking_rotation_deg']:.1f}); "
                  f"reachable {100 * f['reachable_share']:.0f} %, room "
                  f"{100 * f['room_share']:.0f} %", flush=True)
    if len(hands) > 1:
        print(f"{len(hands)} hands, median / p90 / worst:")
        for name in (*FIGURES, "at_acceleration_limit_share"):
            v = np.array([h[name] for h in hands])
            print(f"  {name:30s} {np.median(v):7.2f} {np.percentile(v, 90):7.2f} {v.max():7.2f}")


if __name__ == "__main__":
    main()
