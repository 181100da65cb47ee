"""The torso's pose in the stance frame as the robot measures it, and the hand-goal correction
that holds a tool in the world while the body sways.

Measurement (:func:`torso_in_stance`, :class:`TorsoEstimator`): the feet stand where the stance
frame S puts them, so each leg's forward kinematics from the measured joints gives the neck
frame N in S (the encoders). The IMU corrects the encoders' orientation (a sole rocking on its
edge, the soles' compliance, the feet twisting on the floor, a tilted floor and the ankles'
tracking error turn the body without showing in the leg joints): its tilt as it is, its
heading referenced to the encoders' heading at the first measurement (the IMU's yaw has no
absolute reference; over one run its drift is small). Each foot then pivots about its sole
origin: the neck sits at ``p_S_sole - R_S_N p_N_sole``; the two feet's estimates are averaged.
A real robot has the same inputs: the encoders (``RobotState.q_rad``) and the estimated
attitude (the store's :data:`~hubo_cli.estimation.keys.QUAT_WORLD_TORSO`, which the caller
passes); no simulator ground truth is used.

The estimator fuses the two orientations as a complementary filter: the encoders' orientation
as it is (its noise is the encoders', about 0.5 mrad), times the IMU's rotation from it,
low-passed. About the horizontal axes (:data:`IMU_TILT_TIME_CONSTANT_S`) what the encoders
miss changes slowly (a floor's tilt, an IMU's bias, the soles' compliance under a slowly
moving load), while an IMU's orientation noise (0.2 deg per reading on the perturbed robots)
would otherwise move the measured neck by 3 mm and the measured bit by 4 mm from one period to
the next: the torso correction then chased the noise at its rate bounds instead of the body's
sway. About the vertical axis (:data:`IMU_HEADING_TIME_CONSTANT_S`) the IMU alone sees the
feet twisting on the floor, which on a perturbed robot (foot friction 0.4-1.0) turns the body
by up to 2.4 deg within a cut, at up to 0.5 deg/s: its filter is short.

Correction (:class:`TorsoCorrection`): the joint targets of a plan or of the teleoperation
solver put a hand goal ``T_S_E`` in the neck frame the *commanded* legs give (upright,
T_S_N_cmd). The measured neck frame differs from it by ``T_dev = T_S_N_cmd^-1 T_S_N_meas``
(the body's lean and sway), so the arm is solved for ``T_dev^-1 T_N_E`` instead: the goal given
in S (the wall's frame) re-expressed in the measured frame. ``T_dev`` is low-passed, bounded
in size and in rate, so the arm never jumps. Where the corrected goal has no exact solution
within the joint limits (a plan's pose a few hundredths of a radian from a wrist limit, as the
slot's first pose is), the arm takes the nearest pose on its branch with the tool's position
first (:class:`~hubo_cli.kinematics.arm_reach.ArmReach`, ``position_first_weight_m_per_rad``):
the tool's orientation gives way by up to ``nearest_max_rotation_rad`` while its point stays
within ``nearest_max_position_m`` of the corrected goal. Before, the correction faded out there,
the bit stood 2-3 mm off its pose while the wall was placed, and faded back in once the cut
had left the limit: the hole moved by as much (a perturbed robot's slot, 5.1 mm RMS). Only
where that nearest pose misses too does the correction fade out (and back in) at a bounded rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.geometry import quat_wxyz_to_matrix, rotation_exp, rotation_log
from hubo_cli.kinematics.arm_reach import ArmReach, ReachSettings
from hubo_cli.kinematics.dh import invert4
from hubo_cli.kinematics.limb import IKResult
from hubo_cli.kinematics.torso_kernels import follow_deviation, stance_legs
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import LEGS

IMU_TILT_TIME_CONSTANT_S = 0.5
"""Low-pass time constant of the IMU's correction of the encoders' tilt (s)."""
IMU_HEADING_TIME_CONSTANT_S = 0.1
"""Low-pass time constant of the IMU's correction of the encoders' heading (s)."""


def torso_in_stance(body: WholeBody, q_rad, quat_world_torso_wxyz=None,
                    imu_heading_rad: float | None = None) -> np.ndarray:
    """T_S_N, the neck frame in the stance frame (4x4, m), from the leg joints and the IMU.

    Args:
        body: the whole-body solver (its legs and the soles' places in S).
        q_rad: the full joint vector (measured, or commanded for the nominal pose).
        quat_world_torso_wxyz: the torso's estimated orientation in the world (w, x, y, z);
            None: the encoders' orientation alone.
        imu_heading_rad: the IMU's heading (rad) of S's x axis: the IMU's orientation is then
            used whole, turned by it; None: the IMU's tilt under the encoders' heading.
    """
    quat = quat_world_torso_wxyz
    R_imu = None if quat is None else quat_wxyz_to_matrix(quat)
    return stance_legs(body).pose(q_rad, R_imu, imu_heading_rad)  # compiled (torso_kernels)


class TorsoEstimator:
    """The torso pose from the leg encoders and the IMU, fused (see the module docstring): the
    IMU's heading is referenced once (at the first measurement it is taken to be the encoders':
    the robot stands on its stance), and its rotation from the encoders' orientation is
    low-passed over the states' time.

    Args:
        body: the whole-body solver (legs, soles).
        tilt_time_constant_s, heading_time_constant_s: the low-pass time constants of the
            IMU's part about the neck's x and y axes and about its z axis (0: the IMU's
            orientation as it is, each reading).
    """

    def __init__(self, body: WholeBody,
                 tilt_time_constant_s: float = IMU_TILT_TIME_CONSTANT_S,
                 heading_time_constant_s: float = IMU_HEADING_TIME_CONSTANT_S) -> None:
        self.body = body
        self.time_constants_s = np.array([tilt_time_constant_s, tilt_time_constant_s,
                                          heading_time_constant_s], dtype=float)
        self._legs = stance_legs(body)  # compiles the kernels now, not in a control period
        self._heading = np.zeros(1)  # the filter's state (in place in the compiled kernel):
        self._offset = np.zeros(3)   # the IMU's heading of S's x axis and its rotation offset
        self._referenced = False     # ... set by the first finite IMU reading
        self._alpha = (None, None)   # (dt s, the filter's weights for it)
        self._t_s = 0.0  # the time of the filter's last reading
        self._last: tuple = (None, None, None, None, None)  # (state, time, joints, IMU, T_S_N)

    @property
    def imu_heading_rad(self) -> float | None:
        """The IMU's heading (rad) of S's x axis, referenced at its first reading (None before)."""
        return float(self._heading[0]) if self._referenced else None

    @property
    def imu_offset_rad(self) -> np.ndarray | None:
        """The filter's state: the IMU's rotation from the encoders' orientation (a rotation
        vector in the neck frame, rad), None before the first IMU reading."""
        return self._offset.copy() if self._referenced else None

    def _weights(self, dt_s: float) -> np.ndarray:
        """The filter's weights on a new reading ``dt_s`` after the last one (per neck axis)."""
        if self._alpha[0] != dt_s:
            tau = self.time_constants_s
            self._alpha = (dt_s, np.where(tau > 0.0, -np.expm1(-dt_s / np.maximum(tau, 1e-12)),
                                          1.0))
        return self._alpha[1]

    def __call__(self, state, quat_world_torso_wxyz: np.ndarray) -> np.ndarray:
        """T_S_N (4x4, m) from a :class:`~hubo_cli.state.RobotState`'s joints and the
        estimated torso attitude ``quat_world_torso_wxyz`` (w, x, y, z; the store's
        QUAT_WORLD_TORSO; a reading that is not finite leaves the IMU's part as it was).

        The legs' kinematics, the orientations' mean, the filter step and the pose are one
        compiled call (:func:`~hubo_cli.kinematics.torso_kernels.estimate_pose`); a second call
        with the same reading (the task target measures twice a period) returns the same pose.
        """
        state_last, t_last, q_last, imu_last, T_last = self._last
        if q_last is not None and t_last == state.time_s and (state is state_last or (
                np.array_equal(q_last, state.q_rad)
                and np.array_equal(imu_last, quat_world_torso_wxyz))):
            return T_last
        q = np.asarray(state.q_rad, dtype=float)
        imu = np.asarray(quat_world_torso_wxyz, dtype=float)
        first = False
        alpha = self._no_weights
        if np.isfinite(imu).all():
            first = not self._referenced
            if not first:
                alpha = self._weights(max(0.0, float(state.time_s) - self._t_s))
            self._referenced = True
            self._t_s = float(state.time_s)
        else:
            imu = None
        T = self._legs.estimate(q, imu, first, self._heading, self._offset, alpha)
        self._last = (state, state.time_s, q.copy(),
                      np.array(quat_world_torso_wxyz, dtype=float), T)
        return T

    _no_weights = np.ones(3)  # the first reading is taken as it is; without one, unused


@dataclass(frozen=True)
class CorrectionSettings:
    """How the measured torso pose corrects the hand goals.

    Attributes:
        time_constant_s: first-order low-pass of the deviation (its noise and the fast part
            of the sway, which the loop's delays could not follow).
        max_offset_m: largest translation of the correction.
        max_tilt_rad: largest rotation of the correction (the feet twisting on the floor
            turned a perturbed robot by 2.4 deg within a cut, on a floor tilted by 0.4 deg).
        max_speed_m_s: largest speed of the translation. The correction moves the bit across
            the cardboard at up to this speed, and the cardboard resists that motion (80 N s/m
            in the default cutting model): at 20 mm/s this added up to 0.4 N m of wrist
            torque, and the drill replay's peak sometimes crossed the 1.21 N m stop. At
            10 mm/s it stayed at 1.10-1.13 N m; with the fused torso orientation (the IMU's
            reading noise no longer moves the arm) it peaks at 0.94 N m.
        max_rate_rad_s: largest angular speed of the rotation.
        fade_per_s: how fast the correction fades out where the corrected goal is out of the
            arm's exact reach, and back in (weight per second).
        max_joint_offset_rad: a corrected arm solution further than this from the uncorrected
            one (any joint) counts as out of reach: near a singular configuration or a joint
            limit a small correction would take a large joint motion.
        position_first_weight_m_per_rad: where the corrected goal has no exact solution, the
            nearest pose on the arm's branch weighs one radian of the tool's orientation as
            this many metres of its position (small: the position first).
        nearest_max_position_m, nearest_max_rotation_rad: that nearest pose holds the
            correction when its tool point is within the first of the corrected goal and its
            orientation within the second (a drill bit tilted by a degree cuts the same hole).
    """

    time_constant_s: float = 0.1
    max_offset_m: float = 0.02
    max_tilt_rad: float = float(np.radians(4.0))
    max_speed_m_s: float = 0.01
    max_rate_rad_s: float = float(np.radians(1.0))
    fade_per_s: float = 1.0
    max_joint_offset_rad: float = 0.25
    position_first_weight_m_per_rad: float = 0.01
    nearest_max_position_m: float = 0.2e-3
    nearest_max_rotation_rad: float = float(np.radians(2.0))


class TorsoCorrection:
    """Re-expresses arm goals in the measured neck frame, period by period.

    Args:
        body: the whole-body solver whose arms hold the tools.
        arms: the arms to correct.
        dt_s: the control period (s).
        settings: filter and bounds.
        estimator: the torso pose measurement (None: a new :class:`TorsoEstimator`).
    """

    def __init__(self, body: WholeBody, arms, dt_s: float,
                 settings: CorrectionSettings | None = None,
                 estimator: TorsoEstimator | None = None) -> None:
        self.body = body
        self.estimator = estimator or TorsoEstimator(body)
        self.arms = tuple(arms)
        self._slices = tuple((arm, body.model.limb_slice(arm)) for arm in self.arms)
        self.dt_s = dt_s
        self.settings = settings or CorrectionSettings()
        s = self.settings
        self._bounds = np.array([s.max_offset_m, s.max_speed_m_s * dt_s, s.max_tilt_rad,
                                 s.max_rate_rad_s * dt_s])  # per period
        self.offset_m = np.zeros(3)     # filtered translation of T_dev (in N_cmd axes)
        self.rotation_rad = np.zeros(3)  # filtered rotation vector of T_dev
        self.weight = {arm: 1.0 for arm in self.arms}
        # the position-first nearest pose, on the plan's branch (the drill's wrist margin: the
        # plans' poses already stand there)
        reach = ReachSettings.for_mode(
            "drill", orientation_weight_m_per_rad=s.position_first_weight_m_per_rad)
        self._reach = {arm: ArmReach(body.arms[arm], reach) for arm in self.arms}
        self._T_dev = np.eye(4)  # deviation() as of the last update
        self._T_dev_inv = np.eye(4)  # its inverse
        self._q_out: dict[str, np.ndarray] = {}
        self._dq: dict[str, np.ndarray] = {}  # applied joint offset per arm
        model = body.model
        self._leg_index = np.r_[tuple(model.limb_slice(leg) for leg in LEGS)]
        self._q_legs_cmd: np.ndarray | None = None
        self._T_cmd: np.ndarray | None = None  # torso_in_stance of the commanded legs
        self._T_cmd_inv = np.eye(4)  # its inverse
        follow_deviation(np.eye(4), np.eye(4), np.zeros(3), np.zeros(3), 0.0, self._bounds,
                         np.empty((4, 4)), np.empty((4, 4)))  # compile now, not in a period

    def deviation(self) -> np.ndarray:
        """The filtered and bounded T_dev (4x4): the measured neck frame in the commanded one."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rotation_exp(self.rotation_rad), self.offset_m
        return T

    def update(self, q_cmd_rad, state, quat_world_torso_wxyz: np.ndarray) -> np.ndarray:
        """Advance the filter with this period's measurement (the joints of ``state``, the
        estimated attitude ``quat_world_torso_wxyz``); returns T_dev (4x4). A measurement that
        is not finite (a garbled attitude or encoder reading) leaves it as it was."""
        s = self.settings
        if not (np.isfinite(state.q_rad).all() and np.isfinite(quat_world_torso_wxyz).all()):
            return self._T_dev
        T_meas = self.estimator(state, quat_world_torso_wxyz)
        legs = np.asarray(q_cmd_rad, dtype=float)[self._leg_index]
        if self._T_cmd is None or (legs != self._q_legs_cmd).any():  # the same 12 joints
            self._T_cmd = torso_in_stance(self.body, q_cmd_rad)
            self._T_cmd_inv = _rigid_inverse(self._T_cmd)
            self._q_legs_cmd = legs
        alpha = self.dt_s / (s.time_constant_s + self.dt_s)
        # compiled (torso_kernels): the low-pass of T_cmd^-1 T_meas, its bounds, T_dev, T_dev^-1
        self.offset_m, self.rotation_rad = self.offset_m.copy(), self.rotation_rad.copy()
        self._T_dev, self._T_dev_inv = np.empty((4, 4)), np.empty((4, 4))
        follow_deviation(self._T_cmd_inv, T_meas, self.offset_m, self.rotation_rad, alpha,
                         self._bounds, self._T_dev, self._T_dev_inv)
        return self._T_dev

    def apply(self, q_cmd_rad) -> np.ndarray:
        """The joint target with each arm solved for its goal in the measured neck frame.

        Where the corrected goal has no exact solution, the arm takes the position-first
        nearest pose on its branch if that holds the tool (see :class:`CorrectionSettings`);
        where neither does, it keeps the joint offset of its last held correction, scaled down
        as the weight fades (no jump either way).
        """
        q = np.array(q_cmd_rad, dtype=float)
        T_dev_inv = self._T_dev_inv
        fade = self.settings.fade_per_s * self.dt_s
        for arm, sl in self._slices:
            limb = self.body.arms[arm]
            q_arm = q[sl].copy()
            T_N_E = limb.fk(q_arm)
            w_prev = self.weight[arm]
            w = min(1.0, w_prev + fade)
            T_goal, q_prev = _blend(T_N_E, T_dev_inv @ T_N_E, w), self._q_out.get(arm, q_arm)
            result = limb.solve(T_goal, q_prev)
            if not result.exact:
                result = self._nearest(arm, T_goal, q_arm, q_prev)
            if result is not None and abs(result.q_rad - q_arm).max() <= \
                    self.settings.max_joint_offset_rad:
                self.weight[arm] = w
                self._dq[arm] = result.q_rad - q_arm
            else:
                self.weight[arm] = w = max(0.0, w_prev - fade)
                self._dq[arm] = self._dq.get(arm, np.zeros(6)) * (w / w_prev if w_prev else 0.0)
            q[sl] = q_arm + self._dq[arm]
            self._q_out[arm] = q[sl].copy()
        return q

    def _nearest(self, arm: str, T_goal: np.ndarray, q_arm: np.ndarray,
                 q_prev: np.ndarray) -> IKResult | None:
        """The position-first nearest pose to ``T_goal`` on the branch of the uncorrected
        joints ``q_arm``, from ``q_prev``; None where it misses the goal by more than the
        settings allow."""
        s, reach = self.settings, self._reach[arm]
        reach.start(q_arm)
        result = reach.solve(T_goal, q_prev)
        if (np.all(np.isfinite(result.q_rad))
                and result.position_error_m <= s.nearest_max_position_m
                and result.rotation_error_rad <= s.nearest_max_rotation_rad):
            return result
        return None

    def __call__(self, q_cmd_rad, state, quat_world_torso_wxyz: np.ndarray) -> np.ndarray:
        """:meth:`update` then :meth:`apply`."""
        self.update(q_cmd_rad, state, quat_world_torso_wxyz)
        return self.apply(q_cmd_rad)


def _rigid_inverse(T: np.ndarray) -> np.ndarray:
    """The inverse of a rigid transform (4x4): rotation transposed, translation turned back."""
    T_inv = np.empty((4, 4))
    invert4(np.ascontiguousarray(T, dtype=float), T_inv)  # compiled: one call, not six
    return T_inv


def _blend(T_a: np.ndarray, T_b: np.ndarray, w: float) -> np.ndarray:
    """The pose ``w`` of the way from T_a to T_b (0 <= w <= 1)."""
    if w >= 1.0:
        return T_b
    T = np.eye(4)
    T[:3, :3] = T_a[:3, :3] @ rotation_exp(w * rotation_log(T_a[:3, :3].T @ T_b[:3, :3]))
    T[:3, 3] = T_a[:3, 3] + w * (T_b[:3, 3] - T_a[:3, 3])
    return T
