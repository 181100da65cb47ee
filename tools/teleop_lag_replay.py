"""How much of a teleoperation run's hand error is the trajectory generator's lag, and what would
other ways of running it change?

Takes a ``hubo teleop`` run folder, the arms' logged joint targets while operating (what the
whole-body solver asked for, period by period) and replays them through ruckig offline under
the model's limits, starting from the logged command:

- ``whole body, phase``: one phase-synchronised tracker for every joint, as the pipeline's
  ``otg`` module runs for scripted tasks (an arm waits for the legs' and the other arm's slowest
  joint);
- ``own tracker, phase`` / ``own tracker, none``: each arm by a tracker of its own, its joints
  phase-synchronised or each time-optimal (``none`` is what teleoperation runs while operating);
- ``target velocity xG``: own tracker, phase, with ruckig's target velocity set to G times the
  targets' finite-difference velocity over the last ``--window-s`` (instead of 0: arrive moving);
- ``foresight N ms``: own tracker, phase, fed the target N ms ahead (a perfect prediction).

For each it prints the RMS and the largest distance between the tool at the replayed command and
at the target (arm FK, mm): the generator's share of the hand error only (no servo, no legs).

    python tools/teleop_lag_replay.py RUN_DIR [--window-s 0.07] [--arm-jerk 20]

``--arm-jerk`` replays under another jerk limit for the arms' joints (rad/s^3; the robot file's
is 4, 40 in its ``teleop`` limit set, which free-mode teleoperation runs with), everything else
as the model's.
"""

from __future__ import annotations

import argparse

import numpy as np

from hubo_cli.control.log import load_log
from hubo_cli.kinematics import get_limb
from hubo_cli.model import ARMS, load_model
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker


def replay(limits: JointLimits, dt_s: float, q0: np.ndarray, targets: np.ndarray,
           sync: str = "phase", gain: float = 0.0, window: int = 1, ahead: int = 0
           ) -> np.ndarray:
    """The tracker's samples (N x joints, rad) for ``targets`` (N x joints) from rest at ``q0``."""
    tracker = JointTracker(limits, dt_s, sync)
    tracker.reset(q0)
    out = np.empty_like(targets)
    last = len(targets) - 1
    for k in range(len(targets)):
        velocity = None
        if gain:
            j = max(0, k - window)
            velocity = gain * (targets[k] - targets[j]) / (max(1, k - j) * dt_s)
        out[k] = tracker.track(targets[min(last, k + ahead)], target_v_rad_s=velocity)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir")
    parser.add_argument("--window-s", type=float, default=0.07,
                        help="finite-difference window of the target velocity (s)")
    parser.add_argument("--arm-jerk", type=float, default=None,
                        help="the arms' jerk limit for the replay (rad/s^3; default: the model's)")
    args = parser.parse_args()
    model = load_model()
    dt_s = model.control_period_s
    log = load_log(args.run_dir)
    operating = np.asarray(log["phase_code"]) == 1
    if not operating.any():
        raise SystemExit("no operating periods in this log")
    names = list(model.joint_names)
    order = [log.joint_names.index(n) for n in names]
    targets = log.joints("target")[operating][:, order]
    commands = log.joints("cmd")[operating][:, order]
    tools = log.metadata.get("scene", {}).get("tools", {})
    limits = JointLimits.from_model(model)
    if args.arm_jerk is not None:
        for arm in ARMS:
            limits.jerk_rad_s3[model.limb_slice(arm)] = args.arm_jerk
    arms = [a for a in ARMS if np.ptp(targets[:, model.limb_slice(a)]) > 1e-3]
    limbs = {a: get_limb(a, tools.get(a, "hand")) for a in arms}

    def tool_mm(arm: str, q_arm: np.ndarray) -> np.ndarray:
        return np.array([limbs[arm].fk(q)[:3, 3] for q in q_arm]) * 1000

    goal = {a: tool_mm(a, targets[:, model.limb_slice(a)]) for a in arms}

    def row(label: str, arm: str, q_arm: np.ndarray) -> None:
        e = np.linalg.norm(tool_mm(arm, q_arm) - goal[arm], axis=1)
        print(f"{label:28s} {arm:10s} RMS {np.sqrt(np.mean(e**2)):6.2f} mm   max {e.max():6.1f} mm")

    whole = replay(limits, dt_s, commands[0], targets)
    window = max(1, round(args.window_s / dt_s))
    for arm in arms:
        sl = model.limb_slice(arm)
        own, q0, t = limits.subset(np.arange(len(names))[sl]), commands[0, sl], targets[:, sl]
        row("logged command", arm, commands[:, sl])
        row("whole body, phase", arm, whole[:, sl])
        row("own tracker, phase", arm, replay(own, dt_s, q0, t))
        row("own tracker, none", arm, replay(own, dt_s, q0, t, sync="none"))
        for gain in (0.5, 1.0):
            row(f"target velocity x{gain}", arm, replay(own, dt_s, q0, t, gain=gain,
                                                         window=window))
        for ms in (50, 100):
            row(f"foresight {ms} ms", arm, replay(own, dt_s, q0, t, ahead=round(ms / 1000 / dt_s)))


if __name__ == "__main__":
    main()
