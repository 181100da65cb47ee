"""Arm + leg inverse kinematics (paper III-A): the legs carry the shoulders toward the goal
height, the arms do the rest.

Frames: goals are given in the *stance frame* S, the neck frame of the home posture with the
feet fixed on the ground (S does not move when the robot crouches or rises). When the legs
raise the torso by ``lift_m`` (torso kept upright, feet fixed), the neck frame becomes
N = S shifted up by lift_m, so a hand goal T_S_hand is T_N_hand = Tz(-lift_m) T_S_hand and each
sole, fixed in S, is T_N_sole = Tz(-lift_m) T_S_sole.

Algorithm: (1) take the goal heights; (2) lift = mean goal height - preferred working height,
clipped to what the legs can do (knee kept inside [knee_min, knee_max] and the joint limits);
legs solved with their IK; (3) arms solved in the new neck frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.kinematics.limb import IKResult, Limb
from hubo_cli.model import ARMS, LEGS, RobotModel
from hubo_cli.posture import home_posture


@dataclass(frozen=True)
class WholeBodyResult:
    """One whole-body solution.

    Attributes:
        q_rad: the full joint vector (model.joint_names order).
        lift_m: how far the legs raised the neck above its home height (negative = crouch).
        arms: per arm that had a goal, its IK result (in the lifted neck frame).
        legs: per leg, its IK result.
        lift_capped: True when the goal height needed more lift than the legs can give.
    """

    q_rad: np.ndarray
    lift_m: float
    arms: dict[str, IKResult]
    legs: dict[str, IKResult]
    lift_capped: bool


class WholeBody:
    """Solve hand goals with legs and arms together.

    Args:
        model: the robot model.
        tools: arm name -> tool (``hand``, ``drill``, ``none``).
        working_height_m: hand height in the neck frame the legs aim for (paper: 0, shoulder level).
        knee_range_rad: knee angles the height search may use (keeps clear of the straight-knee
            singularity and of deep crouches).
    """

    def __init__(self, model: RobotModel, tools: dict[str, str] | None = None,
                 working_height_m: float = 0.0,
                 knee_range_rad: tuple[float, float] = (0.45, 1.6)) -> None:
        tools = tools or {}
        self.model = model
        self.tools = {name: tools.get(name, "hand") for name in ARMS}  # arm -> tool held
        self.arms = {name: Limb(model, name, self.tools[name]) for name in ARMS}
        self.legs = {name: Limb(model, name) for name in LEGS}
        self.working_height_m = working_height_m
        self.q_home = home_posture(model)
        self.T_S_sole = {name: leg.fk(self.q_home[model.limb_slice(name)])
                         for name, leg in self.legs.items()}
        self.lift_range_m = self._lift_range(knee_range_rad)

    def _lift_range(self, knee_range_rad: tuple[float, float]) -> tuple[float, float]:
        """Neck lift (m) at the two knee bounds, legs symmetric, soles flat under the hips."""
        L = self.model.lengths_m
        q_home_knee = self.q_home[self.model.limb_slice("right-leg")][3]

        def hip_height(knee: float) -> float:
            return float(np.sqrt(L["lL3"] ** 2 + L["lL4"] ** 2
                                 + 2 * L["lL3"] * L["lL4"] * np.cos(knee)))

        home = hip_height(q_home_knee)
        lo, hi = knee_range_rad
        return hip_height(hi) - home, hip_height(lo) - home

    def lift_of(self, q_rad: np.ndarray) -> float:
        """The neck lift (m) that the leg joints of a full joint vector produce (right leg)."""
        sl = self.model.limb_slice("right-leg")
        return float(self.T_S_sole["right-leg"][2, 3] - self.legs["right-leg"].fk(q_rad[sl])[2, 3])

    def lift_for(self, T_S_goal: dict[str, np.ndarray]) -> float:
        """The lift (m) the legs aim for with these goals: mean goal height minus the working
        height, within the legs' range."""
        heights = [float(T[2, 3]) for T in T_S_goal.values()]
        wanted = (np.mean(heights) if heights else 0.0) - self.working_height_m
        return float(np.clip(wanted, *self.lift_range_m))

    def solve(self, T_S_goal: dict[str, np.ndarray], q_prev_rad: np.ndarray | None = None,
              lift_m: float | None = None) -> WholeBodyResult:
        """Solve goals for one or both arms (arm name -> T_S_E, 4x4 m).

        Args:
            T_S_goal: hand (tool) goals in the stance frame.
            q_prev_rad: previous full joint vector; home posture if None.
            lift_m: impose the legs' lift (m, clipped to their range) instead of deriving it
                from the goal heights (e.g. while moving between postures).
        """
        q_prev = self.q_home if q_prev_rad is None else np.asarray(q_prev_rad, dtype=float)
        q = q_prev.copy()
        heights = [float(T[2, 3]) for T in T_S_goal.values()]
        wanted = (np.mean(heights) if heights else 0.0) - self.working_height_m
        if lift_m is not None:
            wanted = float(lift_m)
        lo, hi = self.lift_range_m
        lift = float(np.clip(wanted, lo, hi))
        down = np.eye(4)
        down[2, 3] = -lift
        legs = {}
        for name, leg in self.legs.items():
            sl = self.model.limb_slice(name)
            result = leg.solve(down @ self.T_S_sole[name], q_prev[sl])
            legs[name] = result
            q[sl] = result.q_rad
        arms = {}
        for name, T_S_E in T_S_goal.items():
            sl = self.model.limb_slice(name)
            result = self.arms[name].solve(down @ np.asarray(T_S_E, dtype=float), q_prev[sl])
            arms[name] = result
            q[sl] = result.q_rad
        return WholeBodyResult(q, lift, arms, legs, lift_capped=bool(wanted != lift))


class LiftFilter:
    """Smooths the legs' lift so the body moves calmly while the arms take the fast part.

    The arms solve the hand goal exactly for whatever lift the legs have, so the legs need not
    follow every millimetre of the operator's height (tremor included). Moving them slowly keeps
    each leg's joints in proportion (the sole stays flat; joint-space tracking of a fast crouch
    tilts it) and the centre of mass still.

    Args:
        max_speed_m_s: the lift's speed limit.
        time_constant_s: first-order smoothing of the wanted lift before the speed limit.
        max_accel_m_s2: the lift's acceleration limit (None: none); the speed then also drops
            in time to stop on the wanted lift.
    """

    def __init__(self, max_speed_m_s: float = 0.02, time_constant_s: float = 0.3,
                 max_accel_m_s2: float | None = None) -> None:
        self.max_speed_m_s = max_speed_m_s
        self.time_constant_s = time_constant_s
        self.max_accel_m_s2 = max_accel_m_s2
        self.lift_m: float | None = None
        self.speed_m_s = 0.0
        self._smoothed: float | None = None

    def reset(self, lift_m: float) -> None:
        self.lift_m = self._smoothed = float(lift_m)
        self.speed_m_s = 0.0

    def step(self, wanted_m: float, dt_s: float) -> float:
        """Advance one period toward ``wanted_m``; returns the lift to use (m)."""
        if self.lift_m is None:
            self.reset(wanted_m)
            return self.lift_m
        alpha = dt_s / (self.time_constant_s + dt_s)
        self._smoothed += alpha * (wanted_m - self._smoothed)
        gap = self._smoothed - self.lift_m
        speed = float(np.clip(gap / dt_s, -self.max_speed_m_s, self.max_speed_m_s))
        if self.max_accel_m_s2 is not None:
            a = self.max_accel_m_s2
            stop = float(np.sqrt(2 * a * abs(gap)))  # the speed that can still stop on it
            speed = float(np.clip(speed, -stop, stop))
            speed = float(np.clip(speed, self.speed_m_s - a * dt_s, self.speed_m_s + a * dt_s))
        self.speed_m_s = speed
        self.lift_m += speed * dt_s
        return self.lift_m
