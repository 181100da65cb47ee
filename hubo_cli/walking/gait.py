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
ankle) moved ``zmp_inset_m`` toward the other foot. A swing foot lifts, moves during
``swing_travel_fraction`` of the phase, ending at ``swing_travel_end_fraction`` of it (0.8
ending at 0.9, the middle: while it is at least 9 % of ``swing_height_m`` up; a travel that
starts at lift-off, as the fast gait's 0.86 ending at 0.86, moves the foot while it is still
low) on
:func:`cruise_profile` (``swing_ramp_fraction`` 0.5: quintic in time), turns with it, and
lands flat; its height is ``swing_height_m * sin^2(pi * tau)``.

**Toe-heel walking** (``toe_heel`` given; multi-layer paper eq. 4 and Fig. 4,
:mod:`~hubo_cli.walking.toe_heel`): each step lasts the walking's single plus double support,
centred on its single support (half a double support before, half after), and its five
phases are the robot file's ``[toe_heel]`` ones scaled to that time (the paper's with the
robot file's 1.0 s step). The ZMP reference is eq. 4's blend of the feet's CoPs (the swing
foot's moving from toe to heel, every CoP ``zmp_inset_m`` inside its foot's centre line), the
swing foot rolls on its toe as it leaves and on its heel as it lands (its pitch and pivot in
``Gait.toe_heel``; its rows are the sole's origin, moved as the roll moves it:
:func:`~hubo_cli.walking.toe_heel.ankle_offset`). A short or sideways step lands flat; a walk
of such steps only (a correction of a few millimetres) is the flat pattern.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.model import FootShape
from hubo_cli.walking.footsteps import SIDE_SIGN, Footstep, stance_of, wrap_angle
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.preview import CoMPath, com_from_zmp, preview_gains
from hubo_cli.walking.toe_heel import (
    ToeHeelParams,
    ToeHeelPlan,
    ankle_offset,
    plan_toe_heel_walk,
    step_direction,
)

SWING_MOVE = (0.1, 0.9)  # fraction of single support during which a capture step's swing
                         # foot travels (a walk's: WalkingParams.swing_travel_fraction)


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
        toe_heel: the toe-heel plan row for row (its feet's angles, pivots and CoPs); None for
            flat feet.
        torso_lead_rad: a correction's lead-in (its first rows, fewer than n): the torso turned
            further by these rotation vectors (rows of 3, rad, in the torso's frame), from
            where the estimated torso stood onto the pattern's own lean and heading
            (:func:`~hubo_cli.walking.lead_in.blend_from_held`); None: no lead-in.
    """

    period_s: float
    steps: tuple[Footstep, ...]
    com_height_m: float
    zmp_ref_m: np.ndarray
    com: CoMPath
    feet: dict[str, np.ndarray]
    support: np.ndarray
    step_index: np.ndarray
    toe_heel: ToeHeelPlan | None = None
    torso_lead_rad: np.ndarray | None = None

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


def cruise_profile(u, ramp: float):
    """0 -> 1 over u in [0, 1] (clipped): the quintic's velocity bell split at its peak, with a
    cruise at that speed between the halves; each half lasts ``ramp`` of the time (0 < ramp
    <= 0.5). ``ramp`` 0.5 is :func:`smoothstep5` itself (peak speed 1.875 times the mean);
    0.25 peaks at 1.30 times the mean, its acceleration at 1.39 times the quintic's."""
    u = np.clip(u, 0.0, 1.0)
    if ramp >= 0.5:
        return smoothstep5(u)
    peak = 1.0 / (1.0 - 14.0 * ramp / 15.0)  # the rising half covers peak * ramp * 8 / 15

    def rise(x):  # the bell 30 x^2 (1 - x)^2 over [0, 2 ramp], its first half, integrated
        x = x / (2.0 * ramp)
        return peak * 2.0 * ramp * 16.0 * (x**3 / 3 - x**4 / 2 + x**5 / 5)

    return np.where(u < ramp, rise(u), np.where(
        u > 1.0 - ramp, 1.0 - rise(1.0 - u), peak * (8.0 * ramp / 15.0 + u - ramp)))


def swing_rows(start: Footstep, end: Footstep, n: int, height_m: float,
               z_m: float, travel: float, ramp: float, travel_end: float | None = None
               ) -> np.ndarray:
    """The swing foot over one single-support phase of n periods: (n, 4) rows of
    (x, y, z, yaw); the sample k is at tau = (k + 1) / n (the last one has landed). It
    travels during ``travel`` of the phase ending at ``travel_end`` (None: the middle) on
    :func:`cruise_profile` (``ramp``)."""
    tau = (np.arange(n) + 1.0) / n
    lo = (1.0 - travel) / 2 if travel_end is None else travel_end - travel
    s = cruise_profile((tau - lo) / travel, ramp)
    turn = wrap_angle(end.yaw_rad - start.yaw_rad)
    rows = np.empty((n, 4))
    rows[:, 0] = start.x_m + s * (end.x_m - start.x_m)
    rows[:, 1] = start.y_m + s * (end.y_m - start.y_m)
    rows[:, 2] = z_m + height_m * np.sin(np.pi * tau) ** 2
    rows[:, 3] = start.yaw_rad + s * turn
    return rows


def make_gait(right: Footstep, left: Footstep, steps: list[Footstep], params: WalkingParams,
              period_s: float, com_height_m: float, sole_z_m: float = 0.0,
              zmp_forward_m: float = 0.0, com_start_m: np.ndarray | None = None,
              toe_heel: ToeHeelParams | None = None, sole: FootShape | None = None,
              com_rows: int | None = None) -> Gait:
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
        toe_heel, sole: walk on toe and heel (see the module docstring) with these phases
            and angles on this sole (both needed); None: flat feet.
        com_rows: the flat pattern's CoM path only over its first rows (the rest previewed;
            at least one): a re-plan computes its own (:mod:`hubo_cli.walking.replan`).
    """
    if toe_heel is not None and _rolls(right, left, steps, toe_heel.min_step_m):
        if sole is None:
            raise ValueError("toe-heel walking needs the sole's shape")
        return _toe_heel_gait(right, left, steps, params, period_s, com_height_m, sole_z_m,
                              com_start_m, toe_heel, sole)

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
                                          sole_z_m, params.swing_travel_fraction,
                                          params.swing_ramp_fraction,
                                          params.swing_travel_end_fraction))
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
    com = com_from_zmp(zmp_ref, gains, start, rows=com_rows)
    return Gait(period_s, tuple(steps), com_height_m, zmp_ref, com,
                {side: np.vstack(r) for side, r in rows.items()}, np.vstack(support),
                np.concatenate(index))


def _rolls(right: Footstep, left: Footstep, steps: list[Footstep], min_step_m: float) -> bool:
    """Some step is long enough to roll on toe and heel (the others land flat)."""
    feet = {"right": right, "left": left}
    for step in steps:
        if step_direction(feet[step.side], step, min_step_m) != 0:
            return True
        feet[step.side] = step
    return False


def _toe_heel_gait(right: Footstep, left: Footstep, steps: list[Footstep],
                   params: WalkingParams, period_s: float, com_height_m: float,
                   sole_z_m: float, com_start_m: np.ndarray | None, toe_heel: ToeHeelParams,
                   sole: FootShape) -> Gait:
    """:func:`make_gait` walking on toe and heel (see the module docstring)."""
    lead = max(1, int(round(params.start_s / period_s)))
    half = max(1, int(round(params.double_support_s / 2 / period_s)))
    single = max(1, int(round(params.single_support_s / period_s)))
    step_n = single + 2 * half
    settle = max(1, int(round(params.settle_s / period_s)))
    walk_n = lead + len(steps) * step_n
    n = walk_n + settle
    plan = plan_toe_heel_walk(right, left, steps, toe_heel.scaled_to(step_n * period_s), sole,
                              2 * half * period_s, period_s, stand_s=lead * period_s,
                              inset_m=params.zmp_inset_m)
    rows = np.r_[np.arange(walk_n), np.full(settle, walk_n)]  # settle: the plan's standing row
    plan = plan.take(rows)
    plan.t_s = np.arange(n) * period_s
    zmp_ref = plan.zmp_m.copy()
    start = zmp_ref[lead] if com_start_m is None else np.asarray(com_start_m, dtype=float)
    zmp_ref[:lead] = start + smoothstep5((np.arange(lead) + 1.0) / lead)[:, None] * (
        zmp_ref[lead] - start)  # the lead-in: from under the CoM to between the feet
    feet = {"right": right, "left": left}
    foot_rows = {side: np.empty((n, 4)) for side in feet}
    support = np.ones((n, 2), dtype=bool)
    index = np.full(n, -1)
    for side in feet:
        foot_rows[side][:lead + 1] = _row(feet[side], sole_z_m)
    for i, step in enumerate(steps):
        base = lead + i * step_n
        column = 0 if step.side == "right" else 1
        other = "left" if column == 0 else "right"
        foot_rows[other][base:base + step_n] = _row(feet[other], sole_z_m)
        foot_rows[step.side][base:base + half] = _row(feet[step.side], sole_z_m)
        foot_rows[step.side][base + half:base + half + single] = swing_rows(
            feet[step.side], step, single, params.swing_height_m, sole_z_m,
            params.swing_travel_fraction, params.swing_ramp_fraction,
            params.swing_travel_end_fraction)
        foot_rows[step.side][base + half + single:base + step_n] = _row(step, sole_z_m)
        support[base + half:base + half + single, column] = False
        index[base:base + step_n] = i
        feet[step.side] = step
    for side in feet:
        foot_rows[side][walk_n:] = _row(feet[side], sole_z_m)
        column = 0 if side == "right" else 1
        dx, dz = ankle_offset(plan.foot_angle_rad[:, column], plan.pivot_m[:, column])
        yaw = foot_rows[side][:, 3]
        foot_rows[side][:, 0] += np.cos(yaw) * dx
        foot_rows[side][:, 1] += np.sin(yaw) * dx
        foot_rows[side][:, 2] += dz
    gains = preview_gains(period_s, com_height_m, params.preview_s, params.zmp_weight,
                          params.jerk_weight)
    com = com_from_zmp(zmp_ref, gains, start)
    return Gait(period_s, tuple(steps), com_height_m, zmp_ref, com, foot_rows, support, index,
                plan)
