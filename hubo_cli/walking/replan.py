"""Changing a walk's pattern while it runs: the step in progress finished into a stance (a stop),
or the next footsteps moved after the capture point (a push).

Both re-plan the pattern from the period they act in (:func:`pattern_from`): the footsteps
(the plan's, changed from the step in progress on) make a new pattern on the same timeline
(:func:`~hubo_cli.walking.gait.make_gait`, from the plan's start), and its rows from that
period on replace the rest of the current one. The CoM continues from the current pattern's
own state (position, velocity, acceleration) under the new ZMP reference (preview control), and
a swing foot in the air moves from its old path onto the new one by its landing: nothing
jumps.

A whole re-plan does not fit in one control period (the legs solved twice and the multi-body
ZMP over every row of the new pattern: tens of milliseconds), and a stalled loop is a hazard
on the real-time hardware exactly when the robot is stopped or pushed; but a re-plan played
0.2-0.4 s late (computed a slice a period first) moves a pushed walk's landing too late. So the
walking target (:meth:`~hubo_cli.walking.target.WalkTarget._replan`) plays it from the period
it is decided in: that period computes the new pattern's cart-table rows (a few milliseconds)
and the legs for its first rows (:func:`prefix_rows`: as many as the rest takes to compute),
a few rows a period from then on, always ahead of the row played; their multi-body correction
is the playing pattern's, continued (:func:`continued_fix`, :func:`with_fix`: the correction
changes slowly and a moved landing hardly changes it over a few tenths of a second). The rest
(:func:`rest_of`), with its own multi-body correction continued from the first rows' end, is
computed a slice of rows a period while they play (the body's ``*_slices`` generators) and
follows them.

The footstep change after a push (:func:`shifted_landing`) is hrpsys AutoBalancer's
(``modify_footsteps_for_recovery``): the capture point's error beyond a margin moves the
landing of the step in progress, within step limits and never across the stance leg, and
every later footstep by as much.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from hubo_cli.state import GRAVITY_M_S2
from hubo_cli.walking.footsteps import SIDE_SIGN, Footstep
from hubo_cli.walking.gait import Gait, make_gait, smoothstep5
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.preview import CoMPath, com_from_zmp, preview_gains

CP_MARGIN_M = 0.02          # [chosen] a capture-point error within this moves no footstep
CP_STEP_FORWARD_M = 0.25    # [chosen] a moved landing at most this far ahead of the stance foot
CP_STEP_BACKWARD_M = 0.15   # [chosen] ... behind it
CP_WIDTH_MAX_M = 0.36       # [chosen] ... and at most this far from it sideways
CP_GAP_M = 0.04             # [chosen] the soles' inner edges stay this far apart: no crossing
CP_MAX_SHIFT_M = 0.2        # [chosen] a shift longer than this is shortened to it
PREFIX_LEAD_PERIODS = 4     # [chosen] a re-plan's first rows: the rest's slices and this many
HELD_BLEND_ROWS = 60        # [chosen] a foot standing elsewhere than a re-plan has it moves
                            # onto it over this many rows (0.3 s; a correction's lead-in blends
                            # over 0.55 s, and a stop in it jumped 4.1 deg of the legs at once)
HELD_TOLERANCE = 1e-9       # [chosen] (m and rad) a standing foot this close is where it is
TOUCH_BLEND_ROWS = 20       # [chosen] a swing foot down early moves from its command onto its
                            # landing place over this many rows (it stands there already;
                            # over 10, its joints met the walking limit set's speed limit)

Fix = tuple[np.ndarray, np.ndarray, np.ndarray]  # a multi-body correction of the CoM path per
                                                 # row: position, velocity, acceleration (n x 2)


def shifted_landing(stance: Footstep, planned: Footstep, shift_m: np.ndarray,
                    sole_width_m: float, step_width_m: float) -> Footstep:
    """The landing ``planned`` moved by ``shift_m`` (world x, y; m; at most CP_MAX_SHIFT_M
    of it), seen from ``stance``: at most CP_STEP_FORWARD_M ahead and CP_STEP_BACKWARD_M
    behind it, toward the swing side at least a sole's width and CP_GAP_M (the legs never
    cross; the walking width ``step_width_m`` if that is less) and at most CP_WIDTH_MAX_M."""
    shift = np.asarray(shift_m, dtype=float)
    norm = float(np.hypot(*shift))
    if norm > CP_MAX_SHIFT_M:
        shift = shift * (CP_MAX_SHIFT_M / norm)
    x, y = planned.x_m + shift[0], planned.y_m + shift[1]
    c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
    dx, dy = x - stance.x_m, y - stance.y_m
    ahead = min(max(c * dx + s * dy, -CP_STEP_BACKWARD_M), CP_STEP_FORWARD_M)
    across = SIDE_SIGN[planned.side] * (-s * dx + c * dy)  # toward the swing side: positive
    across = min(max(across, min(sole_width_m + CP_GAP_M, step_width_m)), CP_WIDTH_MAX_M)
    left = SIDE_SIGN[planned.side] * across
    return Footstep(planned.side, stance.x_m + c * ahead - s * left,
                    stance.y_m + s * ahead + c * left, planned.yaw_rad)


def shift_steps(steps: list[Footstep], index: int, moved: Footstep) -> list[Footstep]:
    """``steps`` with step ``index`` at ``moved`` and every later one moved by as much."""
    dx, dy = moved.x_m - steps[index].x_m, moved.y_m - steps[index].y_m
    return [*steps[:index], moved,
            *(Footstep(s.side, s.x_m + dx, s.y_m + dy, s.yaw_rad) for s in steps[index + 1:])]


def pattern_from(current: Gait, k: int, row: int, start: tuple[Footstep, Footstep],
                 steps: list[Footstep], params: WalkingParams, sole_z_m: float,
                 zmp_forward_m: float, com_start_m: np.ndarray,
                 planted: int | None = None, rows_per_period: int | None = None) -> Gait:
    """The pattern of ``steps`` from period ``k`` of ``current`` on (its ``steps`` and
    ``step_index`` the plan's: all of ``steps``, indices into them).

    Args:
        current: the pattern being played; ``k`` its period now, ``row`` the index on the
            plan's timeline (the pattern :func:`make_gait` made from ``start``) played from
            then on: that period's, or a later one (a swing ended early: its landing's row,
            the rest of the timeline moved that much earlier; the foot touched down moves
            onto its landing place over TOUCH_BLEND_ROWS).
        start: the feet (right, left) the plan started from.
        steps: the plan's footsteps, changed from the step in progress on (none: stand
            where the feet are, both down).
        params, sole_z_m, zmp_forward_m, com_start_m: as the plan was made.
        planted: the index of a step (onto its foot's own place) whose foot stays down: its
            single support keeps both feet on the ground, the ZMP on the other foot (a
            weight shift without a step).
        rows_per_period: the CoM path only over the first rows a re-plan solving this many
            rows a period solves at once (:func:`prefix_rows`) and one more (the state
            :func:`rest_of` continues from); None: all.
    """
    period = current.period_s
    if steps:
        full = make_gait(*start, steps, params, period, current.com_height_m, sole_z_m,
                         zmp_forward_m, com_start_m=com_start_m, com_rows=1)
    else:  # no step to take: stand where the feet are now, the ZMP between them
        here = [Footstep(side, *current.feet[side][k][[0, 1, 3]].tolist())
                for side in ("right", "left")]
        full = make_gait(*here, [], params, period, current.com_height_m, sole_z_m,
                         zmp_forward_m, com_rows=1)
        row = 0
    row = min(row, full.n - 1)
    feet = {side: rows[row:].copy() for side, rows in full.feet.items()}
    support = full.support[row:].copy()
    if planted is not None:
        held = full.step_index[row:] == planted
        place = feet[steps[planted].side]
        place[held] = place[np.nonzero(held)[0][-1]]  # where it stands, down all along
        support[held] = True
    for column, side in enumerate(("right", "left")):
        # a foot in the air moves from its old path onto the new one by its landing
        down = np.nonzero(support[:, column])[0]
        landing = int(down[0]) if len(down) else len(support)
        old = current.feet[side][k:k + landing]
        if landing > 0 and len(old) == landing:
            blend = smoothstep5((np.arange(landing) + 1.0) / landing)[:, None]
            feet[side][:landing] = old + blend * (feet[side][:landing] - old)
        elif landing == 0:
            now = current.feet[side][min(k, current.n - 1)]
            if not current.support[min(k, current.n - 1), column]:
                # down at once (a swing ended early, ``row`` past its landing): from the
                # command now onto the landing place, where the foot already stands
                n = min(TOUCH_BLEND_ROWS, len(support))
            elif np.max(np.abs(feet[side][0] - now)) > HELD_TOLERANCE:
                # down now and then, held elsewhere than the new pattern has it (a correction's
                # lead-in, :func:`~hubo_cli.walking.lead_in.blend_from_held`, not yet done):
                # onto it over its stance's rows before a lift-off, at most HELD_BLEND_ROWS
                lifted = np.nonzero(~support[:, column])[0]
                n = min(int(lifted[0]) if len(lifted) else len(support), HELD_BLEND_ROWS)
            else:
                continue
            if n > 0:
                blend = smoothstep5((np.arange(n) + 1.0) / n)[:, None]
                feet[side][:n] = now + blend * (feet[side][:n] - now)
    zmp_ref = full.zmp_ref_m[row:]
    com = current.com
    gains = preview_gains(period, current.com_height_m, params.preview_s, params.zmp_weight,
                          params.jerk_weight)
    rows = None if rows_per_period is None else prefix_rows(len(zmp_ref), rows_per_period) + 1
    path = com_from_zmp(zmp_ref, gains, com.com_m[k],
                        (com.com_velocity_m_s[k], com.com_acceleration_m_s2[k]), rows)
    return replace(full, zmp_ref_m=zmp_ref, com=path, feet=feet, support=support,
                   step_index=full.step_index[row:],
                   # a correction's lead-in in progress: its turn continued
                   torso_lead_rad=_lead_rows(current.torso_lead_rad, k, None))


def prefix_rows(n: int, rows_per_period: int) -> int:
    """How many of a re-plan's ``n`` rows are solved at once: the periods the rest (three
    passes over at most ``n`` rows, ``rows_per_period`` a period) takes to compute, and
    PREFIX_LEAD_PERIODS; all ``n`` when that is more."""
    return min(n, PREFIX_LEAD_PERIODS + 3 * math.ceil(n / rows_per_period))


def gait_rows(gait: Gait, first: int, last: int | None = None) -> Gait:
    """Rows ``first:last`` of a flat ``gait`` (its footsteps all kept)."""
    com = gait.com
    return replace(gait, zmp_ref_m=gait.zmp_ref_m[first:last],
                   com=CoMPath(com.com_m[first:last], com.com_velocity_m_s[first:last],
                               com.com_acceleration_m_s2[first:last], com.zmp_m[first:last]),
                   feet={side: rows[first:last] for side, rows in gait.feet.items()},
                   support=gait.support[first:last], step_index=gait.step_index[first:last],
                   torso_lead_rad=_lead_rows(gait.torso_lead_rad, first, last))


def _lead_rows(lead: np.ndarray | None, first: int, last: int | None) -> np.ndarray | None:
    """Rows ``first:last`` of a lead-in's torso turn (None when none is left)."""
    if lead is None or first >= len(lead):
        return None
    return lead[first:last]


def rest_of(cart: Gait, first: int, params: WalkingParams) -> Gait:
    """Rows ``first:`` of a re-plan's ``cart`` (:func:`pattern_from`, its CoM path computed
    over them at least up to row ``first``) with their CoM path, continued from its state at
    that row."""
    rest = gait_rows(cart, first)
    com = rest.com
    gains = preview_gains(cart.period_s, cart.com_height_m, params.preview_s,
                          params.zmp_weight, params.jerk_weight)
    return replace(rest, com=com_from_zmp(rest.zmp_ref_m, gains, com.com_m[0],
                                          (com.com_velocity_m_s[0],
                                           com.com_acceleration_m_s2[0])))


def continued_fix(fix: Fix, k: int, n: int) -> Fix:
    """The multi-body correction ``fix`` from row ``k`` on, ``n`` rows: cut, or held at its
    last position (at rest) past its end."""
    position, velocity, acceleration = (np.asarray(part[k:k + n], dtype=float) for part in fix)
    short = n - len(position)
    if short > 0:
        last = position[-1] if len(position) else np.asarray(fix[0][-1], dtype=float)
        position = np.vstack([position, np.tile(last, (short, 1))])
        velocity, acceleration = (np.vstack([part, np.zeros((short, 2))])
                                  for part in (velocity, acceleration))
    return position, velocity, acceleration


def with_fix(gait: Gait, fix: Fix) -> Gait:
    """``gait`` with its CoM path moved by the multi-body correction ``fix`` (as many rows),
    its cart-table ZMP moved as that motion moves it (p = c - z_c / g c'')."""
    com = gait.com
    position, velocity, acceleration = fix
    zmp = position - gait.com_height_m / GRAVITY_M_S2 * acceleration
    return replace(gait, com=CoMPath(com.com_m + position, com.com_velocity_m_s + velocity,
                                     com.com_acceleration_m_s2 + acceleration, com.zmp_m + zmp))
