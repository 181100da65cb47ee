"""Arm targets that keep clear of the body: the body is a limit of the operator's goal, like reach.

The pipeline's collision detector (:mod:`hubo_cli.control.collision`) holds the arms once the
command, where it is or where it would stop, comes within 10 mm of the body, and then takes
2.5 s to recover: on ``two-hand-free.csv`` the operator's right-hand goal brings the upper arm
within 6 mm of the torso at 17 s, so a hand that follows it closely is held there and falls
28 mm behind. Instead, teleoperation stops an arm's target where it would come within
``BODY_CLEARANCE_M`` of the body (the same pairs as the detector), on the straight joint-space
way from the last target toward the new one, and the hand carries on once the goal leaves.
The detector stays as it is, the last word.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.control.collision import SelfCollisionChecker

BODY_CLEARANCE_M = 0.011  # the detector's 10 mm, and 1 mm for its braking way
BISECTIONS = 6            # the stop is found within 1/64 of the period's step
GRADIENT_STEP_RAD = 1e-4  # finite differences of the distance for sliding along the body


def clear_of_body(checker: SelfCollisionChecker, q_rad: np.ndarray, arm: slice,
                  q_from_rad: np.ndarray, q_to_rad: np.ndarray,
                  clearance_m: float = BODY_CLEARANCE_M) -> np.ndarray | None:
    """Where an arm's target may go on its way from q_from to q_to, or None if q_to is clear.

    Args:
        checker: the self-collision geometry.
        q_rad: the whole-body joint vector (the other limbs as they will be commanded).
        arm: the arm's slice of q_rad.
        q_from_rad, q_to_rad: the arm's last target and its new one (rad).
        clearance_m: the distance to keep from the body (m).

    Returns None when q_to keeps ``clearance_m``. Otherwise the arm goes as far as the
    clearance allows on the straight way, then slides along the body with the rest of the
    step less its part toward the body (the distance's gradient), as far as that allows: the
    hand follows a goal that moves along the body instead of sticking where it met it. When
    q_from itself is closer than the clearance: q_to if it is no closer, else q_from.
    """
    q = np.array(q_rad, dtype=float)
    q_from = np.asarray(q_from_rad, dtype=float)
    q_to = np.asarray(q_to_rad, dtype=float)

    def distance(q_arm: np.ndarray) -> float:
        q[arm] = q_arm
        return checker.check(q).distance_m

    d_to = distance(q_to)
    if d_to >= clearance_m:
        return None
    d_from = distance(q_from)
    if d_from < clearance_m:
        return None if d_to >= d_from else q_from.copy()
    q_stop = _furthest_clear(distance, q_from, q_to - q_from, clearance_m)
    # slide along the body: the rest of the step without its part toward the body
    rest = q_to - q_stop
    d_stop = distance(q_stop)
    grad = np.empty(len(q_stop))
    for j in range(len(q_stop)):
        q_probe = q_stop.copy()
        q_probe[j] += GRADIENT_STEP_RAD
        grad[j] = (distance(q_probe) - d_stop) / GRADIENT_STEP_RAD
    inward = float(rest @ grad)
    if inward < 0.0:
        rest = rest - inward / float(grad @ grad) * grad
    if distance(q_stop + rest) >= clearance_m:
        return q_stop + rest
    return _furthest_clear(distance, q_stop, rest, clearance_m)


def _furthest_clear(distance, q_from: np.ndarray, step: np.ndarray,
                    clearance_m: float) -> np.ndarray:
    """The furthest q_from + s step (s in [0, 1], bisection) that keeps the clearance, q_from
    being clear."""
    lo, hi = 0.0, 1.0
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if distance(q_from + mid * step) >= clearance_m:
            lo = mid
        else:
            hi = mid
    return q_from + lo * step
