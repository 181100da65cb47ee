"""The walking pattern: a timeline of support phases, the ZMP reference made from the
footsteps, the CoM path from preview control and the swing feet's trajectories.

Timeline (one sample per control period):

1. ``start_s`` standing with the ZMP reference between the feet (the preview controller starts
   the CoM moving: without this lead-in the CoM, at rest, would need a large ZMP excursion),
   then ``double_support_s`` while the ZMP moves to the first stance foot;
2. per footstep, ``single_support_s`` with the swing foot in the air (ZMP on the stance foot),
   then ``double_support_s`` while the ZMP moves to the foot that just landed (after the last
   step: back between the feet);
3. ``settle_s`` standing, the ZMP between the feet.

On a stance foot the ZMP reference is the middle of the sole (``feet.forward_m`` ahead of the
ankle) moved ``zmp_inset_m`` toward the other foot. A swing foot lifts, moves only while it is
at least 9 % of ``swing_height_m`` up (the middle 80 % of the phase, quintic in time),
turns with it, and lands flat; its height is ``swing_height_m * sin^2(pi * tau)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.walking.footsteps import SIDE_SIGN, Footstep, stance_of, wrap_angle
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.preview import CoMPath, com_from_zmp, preview_gains

SWING_MOVE = (0.1, 0.9)  # fraction of single support during which the swing foot travels


def smoothstep5(s):
    """The quintic 0 -> 1 with zero velocity and acceleration at both ends (s clipped)."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


@dataclass(frozen=True)
class Gait:
    """A walking pattern sampled once per control period (n samples, world frame).

    Attributes:
        period_s: the control period (s).
        steps: the footsteps taken, in order.
        zmp_ref_m: the ZMP reference (n, 2).
        com: the CoM path from preview control (see :class:`CoMPath`), at ``com_height_m``.
        feet: the soles' poses per period, side -> (n, 4) rows of (x, y, z, yaw) (m, rad).
        support: which feet carry the robot, (n, 2) booleans (right, left).
        step_index: the footstep being taken (-1 before the first and after the last), (n,).
    """

    period_s: float
    steps: tuple[Footstep, ...]
    com_height_m: float
    zmp_ref_m: np.ndarray
    com: CoMPath
    feet: dict[str, np.ndarray]
    support: np.ndarray
    step_index: np.ndarray

    @property
    def n(self) -> int:
        return len(self.zmp_ref_m)

    @property
    def duration_s(self) -> float:
        return self.n * self.period_s


def zmp_point(foot: Footstep, params: WalkingParams, forward_m: float) -> np.ndarray:
    """Where the ZMP reference sits while ``foot`` alone carries the robot (x, y; m)."""
    inset = -SIDE_SIGN[foot.side] * params.zmp_inset_m  # toward the other foot
    c, s = math.cos(foot.yaw_rad), math.sin(foot.yaw_rad)
    return np.array([foot.x_m + c * forward_m - s * inset, foot.y_m + s * forward_m + c * inset])


def _middle(right: Footstep, left: Footstep, forward_m: float) -> np.ndarray:
    stance = stance_of(right, left)
    return np.array([stance.x_m + math.cos(stance.yaw_rad) * forward_m,
                     stance.y_m + math.sin(stance.yaw_rad) * forward_m])


def _row(foot: Footstep, z_m: float) -> np.ndarray:
    return np.array([foot.x_m, foot.y_m, z_m, foot.yaw_rad])


def swing_rows(start: Footstep, end: Footstep, n: int, height_m: float,
               z_m: float) -> np.ndarray:
    """The swing foot over one single-support phase of n periods: (n, 4) rows of
    (x, y, z, yaw); the sample k is at tau = (k + 1) / n (the last one has landed)."""
    tau = (np.arange(n) + 1.0) / n
    lo, hi = SWING_MOVE
    s = smoothstep5((tau - lo) / (hi - lo))
    turn = wrap_angle(end.yaw_rad - start.yaw_rad)
    rows = np.empty((n, 4))
    rows[:, 0] = start.x_m + s * (end.x_m - start.x_m)
    rows[:, 1] = start.y_m + s * (end.y_m - start.y_m)
    rows[:, 2] = z_m + height_m * np.sin(np.pi * tau) ** 2
    rows[:, 3] = start.yaw_rad + s * turn
    return rows


def make_gait(right: Footstep, left: Footstep, steps: list[Footstep], params: WalkingParams,
              period_s: float, com_height_m: float, sole_z_m: float = 0.0,
              zmp_forward_m: float = 0.0, com_start_m: np.ndarray | None = None) -> Gait:
    """Sample the walking pattern for ``steps`` starting from the feet ``right`` and ``left``.

    Args:
        right, left: where the feet stand at the start.
        steps: the footsteps (:func:`~hubo_cli.walking.footsteps.plan_footsteps`).
        params: the walking parameters.
        period_s: the control period (s).
        com_height_m: the CoM's height above the soles for the cart-table model (m).
        sole_z_m: the soles' height in the world (m).
        zmp_forward_m: the sole's middle ahead of its frame origin (m).
        com_start_m: the CoM at the start (x, y; m; default the middle between the feet);
            the ZMP reference starts under it.
    """
    def periods(duration_s: float) -> int:
        return max(1, int(round(duration_s / period_s)))

    feet = {"right": right, "left": left}
    zmp: list[np.ndarray] = []
    rows: dict[str, list[np.ndarray]] = {"right": [], "left": []}
    support: list[np.ndarray] = []
    index: list[np.ndarray] = []

    def hold(n: int, zmp_from: np.ndarray, zmp_to: np.ndarray, step: int) -> None:
        s = smoothstep5((np.arange(n) + 1.0) / n)[:, None]
        zmp.append(zmp_from + s * (zmp_to - zmp_from))
        for side in feet:
            rows[side].append(np.tile(_row(feet[side], sole_z_m), (n, 1)))
        support.append(np.ones((n, 2), dtype=bool))
        index.append(np.full(n, step))

    start = (_middle(right, left, zmp_forward_m) if com_start_m is None
             else np.asarray(com_start_m, dtype=float))
    here = start
    if steps:
        first_stance = feet["left" if steps[0].side == "right" else "right"]
        there = zmp_point(first_stance, params, zmp_forward_m)
        hold(periods(params.start_s), here, here, -1)  # the preview's lead-in
        hold(periods(params.double_support_s), here, there, -1)
        here = there
    for i, step in enumerate(steps):
        n = periods(params.single_support_s)
        stance_side = "left" if step.side == "right" else "right"
        zmp.append(np.tile(here, (n, 1)))
        rows[stance_side].append(np.tile(_row(feet[stance_side], sole_z_m), (n, 1)))
        rows[step.side].append(swing_rows(feet[step.side], step, n, params.swing_height_m,
                                          sole_z_m))
        on_ground = np.zeros((n, 2), dtype=bool)
        on_ground[:, 0 if stance_side == "right" else 1] = True
        support.append(on_ground)
        index.append(np.full(n, i))
        feet[step.side] = step
        last = i == len(steps) - 1
        there = (_middle(feet["right"], feet["left"], zmp_forward_m) if last
                 else zmp_point(step, params, zmp_forward_m))
        hold(periods(params.double_support_s), here, there, i)
        here = there
    hold(periods(params.settle_s), here, here, -1)
    zmp_ref = np.vstack(zmp)
    gains = preview_gains(period_s, com_height_m, params.preview_s, params.zmp_weight,
                          params.jerk_weight)
    com = com_from_zmp(zmp_ref, gains, start)
    return Gait(period_s, tuple(steps), com_height_m, zmp_ref, com,
                {side: np.vstack(r) for side, r in rows.items()}, np.vstack(support),
                np.concatenate(index))
