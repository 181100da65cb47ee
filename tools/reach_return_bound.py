"""How soon can a hand parked at its reach limit be back on a goal that walks back into reach?

The goal of the out-of-reach test (tests/test_teleop_reach.py) walks the right hand straight
forward from the free-mode ready pose to 30 cm beyond its reach and back along the same line
(minimum-jerk, ``--back`` seconds). Near the straight elbow only the elbow moves the hand
inward, so the question is one of the elbow: this script takes the elbow angle of the exact
position-only solution along the path and an ideal elbow that starts from rest at its parked
bend the moment the goal passes the parked hand, accelerates at the elbow's acceleration limit
up to its speed limit (no jerk limit, no braking, no speed scale: a lower bound), and prints
the first time it is back within 2 mm of the goal (measured along the path) after the goal is
reachable again, and the largest gap before that.

    python tools/reach_return_bound.py [--back 8] [--parked-bend 0.1 0.64]
"""

from __future__ import annotations

import argparse

import numpy as np

from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.reach import branch_of, nearest_on_branch
from hubo_cli.model import load_model
from hubo_cli.teleop.session import FREE_READY_ARM_RAD

ARM = "right-arm"


def _min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


def elbow_along_path(ahead_m: np.ndarray) -> tuple[np.ndarray, float]:
    """|theta4| (rad) of the exact position-only solution at each offset ahead of the ready
    pose (NaN beyond the reach), and the first offset beyond the reach (1 mm, as the test)."""
    limb = get_limb(ARM, "hand")
    q = np.array(FREE_READY_ARM_RAD[ARM], dtype=float)
    T = limb.fk(q)
    ready_m = T[:3, 3].copy()
    out = np.empty(6)
    bend, edge_m = [], np.inf
    for a in ahead_m:
        T[:3, 3] = ready_m + [a, 0.0, 0.0]
        pos, _, _ = nearest_on_branch(T, limb.chain, limb.lower_rad, limb.upper_rad, q,
                                      branch_of(q), np.zeros(3), 1.0, 1e-4, 300, out)
        q = out.copy()
        if pos > 1e-3:
            edge_m = min(edge_m, float(a))
        bend.append(abs(q[3]) if pos < 1e-6 else np.nan)
    return np.asarray(bend), edge_m


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--back", type=float, default=8.0, help="walk back duration (s)")
    parser.add_argument("--parked-bend", type=float, nargs="+", default=[0.1, 0.64],
                        help="elbow bend (rad from straight) where the hand waits")
    args = parser.parse_args()
    spec = load_model().limb(ARM)
    elbow_speed, elbow_accel = spec.velocity_rad_s[3], spec.acceleration_rad_s2[3]
    ahead = np.linspace(0.0, 0.2, 2001)
    bend, edge_m = elbow_along_path(ahead)
    inside = np.isfinite(bend)
    t_s = np.arange(0.0, args.back, 0.001)
    goal_m = (edge_m + 0.3) * (1.0 - _min_jerk(t_s / args.back))
    goal_in = goal_m <= ahead[inside][-1]
    t_cross = t_s[np.argmax(goal_in)]
    goal_bend = np.interp(goal_m, ahead[inside], bend[inside])
    print(f"elbow limits {elbow_speed:.2f} rad/s, {elbow_accel:.2f} rad/s^2; the goal is "
          f"reachable again at {t_cross:.2f} s, moving inward at "
          f"{1e3 * np.interp(t_cross, t_s, -np.gradient(goal_m, t_s)):.0f} mm/s")
    for bend0 in args.parked_bend:
        t_pass = t_s[np.argmax(goal_in & (goal_bend >= bend0))]
        tau = np.maximum(t_s - t_pass, 0.0)
        t_full = elbow_speed / elbow_accel
        moved = np.where(tau < t_full, 0.5 * elbow_accel * tau**2,
                         0.5 * elbow_speed * t_full + elbow_speed * (tau - t_full))
        hand_m = np.interp(bend0 + moved, bend[inside][::-1], ahead[inside][::-1])
        gap_m = np.where(t_s >= t_pass, hand_m - goal_m, 0.0)
        behind = (t_s > t_pass) & (gap_m >= 0.002)
        k_out = np.argmax(behind) if behind.any() else None
        if k_out is None:
            t_back = t_pass
        else:
            caught = np.nonzero((t_s > t_s[k_out]) & (gap_m < 0.002))[0]
            t_back = t_s[caught[0]] if len(caught) else np.inf
        before = (t_s >= t_pass) & (t_s <= t_back)
        parked_mm = 1e3 * (np.interp(bend0, bend[inside][::-1], ahead[inside][::-1]) - edge_m)
        print(f"parked at {bend0:.2f} rad from straight ({parked_mm:+.0f} mm along the path): "
              f"the goal passes the hand {t_pass - t_cross:.2f} s after it is reachable; the "
              f"ideal elbow is back within 2 mm {t_back - t_cross:.2f} s after it is reachable, "
              f"the gap up to {1e3 * np.max(gap_m[before]):.0f} mm")


if __name__ == "__main__":
    main()
