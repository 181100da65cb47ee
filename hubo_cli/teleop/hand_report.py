"""How well a hand followed its operator: the figures of one arm's record while operating
(the ``reach`` figures of ``hubo teleop``'s summary, which the bench and the tests read).

A record is per control period: the time, the goal's and the hand's positions (S, m), the
position and rotation errors, whether the goal was reachable (the reach search's nearest pose
is the goal) and whether the hand was meant to follow it (input live, not held for a
re-centre, clutch released). The excursion is the hand's distance to the nearest goal sample
within +-``EXCURSION_WINDOW_S``: a hand that lags along the goal's path has none, one that
swings off it has.
"""

from __future__ import annotations

import numpy as np

EXCURSION_WINDOW_S = 1.0  # max_excursion_mm: nearest goal sample within +-this
# the first this long after a goal comes back into reach is its return; the rest of the reachable
# time is steady following (the steady_* figures): on generated 20 s streams the return's second
# holds 57-68 % of the reachable time's squared position error in 26-29 % of the time
# (docs/history/teleop.md, round 25)
RETURN_WINDOW_S = 1.0


def hand_report(t_s, paths, errors_m, rotation_errors_rad, reachable, meant_to_follow, *,
                at_limit_s: float, branch_changes: int, collision_room_s: float) -> dict:
    """One hand's figures from its record (``t_s`` the periods' times, s; ``paths`` (goal,
    hand) positions, m; ``errors_m`` and ``rotation_errors_rad``; ``reachable`` and
    ``meant_to_follow`` flags), with its time at the reach limit (s), its branch changes and
    the time its target was kept out of the collision band (s) as given: the position and
    orientation RMS (mm, deg) over all the time, the largest excursion, the share of the time
    the goal was reachable (``reachable_share``) with the position and orientation RMS and
    the largest excursion over that time (None when it never was), the share of the time the
    goal was reachable while the hand was meant to follow it (``followed_share``) with the
    position and orientation RMS over it (``followed_position_rms_mm``,
    ``followed_orientation_rms_deg``: what the replay's verdict judges), and the share of the
    reachable time that is steady following, more than ``RETURN_WINDOW_S`` after the goal
    last came back into reach (``steady_share``), with the position and orientation RMS over
    it (``steady_position_rms_mm``, ``steady_orientation_rms_deg``; :func:`steady_mask`)."""
    pos = np.asarray(errors_m)
    rot = np.asarray(rotation_errors_rad)
    ok = np.asarray(reachable, dtype=bool)
    followed = ok & np.asarray(meant_to_follow, dtype=bool)
    t_s = np.asarray(t_s)
    steady = steady_mask(t_s, ok)
    excursion = excursions_m(t_s, np.array([g for g, _ in paths]).reshape(-1, 3),
                             np.array([a for _, a in paths]).reshape(-1, 3))
    return {
        "reachable_share": float(ok.mean()) if len(ok) else None,
        "reachable_position_rms_mm": float(np.sqrt(np.mean(pos[ok]**2)) * 1000)
        if ok.any() else None,
        "reachable_orientation_rms_deg": float(np.degrees(np.sqrt(np.mean(rot[ok]**2))))
        if ok.any() else None,
        "followed_share": float(followed.mean()) if len(followed) else None,
        "followed_position_rms_mm": float(np.sqrt(np.mean(pos[followed]**2)) * 1000)
        if followed.any() else None,
        "position_rms_mm": float(np.sqrt(np.mean(pos**2)) * 1000) if len(pos) else None,
        "orientation_rms_deg": float(np.degrees(np.sqrt(np.mean(rot**2))))
        if len(rot) else None,
        "at_limit_s": at_limit_s,
        "branch_changes": branch_changes,
        "collision_room_s": collision_room_s,
        "max_excursion_mm": float(np.max(excursion, initial=0.0)) * 1000,
        "reachable_max_excursion_mm": float(np.max(excursion[ok])) * 1000
        if ok.any() else None,
        "followed_orientation_rms_deg":
        float(np.degrees(np.sqrt(np.mean(rot[followed]**2)))) if followed.any() else None,
        "steady_share": float(steady.sum() / ok.sum()) if ok.any() else None,
        "steady_position_rms_mm": float(np.sqrt(np.mean(pos[steady]**2)) * 1000)
        if steady.any() else None,
        "steady_orientation_rms_deg": float(np.degrees(np.sqrt(np.mean(rot[steady]**2))))
        if steady.any() else None,
    }


def steady_mask(t_s: np.ndarray, reachable: np.ndarray,
                return_window_s: float = RETURN_WINDOW_S) -> np.ndarray:
    """Per sample (times ``t_s``, s, ascending; ``reachable`` flags), whether the goal is
    reachable and came back into reach more than ``return_window_s`` earlier: steady following,
    not a return (a goal reachable from the first sample on has not returned)."""
    t = np.asarray(t_s, dtype=float)
    ok = np.asarray(reachable, dtype=bool)
    if not len(t):
        return np.zeros(0, dtype=bool)
    out_t = np.where(ok, -np.inf, t)  # the time of each sample out of reach
    last_out_s = np.maximum.accumulate(out_t)  # ... of the last one up to each sample
    return ok & (t - last_out_s > return_window_s)


def max_excursion_m(t_s: np.ndarray, goals_m: np.ndarray, actual_m: np.ndarray,
                    window_s: float = EXCURSION_WINDOW_S) -> float:
    """The largest distance (m) from the hand to the nearest goal sample within +-window_s.

    Args:
        t_s: sample times (N,), increasing.
        goals_m, actual_m: goal and hand positions (N x 3) at those times.
    """
    return float(np.max(excursions_m(t_s, goals_m, actual_m, window_s), initial=0.0))


def excursions_m(t_s: np.ndarray, goals_m: np.ndarray, actual_m: np.ndarray,
                 window_s: float = EXCURSION_WINDOW_S) -> np.ndarray:
    """Per sample, the distance (m) from the hand to the nearest goal sample within +-window_s
    ((N,); see :func:`max_excursion_m`)."""
    if len(t_s) == 0:
        return np.zeros(0)
    nearest = np.full(len(t_s), np.inf)
    lo = np.searchsorted(t_s, t_s - window_s, side="left")
    hi = np.searchsorted(t_s, t_s + window_s, side="right")
    for k in range(int(np.max(np.arange(len(t_s)) - lo)) + 1):  # goal k samples earlier
        idx = np.arange(len(t_s)) - k
        ok = idx >= lo
        d = np.linalg.norm(actual_m[ok] - goals_m[idx[ok]], axis=1)
        nearest[ok] = np.minimum(nearest[ok], d)
    for k in range(1, int(np.max(hi - np.arange(len(t_s)))) + 1):  # goal k samples later
        idx = np.arange(len(t_s)) + k
        ok = idx < hi
        d = np.linalg.norm(actual_m[ok] - goals_m[idx[ok]], axis=1)
        nearest[ok] = np.minimum(nearest[ok], d)
    return nearest
