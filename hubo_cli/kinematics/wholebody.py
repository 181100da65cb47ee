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

CoM control (hrpsys AutoBalancer, standing; optional): the legs also move the torso forward or
back by ``shift_m`` (upright, feet fixed), so the neck frame is N = S shifted by
(shift_m, 0, lift_m), and the arms solve their goals in that N: the hands keep their goals in S.
The shift is chosen so that the static balance point -- the ground projection of the CoM of the
model's masses (pinocchio, the tool included), moved by the hands' expected forces as in the
multi-layer paper's eq. 5-6 -- lies at the centre of the two soles. As hrpsys's
``solveFullbodyIK`` does, each solve moves the waist by ``COM_GAIN`` x the balance point's error
(:meth:`WholeBody.next_shift`); a caller that solves period by period passes the previous
period's next shift, so the waist follows the arms continuously at the cost of one CoM per
period. Sideways the hips' Table IV roll limits (0 in the standing posture) leave no room, so
the shift is along x only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import ConfigError
from hubo_cli.kinematics.dh import kernel_array, mul4
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
        shift_m: how far the legs moved the neck forward over the feet (m, CoM control).
        balance_error_m: support centre minus the static balance point along x (m) with this
            solution (0 without CoM control).
    """

    q_rad: np.ndarray
    lift_m: float
    arms: dict[str, IKResult]
    legs: dict[str, IKResult]
    lift_capped: bool
    shift_m: float = 0.0
    balance_error_m: float = 0.0


COM_GAIN = 0.8         # hrpsys SimpleFullbodyInverseKinematicsSolver: 0.8 x the CoM error
MAX_SHIFT_M = 0.12     # the waist's reach forward or back over the feet
MAX_SHIFT_STEP_M = 0.0005  # per solve: 0.1 m/s at 200 Hz
STEADY_ITERATIONS = 4
_EYE4 = np.eye(4)  # copied, not rebuilt, every solve


class WholeBody:
    """Solve hand goals with legs and arms together.

    Args:
        model: the robot model.
        tools: arm name -> tool (``hand``, ``drill``, ``none``).
        working_height_m: hand height in the neck frame the legs aim for (paper: 0, shoulder level).
        knee_range_rad: knee angles the height search may use (keeps clear of the straight-knee
            singularity and of deep crouches).
        com_control: move the waist so the static balance point sits at the support centre
            (see the module docstring).
        support_offset_m: where along x the balance point should sit, from the soles' centre
            (m); inside the soles.

    Raises:
        ConfigError: a support offset that puts the balance point outside the soles.
    """

    def __init__(self, model: RobotModel, tools: dict[str, str] | None = None,
                 working_height_m: float = 0.0,
                 knee_range_rad: tuple[float, float] = (0.45, 1.6),
                 com_control: bool = False, support_offset_m: float = 0.0) -> None:
        tools = tools or {}
        self.model = model
        self.tools = {name: tools.get(name, "hand") for name in ARMS}  # arm -> tool held
        self.arms = {name: Limb(model, name, self.tools[name]) for name in ARMS}
        self.legs = {name: Limb(model, name) for name in LEGS}
        self._slices = {name: model.limb_slice(name) for name in (*ARMS, *LEGS)}
        self._last_leg: dict[str, tuple] = {}  # leg -> ((lift, shift, q_prev bytes), IKResult)
        self.working_height_m = working_height_m
        self.q_home = home_posture(model)
        self.T_S_sole = {name: leg.fk(self.q_home[model.limb_slice(name)])
                         for name, leg in self.legs.items()}
        self.lift_range_m = self._lift_range(knee_range_rad)
        self.com_control = bool(com_control)
        feet = model.feet
        half = feet.length_m / 2
        if not (np.isfinite(support_offset_m) and abs(support_offset_m) < half):
            raise ConfigError(f"the balance point's offset {support_offset_m * 1000:+.0f} mm lies "
                              f"outside the soles (+-{half * 1000:.0f} mm from their centre)",
                              hint="use an offset inside the feet, e.g. 0")
        sole_x = np.mean([T[0, 3] for T in self.T_S_sole.values()])
        self.support_x_m = float(sole_x + feet.forward_m + support_offset_m)
        self._ground_z_m = float(np.mean([T[2, 3] for T in self.T_S_sole.values()]))
        self._pin = None
        if self.com_control:
            from hubo_cli.pin_robot import load_pin_robot

            urdf = model.urdf_path(drill=self.tools["right-arm"] == "drill")
            # floating, the torso at the origin: a fixed base would leave the torso's mass out
            self._pin = load_pin_robot(model, floating=True, urdf_path=urdf)
            self._pin_data = self._pin.model.createData()
            self._weight_n = self._pin.weight_n
            # how far the balance point moves per metre of waist shift (the legs' own mass
            # moves less than the torso's): about 0.7, measured once at the home posture
            moved = [self._solve({}, None, None, s, None).balance_error_m for s in (0.0, 0.01)]
            self.shift_gain = float((moved[0] - moved[1]) / 0.01)

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
        sl = self._slices["right-leg"]
        return float(self.T_S_sole["right-leg"][2, 3] - self.legs["right-leg"].fk(q_rad[sl])[2, 3])

    def shift_of(self, q_rad: np.ndarray) -> float:
        """The neck's shift forward over the feet (m) that the leg joints of a full joint
        vector produce (right leg; CoM control)."""
        sl = self.model.limb_slice("right-leg")
        return float(self.T_S_sole["right-leg"][0, 3] - self.legs["right-leg"].fk(q_rad[sl])[0, 3])

    def balance_point_x(self, q_rad: np.ndarray, shift_m: float,
                        T_S_goal: dict[str, np.ndarray] | None = None,
                        hand_forces_n: dict[str, np.ndarray] | None = None) -> float:
        """The static balance point along x in S (m): the CoM's ground projection, moved by
        the forces the environment exerts on the hands (N, in S, at their goals) as in the
        multi-layer paper's eq. 5-6: p = (W x_G + sum(z_h F_x - x_h F_z)) / (W - sum F_z)."""
        import pinocchio

        q = self._pin.configuration(q_rad, None)
        com_x = float(pinocchio.centerOfMass(self._pin.model, self._pin_data, q, False)[0])
        x_g = com_x + shift_m
        if not hand_forces_n:
            return x_g
        num, den = self._weight_n * x_g, self._weight_n
        for arm, force in hand_forces_n.items():
            x_h, z_h = float(T_S_goal[arm][0, 3]), float(T_S_goal[arm][2, 3]) - self._ground_z_m
            num += z_h * float(force[0]) - x_h * float(force[2])
            den -= float(force[2])
        return num / den

    def next_shift(self, result: WholeBodyResult) -> float:
        """The shift (m) to solve the next period with: the waist moved by ``COM_GAIN`` x what
        the balance error needs, at most ``MAX_SHIFT_STEP_M`` per solve, within ``MAX_SHIFT_M``."""
        step = float(np.clip(COM_GAIN * result.balance_error_m / self.shift_gain,
                             -MAX_SHIFT_STEP_M,
                             MAX_SHIFT_STEP_M))
        return float(np.clip(result.shift_m + step, -MAX_SHIFT_M, MAX_SHIFT_M))

    def lift_for(self, T_S_goal: dict[str, np.ndarray]) -> float:
        """The lift (m) the legs aim for with these goals: mean goal height minus the working
        height, within the legs' range."""
        return self._lift_within_range(self._mean_goal_height(T_S_goal) - self.working_height_m)

    @staticmethod
    def _mean_goal_height(T_S_goal: dict[str, np.ndarray]) -> float:
        """The goals' mean height in the stance frame (m); 0 without goals."""
        return sum(float(T[2, 3]) for T in T_S_goal.values()) / len(T_S_goal) if T_S_goal else 0.0

    def solve(self, T_S_goal: dict[str, np.ndarray], q_prev_rad: np.ndarray | None = None,
              lift_m: float | None = None, shift_m: float | None = None,
              hand_forces_n: dict[str, np.ndarray] | None = None) -> WholeBodyResult:
        """Solve goals for one or both arms (arm name -> T_S_E, 4x4 m).

        Args:
            T_S_goal: hand (tool) goals in the stance frame.
            q_prev_rad: previous full joint vector; home posture if None.
            lift_m: impose the legs' lift (m, clipped to their range) instead of deriving it
                from the goal heights (e.g. while moving between postures).
            shift_m: the waist's shift forward over the feet to solve with (m; e.g. the
                previous period's :meth:`next_shift`, or a task's constant shift); None: with
                CoM control the steady shift for these goals (iterated), else 0.
            hand_forces_n: with CoM control, the forces the environment is expected to exert
                on the hands (arm -> 3-vector in S, N), e.g. a drill's thrust.
        """
        if shift_m is not None:
            return self._solve(T_S_goal, q_prev_rad, lift_m, float(shift_m), hand_forces_n)
        if not self.com_control:
            return self._solve(T_S_goal, q_prev_rad, lift_m, 0.0, None)
        shift = 0.0
        for _ in range(STEADY_ITERATIONS):
            result = self._solve(T_S_goal, q_prev_rad, lift_m, shift, hand_forces_n)
            shift = min(max(shift + result.balance_error_m / self.shift_gain, -MAX_SHIFT_M),
                        MAX_SHIFT_M)
        return self._solve(T_S_goal, q_prev_rad, lift_m, shift, hand_forces_n)

    def legs_at(self, q_prev_rad: np.ndarray, lift_m: float) -> tuple[np.ndarray, float]:
        """``solve({}, q_prev_rad, lift_m=lift_m)``'s joints and lift (the same numbers: each
        leg's :meth:`Limb.solve_into`, its goal ``T_N_S @ T_S_sole`` compiled: each entry the
        sum of four products of which at most one is neither zero nor exact, so numpy's to the
        last bit and sign) without the result objects: the teleoperation solves the legs every
        period (its lift filter moves every period). With CoM control it is :meth:`solve`
        (its shift needs the whole solve)."""
        if self.com_control:
            result = self.solve({}, q_prev_rad, lift_m=lift_m)
            return result.q_rad, result.lift_m
        lift = self._lift_within_range(float(lift_m))
        q_prev = kernel_array(q_prev_rad)
        q = q_prev.copy()
        T_N_S, T_goal = self._T_N_S(lift, 0.0), np.empty((4, 4))
        for name in LEGS:
            sl = self._slices[name]
            mul4(T_N_S, self.T_S_sole[name], T_goal)
            self.legs[name].solve_into(T_goal, q_prev[sl], q[sl])
        return q, lift

    def _lift_within_range(self, lift_m: float) -> float:
        """The lift (m) clipped to the legs' range (a NaN as it is)."""
        lo, hi = self.lift_range_m
        return min(max(lift_m, lo), hi)

    @staticmethod
    def _T_N_S(lift_m: float, shift_m: float) -> np.ndarray:
        """The stance frame S in the neck frame N with the legs at ``lift_m`` and the waist
        shifted forward by ``shift_m`` (4x4, m)."""
        T_N_S = _EYE4.copy()
        T_N_S[0, 3], T_N_S[2, 3] = -shift_m, -lift_m
        return T_N_S

    def _solve(self, T_S_goal, q_prev_rad, lift_m, shift_m, hand_forces_n) -> WholeBodyResult:
        q_prev = self.q_home if q_prev_rad is None else np.asarray(q_prev_rad, dtype=float)
        q = q_prev.copy()
        if lift_m is None:
            wanted = self._mean_goal_height(T_S_goal) - self.working_height_m
        else:
            wanted = float(lift_m)
        lift = self._lift_within_range(wanted)
        T_N_S = self._T_N_S(lift, shift_m)
        legs = {}
        for name, leg in self.legs.items():
            sl = self._slices[name]
            # the legs' goal depends on the lift and shift alone: while both hold (a level cut,
            # a wait) the same goal from the same joints has the same answer as last time
            key = (lift, shift_m, q_prev[sl].tobytes())
            last = self._last_leg.get(name)
            if last is not None and last[0] == key:
                result = last[1]
            else:
                result = leg.solve(T_N_S @ self.T_S_sole[name], q_prev[sl])
                self._last_leg[name] = (key, result)
            legs[name] = result
            q[sl] = result.q_rad
        arms = {}
        for name, T_S_E in T_S_goal.items():
            sl = self._slices[name]
            result = self.arms[name].solve(T_N_S @ np.asarray(T_S_E, dtype=float), q_prev[sl])
            arms[name] = result
            q[sl] = result.q_rad
        error = 0.0
        if self.com_control:
            error = self.support_x_m - self.balance_point_x(q, shift_m, T_S_goal, hand_forces_n)
        return WholeBodyResult(q, lift, arms, legs, lift_capped=bool(wanted != lift),
                               shift_m=float(shift_m), balance_error_m=float(error))


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
        # Python floats (min/max, math.sqrt): the same values as numpy's, at a tenth of the cost
        speed = float(min(max(gap / dt_s, -self.max_speed_m_s), self.max_speed_m_s))
        if self.max_accel_m_s2 is not None:
            a = self.max_accel_m_s2
            stop = math.sqrt(2 * a * abs(gap))  # the speed that can still stop on it
            speed = min(max(speed, -stop), stop)
            speed = min(max(speed, self.speed_m_s - a * dt_s), self.speed_m_s + a * dt_s)
        self.speed_m_s = speed
        self.lift_m += speed * dt_s
        return self.lift_m
