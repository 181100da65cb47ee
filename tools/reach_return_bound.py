"""How soon can a hand parked at its reach limit be back on a goal that walks back into reach?

The goal of the out-of-reach test (tests/test_teleop_reach.py) walks the right hand straight
forward from the free-mode ready pose to ``--beyond`` (30 cm) beyond its reach and back along
the same line (minimum-jerk, ``--back`` seconds). Near the straight elbow only the elbow moves
the hand inward, so the question is one of the elbow: this script takes the elbow angle of the
exact position-only solution along the path and prints two floors for an ideal elbow (its
speed and acceleration limits, no jerk limit, no braking, no speed scale):

- *reactive*: it starts from rest at its parked bend the moment the goal passes the parked
  hand (a controller that only reacts to where the goal is), accelerates at the limit up to
  its speed limit; the first time it is back within 2 mm of the goal (along the path) after
  the goal is reachable again, and the largest gap before that;
- *perfect prediction*: it may start whenever it likes (it knows the goal's future): the first
  time after re-entry from which it can stay within 2 mm of the goal, starting from rest at
  the parked bend and never straighter than that (linear programs, see
  :func:`_perfect_meet_s`);
- the same with the hand never more than ``--lead`` (default teleop/reach_lead.py's
  ``LEAD_M``, within the issue's 10 mm cap on anticipation) inward of the goal's nearest
  reachable point: a floor for any controller, causal or not, that keeps that cap; with the
  elbow's bend and speed at re-entry on one way that meets it;
- the same with two conditions every *causal* elbow (one that knows only the goal's past)
  must meet: able at every moment before re-entry to stop within that lead (a goal that
  stops just outside the reach looks the same until then), and after re-entry to stop within
  ``--excursion`` (15 mm, the issue's) beyond the goal; then with the elbow's jerk limit as
  well (a floor still: it knows where the goal goes, it only keeps able to stop);
- *reacting and staying*: the perfect-prediction floor for an elbow at rest until the goal
  passes the parked hand (the reactive floor's start): the first time from which it can stay
  within 2 mm (the reactive floor only asks when it is first back within 2 mm, and may pass the
  goal at full speed).

    python tools/reach_return_bound.py [--back 8] [--beyond 0.3] [--parked-bend 0.1 0.64]
        [--lead M] [--excursion M]

The causal floors take about a minute for the 8 s walk, longer for slower ones (dense linear
programs).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import linprog

from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.reach import branch_of, nearest_on_branch
from hubo_cli.model import load_model
from hubo_cli.teleop.reach_lead import LEAD_M
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
    parser.add_argument("--beyond", type=float, default=0.3,
                        help="how far beyond the reach the walk goes (m)")
    parser.add_argument("--parked-bend", type=float, nargs="+", default=[0.1, 0.64],
                        help="elbow bend (rad from straight) where the hand waits")
    parser.add_argument("--lead", type=float, default=LEAD_M,
                        help="the hand's largest lead over the goal's nearest reachable point (m)")
    parser.add_argument("--excursion", type=float, default=0.015,
                        help="how far beyond the goal a causal elbow may have to stop (m)")
    args = parser.parse_args()
    spec = load_model().limb(ARM)
    elbow_speed, elbow_accel = spec.velocity_rad_s[3], spec.acceleration_rad_s2[3]
    elbow_jerk = spec.jerk_rad_s3[3]
    ahead = np.linspace(0.0, 0.2, 2001)
    bend, edge_m = elbow_along_path(ahead)
    inside = np.isfinite(bend)
    t_s = np.arange(0.0, args.back, 0.001)
    goal_m = (edge_m + args.beyond) * (1.0 - _min_jerk(t_s / args.back))
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
        t_meet, _, _ = _perfect_meet_s(t_s, goal_m, ahead[inside], bend[inside], t_cross,
                                       bend0, elbow_speed, elbow_accel)
        t_led, bend_led, speed_led = _perfect_meet_s(
            t_s, goal_m, ahead[inside], bend[inside], t_cross, bend0, elbow_speed, elbow_accel,
            lead_m=args.lead)
        t_causal, bend_causal, speed_causal = _perfect_meet_s(
            t_s, goal_m, ahead[inside], bend[inside], t_cross, bend0, elbow_speed, elbow_accel,
            lead_m=args.lead, stoppable=True)
        t_careful, bend_careful, speed_careful = _perfect_meet_s(
            t_s, goal_m, ahead[inside], bend[inside], t_cross, bend0, elbow_speed, elbow_accel,
            lead_m=args.lead, stoppable=True, excursion_m=args.excursion)
        t_jerk, _, _ = _perfect_meet_s(
            t_s, goal_m, ahead[inside], bend[inside], t_cross, bend0, elbow_speed, elbow_accel,
            lead_m=args.lead, stoppable=True, excursion_m=args.excursion,
            jerk=elbow_jerk)
        t_stays, _, _ = _perfect_meet_s(t_s, goal_m, ahead[inside], bend[inside], t_cross,
                                        bend0, elbow_speed, elbow_accel, start_s=t_pass)
        print(f"parked at {bend0:.2f} rad from straight ({parked_mm:+.0f} mm along the path): "
              f"the goal passes the hand {t_pass - t_cross:.2f} s after it is reachable; "
              f"reactive floor: back within 2 mm {t_back - t_cross:.2f} s after it is "
              f"reachable (the gap up to {1e3 * np.max(gap_m[before]):.0f} mm); perfect "
              f"prediction floor: within 2 mm from {t_meet - t_cross:.2f} s after it on; "
              f"with the lead within {1e3 * args.lead:.0f} mm of the goal's nearest reachable "
              f"point: from {t_led - t_cross:.2f} s (the elbow {bend_led:.2f} rad from "
              f"straight at {speed_led:.2f} rad/s at re-entry on one such way); and able "
              f"to stop within that lead until re-entry (causal): from "
              f"{t_causal - t_cross:.2f} s ({bend_causal:.2f} rad, {speed_causal:.2f} rad/s "
              f"at re-entry), and after it within {1e3 * args.excursion:.0f} mm beyond the "
              f"goal: from {t_careful - t_cross:.2f} s ({bend_careful:.2f} rad, "
              f"{speed_careful:.2f} rad/s), and with the elbow's {elbow_jerk:.0f} rad/s^3 "
              f"jerk limit as well: from {t_jerk - t_cross:.2f} s; reacting and staying "
              f"within 2 mm: from {t_stays - t_cross:.2f} s")


def _perfect_meet_s(t_s, goal_m, ahead_m, bend, t_cross, bend0, speed, accel, step_s=0.02,
                    lead_m=None, start_s=-np.inf, stoppable=False, excursion_m=np.inf,
                    jerk=np.inf):
    """The first time after re-entry from which an elbow that knows the goal's future can stay
    within 2 mm of it (see the module docstring): bisection on that time over feasibility
    linear programs in the elbow's piecewise-constant acceleration (from rest at ``bend0``
    2 s before re-entry, within the acceleration and speed limits, never straighter than
    ``bend0``), the bend kept between the bends of the goal's position +-2 mm from that time
    on, and with ``lead_m`` never more than that inward of the goal's nearest reachable
    point; with ``start_s``, at rest until then (a controller that only reacts: the goal
    passes the parked hand at ``start_s``); with ``stoppable``, able at every time before
    re-entry to stop (at the acceleration limit) within that lead as well (a causal
    controller: the goal's past does not tell a goal that comes back from one that stops just
    outside the reach; bend + speed^2 / 2 accel within the lead's bend, as tangents in the
    speed at 0.05 rad/s steps, so the floor is if anything low), and after re-entry to stop
    within ``excursion_m`` beyond the goal (nor one that stops inside the reach); with
    ``jerk``, the acceleration changing by at most that (rad/s^3). Returns that time and the
    elbow's bend and speed at re-entry (rad from straight, rad/s) on a way that meets it."""
    grid = np.arange(t_cross - 2.0, t_s[-1], step_s)
    goal = np.interp(grid, t_s, goal_m)
    lo = np.interp(goal + 0.002, ahead_m, bend)  # the bend falls as the hand goes out
    hi = np.interp(goal - 0.002, ahead_m, bend)
    n = len(grid)
    tk = np.arange(n) * step_s
    position = np.maximum(tk[:, None] - tk[None, :] - step_s / 2, 0.0) * step_s
    position[tk[:, None] <= tk[None, :]] = 0.0  # bend_k = bend0 + sum_j position_kj u_j
    velocity = np.tril(np.ones((n, n)), -1) * step_s

    A_lead, b_lead = np.zeros((0, n)), np.zeros(0)
    if lead_m is not None:  # never more than lead_m inward of the goal's nearest reachable point
        nearest = np.minimum(goal, ahead_m[-1])
        A_lead, b_lead = position, np.interp(nearest - lead_m, ahead_m, bend) - bend0
        if stoppable:  # 2 w0 v - w0^2 <= 2 accel (bend_stop - bend), bend_stop the lead's
            # bend before re-entry and the bend excursion_m beyond the goal after it
            stop_room = np.where(grid <= t_cross + step_s / 2, b_lead,
                                 np.interp(goal - excursion_m, ahead_m, bend) - bend0)
            rows, rhs = [], []
            for w0 in np.arange(0.05, speed + 1e-9, 0.05):
                rows.append(2.0 * w0 * velocity + 2.0 * accel * position)
                rhs.append(2.0 * accel * stop_room + w0 * w0)
            A_lead = np.vstack([A_lead, *rows])
            b_lead = np.concatenate([b_lead, *rhs])

    if np.isfinite(jerk):  # |u_k - u_k-1| <= jerk x step
        diff = np.eye(n)[1:] - np.eye(n)[:-1]
        A_lead = np.vstack([A_lead, diff, -diff])
        b_lead = np.concatenate([b_lead, np.full(2 * (n - 1), jerk * step_s)])

    bounds = [(0.0, 0.0) if t < start_s else (-accel, accel) for t in grid]
    k_cross = int(np.argmin(np.abs(grid - t_cross)))

    def solve(t_meet):
        rows = grid >= t_meet
        A = np.vstack([position[rows], -position[rows], velocity, -velocity, -position, A_lead])
        b = np.concatenate([hi[rows] - bend0, bend0 - lo[rows], np.full(2 * n, speed),
                            np.zeros(n), b_lead])
        res = linprog(np.zeros(n), A_ub=A, b_ub=b, bounds=bounds, method="highs")
        return res.x if res.status == 0 else None

    lo_s, hi_s = t_cross, grid[-1]
    u = solve(hi_s)
    if u is None:
        return np.inf, np.nan, np.nan
    for _ in range(12):
        mid = (lo_s + hi_s) / 2
        u_mid = solve(mid)
        if u_mid is not None:
            hi_s, u = mid, u_mid
        else:
            lo_s = mid
    return float(hi_s), float(bend0 + position[k_cross] @ u), float(velocity[k_cross] @ u)


if __name__ == "__main__":
    main()
