"""Toe-heel contact: the reference ZMP from each sole's CoP and the swing sole's roll on its
edges (multi-layer paper III-C.1, eq. 4 and Fig. 4; hrpsys-base ``GaitGenerator``'s toe-heel
phases, the paper's five being hrpsys's seven with no flat middle phase).

One step lasts the sum of five phases (the robot file's ``[toe_heel] phase_s``; the paper's
Fig. 4: 0.05, 0.25, 0.4, 0.25, 0.05 s, a 1.0 s step). Through them the *swing* foot's CoP
offset x (m, along its sole from the foot origin, the ankle's projection) and its angle offset
(rad, about the sole's y axis; positive: heel up, rolling on the toe) go:

    phase                   CoP offset x                angle            pivot
    (i)   sole              origin -> toe, linear       0                -
    (ii)  sole to toe       toe                         0 -> theta_toe   toe edge
    (iii) toe to heel       toe -> heel, linear         theta_toe -> -theta_heel  toe -> heel
    (iv)  heel to sole      heel                        -theta_heel -> 0 heel edge
    (v)   sole              heel -> origin, linear      0                -

The angle moves on minimum-jerk (Hoff-Arbib, eq. 1-2) profiles from rest to rest within each
phase; in (iii) the pivot follows the angle from the toe edge to the heel edge (hrpsys with no
flat phase). A backward step runs the five phases in reverse (heel first); a step shorter than
``min_step_m`` either way lands flat (CoP at the origin, angle 0). The toe and heel CoP offsets
are the sole's front and back edges (the robot file's ``[feet]`` box), where the sole rolls.

The support foot's CoP stays at its origin. Eq. 4 blends the two::

    p_zmp = (1 - r) p_rcop + r p_lcop

with r = 0 in right support, 1 in left support, moving linearly through each double support
(the last ``double_support_s / 2`` of a step and the first of the next; 0.5 at the boundary
and while standing). The swing foot's pose follows from the angle and the pivot
(:func:`ankle_offset`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import ConfigError
from hubo_cli.geometry import min_jerk
from hubo_cli.model import FootShape, RobotModel
from hubo_cli.walking.footsteps import Footstep

RIGHT, LEFT = 0, 1
FOOT_INDEX = {"right": RIGHT, "left": LEFT}


@dataclass(frozen=True)
class ToeHeelParams:
    """The robot file's ``[toe_heel]`` table (see its comments).

    Attributes:
        phase_s: the five phases (i)-(v) of a forward step (s, each >= 0, summing > 0).
        toe_angle_rad: theta_toe, the largest roll on the toe (rad, >= 0).
        heel_angle_rad: theta_heel, the largest roll on the heel (rad, >= 0).
        min_step_m: a step shorter than this, forward or back, lands flat (m, >= 0).
    """

    phase_s: tuple[float, float, float, float, float]
    toe_angle_rad: float
    heel_angle_rad: float
    min_step_m: float

    def __post_init__(self) -> None:
        def number(v) -> bool:
            return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)

        if len(self.phase_s) != 5 or not all(number(t) and t >= 0 for t in self.phase_s) \
                or sum(self.phase_s) <= 0:
            raise ConfigError(f"phase_s must be five times >= 0 (s) with a positive sum, got "
                              f"{self.phase_s!r}", field="toe_heel.phase_s",
                              hint="the paper's: [0.05, 0.25, 0.4, 0.25, 0.05]")
        for name in ("toe_angle_rad", "heel_angle_rad", "min_step_m"):
            value = getattr(self, name)
            if not (number(value) and value >= 0):
                raise ConfigError(f"must be a number >= 0, got {value!r}",
                                  field=f"toe_heel.{name}")
        if max(self.toe_angle_rad, self.heel_angle_rad) >= math.pi / 2:
            raise ConfigError("a toe or heel angle of 90 degrees or more stands the foot on end",
                              field="toe_heel")

    @property
    def step_s(self) -> float:
        """One step: the five phases (s)."""
        return float(sum(self.phase_s))

    def scaled_to(self, step_s: float) -> ToeHeelParams:
        """The same phases in proportion, lasting ``step_s`` in all (s): the walking's step."""
        factor = float(step_s) / self.step_s
        return ToeHeelParams(tuple(factor * t for t in self.phase_s), self.toe_angle_rad,
                             self.heel_angle_rad, self.min_step_m)

    @classmethod
    def from_model(cls, model: RobotModel) -> ToeHeelParams:
        raw = model.raw_table("toe_heel")
        try:
            phases = tuple(raw.get("phase_s", ()))
        except TypeError:
            phases = (raw.get("phase_s"),)
        try:
            return cls(phases, raw.get("toe_angle_rad"), raw.get("heel_angle_rad"),
                       raw.get("min_step_m"))
        except ConfigError as exc:
            raise ConfigError(exc.message, path=str(model.source), hint=exc.hint) from None


def sole_edges_m(feet: FootShape) -> tuple[float, float]:
    """(toe, heel): the sole's front and back edges along x from the foot origin (m)."""
    return feet.forward_m + feet.length_m / 2, feet.forward_m - feet.length_m / 2


def swing_profile(t_s, params: ToeHeelParams, feet: FootShape, direction: int = 1):
    """The swing foot's CoP offset x (m), angle offset (rad) and pivot x (m) at times ``t_s``
    (s, array) from the start of its step (see the module docstring).

    ``direction``: +1 forward, -1 backward (the phases reversed), 0 flat.
    """
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if direction == 0:
        zeros = np.zeros_like(t)
        return zeros, zeros.copy(), zeros.copy()
    if direction < 0:  # reversed phases: the forward profile played backward in time
        return swing_profile(params.step_s - t, params, feet, 1)
    toe, heel = sole_edges_m(feet)
    th_toe, th_heel = params.toe_angle_rad, params.heel_angle_rad
    ends = np.cumsum(params.phase_s)
    starts = ends - np.asarray(params.phase_s)

    def progress(i):  # linear 0 -> 1 through phase i (a zero-length phase: a step)
        length = params.phase_s[i]
        if length <= 0:
            return (t >= ends[i]).astype(float)
        return np.clip((t - starts[i]) / length, 0.0, 1.0)

    s = [progress(i) for i in range(5)]
    cop = np.select([t < ends[0], t < ends[1], t < ends[2], t < ends[3]],
                    [toe * s[0], np.full_like(t, toe), toe + (heel - toe) * s[2],
                     np.full_like(t, heel)], default=heel * (1 - s[4]))
    angle = np.select([t < starts[1], t < ends[1], t < ends[2], t < ends[3]],
                      [np.zeros_like(t), th_toe * min_jerk(s[1]),
                       th_toe + (-th_heel - th_toe) * min_jerk(s[2]),
                       -th_heel * (1 - min_jerk(s[3]))], default=0.0)
    span = th_toe + th_heel
    rolled = toe + (heel - toe) * ((th_toe - angle) / span if span > 0 else s[2])
    pivot = np.select([t < ends[1], t < ends[2]], [np.full_like(t, toe), rolled], default=heel)
    return cop, angle, pivot


def ankle_offset(angle_rad, pivot_x_m) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dz) (m, sole frame) of the foot origin when the sole turns by ``angle_rad`` about
    its y axis on the edge at ``pivot_x_m``: the pivot stays put (hrpsys
    ``modif_foot_coords_for_toe_heel_phase``)."""
    a = np.asarray(angle_rad, dtype=float)
    p = np.asarray(pivot_x_m, dtype=float)
    return p * (1 - np.cos(a)), p * np.sin(a)


@dataclass
class ToeHeelPlan:
    """The reference of a toe-heel walk, one row per period; feet indexed (right, left).

    Attributes:
        t_s: (n,) time (s).
        cop_offset_m: (n, 2) each foot's CoP offset x along its sole from its origin (m).
        foot_angle_rad: (n, 2) each foot's angle offset (rad, positive: on the toe).
        pivot_m: (n, 2) the edge each foot turns on, x along its sole (m).
        foot_pose: (n, 2, 3) each foot's planned (x, y, yaw) on the ground (the swing foot's
            landing pose from the middle of its step).
        cop_m: (n, 2, 2) each foot's CoP in the world (m).
        ratio: (n,) r of eq. 4 (0: right support, 1: left).
        zmp_m: (n, 2) the reference ZMP, eq. 4 (m).
        swing: (n,) the swinging foot's index, -1 while both stand.
        direction: (n,) +1 forward, -1 backward, 0 flat (the swinging foot's step).
    """

    t_s: np.ndarray
    cop_offset_m: np.ndarray
    foot_angle_rad: np.ndarray
    pivot_m: np.ndarray
    foot_pose: np.ndarray
    cop_m: np.ndarray
    ratio: np.ndarray
    zmp_m: np.ndarray
    swing: np.ndarray
    direction: np.ndarray

    def take(self, rows: np.ndarray) -> ToeHeelPlan:
        """The plan at these rows (indices into its periods), in their order."""
        return ToeHeelPlan(self.t_s[rows], self.cop_offset_m[rows], self.foot_angle_rad[rows],
                           self.pivot_m[rows], self.foot_pose[rows], self.cop_m[rows],
                           self.ratio[rows], self.zmp_m[rows], self.swing[rows],
                           self.direction[rows])


def step_direction(start: Footstep, landing: Footstep, min_step_m: float) -> int:
    """+1, -1 or 0: the swing foot's travel along its own heading at the start."""
    along = (math.cos(start.yaw_rad) * (landing.x_m - start.x_m)
             + math.sin(start.yaw_rad) * (landing.y_m - start.y_m))
    return 1 if along > min_step_m else -1 if along < -min_step_m else 0


def plan_toe_heel_walk(right: Footstep, left: Footstep, steps: list[Footstep],
                       params: ToeHeelParams, feet: FootShape, double_support_s: float,
                       period_s: float, stand_s: float = 0.5,
                       inset_m: float = 0.0) -> ToeHeelPlan:
    """The CoP offsets, foot angles and reference ZMP (eq. 4) of a walk.

    Args:
        right, left: the feet before the first step.
        steps: the landings, sides alternating (as :func:`~hubo_cli.walking.footsteps.
            plan_footsteps` gives them).
        params: the phases and angles.
        feet: the sole's shape.
        double_support_s: each double support, centred on a step boundary (s, < a step).
        period_s: the sample period (s).
        stand_s: standing before the first step and after the last (s).
        inset_m: every CoP lies this far inside its foot's centre line, toward the other foot
            (m; the walking's ``zmp_inset_m``: the CoM sways less).
    """
    step_s = params.step_s
    if not (math.isfinite(double_support_s) and 0 < double_support_s < step_s):
        raise ConfigError(f"double support {double_support_s!r} s must lie in (0, {step_s}) s")
    if not (math.isfinite(period_s) and 0 < period_s <= step_s / 10):
        raise ConfigError(f"period {period_s!r} s must be positive and a tenth of a step or less")
    if not (math.isfinite(stand_s) and stand_s >= 0):
        raise ConfigError(f"standing time {stand_s!r} s must be >= 0")
    if not (math.isfinite(inset_m) and abs(inset_m) < feet.width_m / 2):
        raise ConfigError(f"CoP inset {inset_m!r} m must lie within the sole's half width")
    current = {"right": right, "left": left}
    for k, step in enumerate([right, left, *steps]):
        if step.side not in FOOT_INDEX:
            raise ConfigError(f"footstep {k}: side {step.side!r} is not 'right' or 'left'")
        if not all(math.isfinite(v) for v in (step.x_m, step.y_m, step.yaw_rad)):
            raise ConfigError(f"footstep {k} is not finite")
    if right.side != "right" or left.side != "left":
        raise ConfigError("the start feet must be the right then the left")
    for k in range(1, len(steps)):
        if steps[k].side == steps[k - 1].side:
            raise ConfigError(f"step {k}: the {steps[k].side} foot steps twice in a row",
                              hint="alternate the feet")
    poses = np.array([[f.x_m, f.y_m, f.yaw_rad] for f in (right, left)])
    n = int(round((2 * stand_s + len(steps) * step_s) / period_s)) + 1
    t = np.arange(n) * period_s
    cop_offset = np.zeros((n, 2))
    angle = np.zeros((n, 2))
    pivot = np.zeros((n, 2))
    foot_pose = np.repeat(poses[None], n, axis=0)
    ratio = np.full(n, 0.5)
    swing = np.full(n, -1)
    direction = np.zeros(n, dtype=int)
    half = double_support_s / 2
    for k, step in enumerate(steps):
        s = FOOT_INDEX[step.side]
        support_ratio = 1.0 - s  # r of the other foot's support: right swings -> left (1)
        t0 = stand_s + k * step_s
        rows = (t >= t0 - 1e-9) & (t < t0 + step_s - 1e-9)
        tau = t[rows] - t0
        d = step_direction(current[step.side], step, params.min_step_m)
        current[step.side] = step
        cop_offset[rows, s], angle[rows, s], pivot[rows, s] = swing_profile(tau, params, feet, d)
        ratio[rows] = np.interp(tau, [0.0, half, step_s - half, step_s],
                                [0.5, support_ratio, support_ratio, 0.5])
        swing[rows], direction[rows] = s, d
        foot_pose[t >= t0 + step_s / 2 - 1e-9, s] = (step.x_m, step.y_m, step.yaw_rad)
    heading = np.stack([np.cos(foot_pose[..., 2]), np.sin(foot_pose[..., 2])], axis=-1)
    normal = np.stack([-heading[..., 1], heading[..., 0]], axis=-1)  # the foot's left
    toward_other = np.array([1.0, -1.0]) * float(inset_m)  # right foot: left; left: right
    cop = (foot_pose[..., :2] + cop_offset[..., None] * heading
           + toward_other[None, :, None] * normal)
    zmp = (1 - ratio)[:, None] * cop[:, RIGHT] + ratio[:, None] * cop[:, LEFT]
    return ToeHeelPlan(t, cop_offset, angle, pivot, foot_pose, cop, ratio, zmp, swing,
                       direction)
