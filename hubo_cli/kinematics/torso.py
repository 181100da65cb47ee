"""The torso's pose in the stance frame S, and the hand-goal correction that holds a tool in the
world while the body sways.

Measurement (:class:`MeasuredTorso`): the torso's pose has one home, the estimation layer's
floating base (:mod:`hubo_cli.estimation.base`, the store's T_WORLD_TORSO: the legs anchored
at the loaded sole, the estimated attitude's tilt, the heading the legs' and the gyro's, never
the IMU's yaw, which has no absolute reference on a Hubo). Here it is only seen from S, which
is placed in the world once where the estimated soles stand. :func:`torso_in_stance` is the
stance's kinematics: the neck frame N in S that given leg joints put there (the commanded
pose), each foot pivoting about its sole origin.

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
from hubo_cli.motion.limits import all_finite


def torso_in_stance(body: WholeBody, q_rad, quat_world_torso_wxyz=None) -> np.ndarray:
    """T_S_N, the neck frame in the stance frame (4x4, m), that leg joints give with the feet
    where S puts them.

    Args:
        body: the whole-body solver (its legs and the soles' places in S).
        q_rad: the full joint vector (commanded, for the nominal pose).
        quat_world_torso_wxyz: a torso orientation (w, x, y, z) whose tilt is taken under the
            legs' heading; None: the legs' orientation alone.
    """
    quat = quat_world_torso_wxyz
    R_imu = None if quat is None else quat_wxyz_to_matrix(quat)
    return stance_legs(body).pose(q_rad, R_imu)  # compiled (torso_kernels)


class MeasuredTorso:
    """T_S_N, the neck frame in the stance frame, as the estimation layer has it: the store's
    T_WORLD_TORSO (:mod:`hubo_cli.estimation.base`: the legs anchored at the loaded sole, the
    estimated attitude's tilt, the heading the legs' and the gyro's) seen from S. S is placed
    in the world once, at the first reading, where the estimated soles stand (T_WORLD_SOLES;
    each sole is at its ``T_S_sole``, S upright: the feet stand where the stance puts them);
    afterwards only the estimate moves. A reading that is not finite gives the last pose.

    Args:
        body: the whole-body solver (the soles' places in S).
    """

    def __init__(self, body: WholeBody) -> None:
        self.body = body
        self.T_world_S: np.ndarray | None = None
        self._T_S_world = np.eye(4)
        self._T_S_N = np.eye(4)

    def _place_stance(self, T_world_soles: np.ndarray) -> None:
        """S upright, its heading the soles' mean, its origin the mean of where each sole's
        middle puts it (a sole rocking on its edge does not swing S's origin about it)."""
        T_S_soles = [self.body.T_S_sole[leg] for leg in LEGS]
        headings = [np.arctan2(W[1, 0], W[0, 0]) - np.arctan2(S[1, 0], S[0, 0])
                    for W, S in zip(T_world_soles, T_S_soles, strict=True)]
        heading = np.arctan2(np.mean(np.sin(headings)), np.mean(np.cos(headings)))
        T_world_S = np.eye(4)
        T_world_S[:2, :2] = [[np.cos(heading), -np.sin(heading)],
                             [np.sin(heading), np.cos(heading)]]
        T_world_S[:3, 3] = np.mean([W[:3, 3] - T_world_S[:3, :3] @ S[:3, 3]
                                    for W, S in zip(T_world_soles, T_S_soles, strict=True)],
                                   axis=0)
        self.T_world_S, self._T_S_world = T_world_S, _rigid_inverse(T_world_S)

    def __call__(self, T_world_torso: np.ndarray, T_world_soles: np.ndarray) -> np.ndarray:
        """T_S_N (4x4, m) from the store's T_WORLD_TORSO and T_WORLD_SOLES (right, left)."""
        T_world_torso = np.asarray(T_world_torso, dtype=float)
        if self.T_world_S is None:
            T_world_soles = np.asarray(T_world_soles, dtype=float)
            if not np.all(np.isfinite(T_world_soles)):
                return self._T_S_N
            self._place_stance(T_world_soles)
        if all_finite(T_world_torso.ravel()):
            self._T_S_N = self._T_S_world @ T_world_torso
        return self._T_S_N


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
    """

    def __init__(self, body: WholeBody, arms, dt_s: float,
                 settings: CorrectionSettings | None = None) -> None:
        self.body = body
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

    def update(self, q_cmd_rad, T_S_N_measured: np.ndarray) -> np.ndarray:
        """Advance the filter with this period's measured neck frame ``T_S_N_measured`` (4x4,
        :class:`MeasuredTorso`); returns T_dev (4x4). A measurement that is not finite leaves
        it as it was."""
        s = self.settings
        T_meas = np.asarray(T_S_N_measured, dtype=float)
        if not np.isfinite(T_meas).all():
            return self._T_dev
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

    def __call__(self, q_cmd_rad, T_S_N_measured: np.ndarray) -> np.ndarray:
        """:meth:`update` then :meth:`apply`."""
        self.update(q_cmd_rad, T_S_N_measured)
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
