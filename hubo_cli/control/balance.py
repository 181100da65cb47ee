"""Ankle balancing of the paper (III-C, eq. 11-12) as a pipeline module.

Each period, per foot, the ankle roll and pitch velocities are

    omega_roll  = K_r * phi_x - K_c * M_x        (11)
    omega_pitch = K_r * phi_y - K_c * M_y        (12)

integrated into offsets that are added to the ankle joints of the command. The first term
resists the torso's tilt (so the robot stands up straight), the second complies with the moment
at the ankle (so a foot that is not flat rotates until it is, instead of the closed chain
through both legs building up large torques).

Units (the paper gives none; these make its gains K_r = 0.009 and K_c = 0.0015 sensible)
    phi     torso tilt in DEGREES, about the world x (roll) and y (pitch) axes, from the
            estimated attitude (the store's QUAT_WORLD_TORSO).
    M       moment in N m that the sole exerts on the ground, about the sole frame's x and y
            axes (the opposite of the ground reaction in ``RobotState.ft``).
    omega   ankle joint velocity in rad/s, per second (not per control period).

So K_r = 0.009 rad/s per degree (0.52 deg/s per degree of tilt: a tilt is worked off with a time
constant of about 2 s) and K_c = 0.0015 rad/s per N m; the two terms balance at 6 N m per degree.
The Hubo team's public balancing code of the time turns the IMU angle into an ankle velocity with
0.5 * pi / 180 = 0.0087 (about the paper's 0.009, i.e. 0.5 deg/s per degree) and the foot moment
with 0.0015. The other readings do not work: with velocities per 5 ms period, K_c alone would
turn a 10 N m moment into 3 rad/s; with the tilt in radians, K_r would need minutes to act.

What it does to a standing robot: with the centre of mass 2.4 cm in front of the ankles in the
home posture, the compliant term lets the body lean forward until the two terms balance, about
1.1 deg after ~10 s, with both feet evenly loaded. Under a short push the compliant term yields
too (it is meant to), so the torso tilts somewhat more than on stiff ankles; what the balancer
buys is even, flat feet (see tests/test_balance.py).

Signs are taken from the kinematics: a positive ankle pitch (roll) velocity turns the foot about
the joint axis, whose direction in the sole frame is computed once, so that a forward (rightward)
tilt drives the body back (left) over a planted foot, and the ankle yields to the moment.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.phase import BALANCERS_REST
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import CONTACT, QUAT_WORLD_TORSO, WRENCHES
from hubo_cli.geometry import GIMBAL_LOCK_COS
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

K_R_RAD_S_PER_DEG = 0.009
K_C_RAD_S_PER_NM = 0.0015
FEET = (("right-leg", "right-ankle"), ("left-leg", "left-ankle"))


def ankle_axis_signs(model: RobotModel) -> dict[str, tuple[float, float]]:
    """Per leg, the sign of the ankle pitch axis along +y and of the ankle roll axis along +x
    (in the sole frame, home posture)."""
    signs = {}
    for leg, _ in FEET:
        limb = Limb(model, leg)
        _, offset, alpha, a, d, _ = limb.fk_chain
        q = home_posture(model)[model.limb_slice(leg)]
        T = limb.T_N_base.copy()
        axes = []
        for i in range(6):
            axes.append(T[:3, 2].copy())  # joint i+1 turns about z of DH frame i
            th = q[i] + offset[i]
            ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(alpha[i]), math.sin(alpha[i])
            T = T @ np.array([[ct, -st * ca, st * sa, a[i] * ct],
                              [st, ct * ca, -ct * sa, a[i] * st], [0, sa, ca, d[i]], [0, 0, 0, 1]])
        R_N_sole = limb.fk(q)[:3, :3]
        pitch_axis, roll_axis = R_N_sole.T @ axes[4], R_N_sole.T @ axes[5]
        signs[leg] = (float(np.sign(pitch_axis[1])), float(np.sign(roll_axis[0])))
    return signs


class AnkleBalancer(Module):
    """Adds the eq. 11-12 ankle corrections to the command.

    Args:
        model: the robot model (joint order, ankle limits, axis directions).
        k_r: resistive gain, rad/s per degree of torso tilt.
        k_c: compliant gain, rad/s per N m of ankle moment.
        max_rate_rad_s: each ankle correction's velocity is clipped to this (rad/s).
        max_offset_rad: each ankle correction is clipped to +- this (rad); the result also stays
            within the joint limits.
    """

    name = "balance"
    reads = (QUAT_WORLD_TORSO, WRENCHES)
    follows = (BALANCERS_REST,)
    log_columns = ("balance.right_pitch_rad", "balance.right_roll_rad",
                   "balance.left_pitch_rad", "balance.left_roll_rad")

    def __init__(self, model: RobotModel, k_r: float = K_R_RAD_S_PER_DEG,
                 k_c: float = K_C_RAD_S_PER_NM, max_rate_rad_s: float = 0.5,
                 max_offset_rad: float = 0.15) -> None:
        self.model = model
        self.k_r = float(k_r)
        self.k_c = float(k_c)
        self.max_rate_rad_s = float(max_rate_rad_s)
        self.max_offset_rad = float(max_offset_rad)
        names = model.joint_names
        self._index = {leg: (names.index(model.limb(leg).joints[4]),
                             names.index(model.limb(leg).joints[5])) for leg, _ in FEET}
        self._signs = ankle_axis_signs(model)
        self.offsets_rad = {leg: np.zeros(2) for leg, _ in FEET}  # (pitch, roll)
        self._resting = False

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        """Start with no correction."""
        self.offsets_rad = {leg: np.zeros(2) for leg, _ in FEET}
        self._resting = False

    def rates_rad_s(self, wrenches: dict, quat_wxyz) -> dict[str, np.ndarray]:
        """Ankle (pitch, roll) velocities of eq. 11-12 for each leg (rad/s), before clipping,
        from the ankle wrenches (the estimate's, ``WRENCHES``) and the torso attitude
        ``quat_wxyz`` (w, x, y, z; the estimate's)."""
        return {leg: np.array(rate) for leg, rate in self._rates(wrenches, quat_wxyz).items()}

    def _rates(self, wrenches: dict, quat_wxyz) -> dict[str, tuple[float, float]]:
        w, x, y, z = (float(v) for v in quat_wxyz)
        roll_deg = math.degrees(math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
        pitch_deg = math.degrees(math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x)))))
        rates = {}
        for leg, sensor in FEET:
            wrench = wrenches.get(sensor)
            # moment of the sole on the ground (about y, about x): minus the ground's on the sole
            m_y, m_x = (0.0, 0.0) if wrench is None else (-float(wrench[4]), -float(wrench[3]))
            sign_pitch, sign_roll = self._signs[leg]
            rates[leg] = (sign_pitch * (self.k_r * pitch_deg - self.k_c * m_y),
                          sign_roll * (self.k_r * roll_deg - self.k_c * m_x))
        return rates

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        """Integrate the ankle velocities over one period and add the offsets to the ankles;
        switched off (BALANCERS_REST) pass the command through, no correction, and start
        afresh when switched on again."""
        q = np.array(q_rad, dtype=float)
        if cycle.store.get(BALANCERS_REST, False):  # a phase moves the CoM itself
            if not self._resting:  # switched off: drop the correction once, then rest
                self.reset(q_rad, state, cycle.store)
                self._resting = True
            return self._report(q, cycle)
        self._resting = False
        rates = self._rates(cycle.store[WRENCHES], cycle.store[QUAT_WORLD_TORSO])
        lower, upper = self.model.lower_rad, self.model.upper_rad
        max_rate, max_offset = self.max_rate_rad_s, self.max_offset_rad
        for leg, _ in FEET:
            rate = rates[leg]
            if not (math.isfinite(rate[0]) and math.isfinite(rate[1])):
                rate = (0.0, 0.0)
                cycle.flags.add("balance-bad-sensor")
            offset = self.offsets_rad[leg]
            for k, i in enumerate(self._index[leg]):
                step = max(-max_rate, min(max_rate, rate[k])) * cycle.dt_s
                wanted = max(-max_offset, min(max_offset, float(offset[k]) + step))
                qi = float(q[i])
                if math.isfinite(qi):
                    target = max(float(lower[i]), min(float(upper[i]), qi + wanted))
                    offset[k] = target - qi
                    q[i] = target
                else:  # no command for this joint: it stays NaN (the next modules hold it)
                    offset[k] = wanted
        return self._report(q, cycle)

    def _report(self, q: np.ndarray, cycle: Cycle) -> np.ndarray:
        side = self.offsets_rad
        cycle.info["balance.right_pitch_rad"] = float(side["right-leg"][0])
        cycle.info["balance.right_roll_rad"] = float(side["right-leg"][1])
        cycle.info["balance.left_pitch_rad"] = float(side["left-leg"][0])
        cycle.info["balance.left_roll_rad"] = float(side["left-leg"][1])
        return q


# ---------------------------------------------------------------------- the default balancer
DAMPING_NM_S_PER_RAD = 667.0     # 1 / K_c: the paper's compliance, now toward a reference
COMMON_LEAK_S = 1.0              # hrpsys EEFM time constant of the return to the command
CHAIN_STIFFNESS_NM_PER_RAD = 1.0e5  # between the feet, the simulated legs (issue 15's figure)
DIFFERENTIAL_TIME_S = 0.2        # foot evening: time constant against that stiffness
DIFFERENTIAL_LEAK_S = 2.0
SMOOTHING_S = 0.05               # corrections follow their integrals with this time constant
MAX_CORRECTION_ACCEL_RAD_S2 = 0.3  # half the limiter's 0.6 rad/s^2 on the ankles
MAX_CORRECTION_RATE_RAD_S = 0.1
EDGE_MARGIN_M = 0.02  # a centre of pressure this close to a sole's edge: the foot is tipping
BALANCE_MODES = ("default", "paper")


class DampingBalancer(Module):
    """The default ankle balancer: eq. 11-12 split into a common and a differential mode.

    Common mode (both ankles alike, hrpsys EEFM damping form): each ankle axis turns with
    ``(M - M_ref) / D + K_r * tilt - offset / T``, where M is the ground's moment on the two
    soles together (about their own origins, sole axes), M_ref the moment the ground exerts
    when the centre of pressure lies under the centre of mass of the *commanded* posture (pitch:
    -W * x_com, W the weight; roll: 0, each foot loaded on its centre line), D the damping, tilt
    the torso's tilt (degrees, from the estimated attitude; the commanded torso is upright) and
    T the leak back to the command. A robot that stands as commanded has nothing to correct,
    so it does not lean with every load as the paper's pure compliance toward zero moment
    does.

    Differential mode (between the feet, only while both carry load): each foot turns with
    ``K_d * (M_foot - M_mean) - offset_d / T_d``, the paper's foot-evening compliance with K_d
    set so that against the chain's stiffness k (1e5 N m/rad between the simulated feet) the
    feet even out in ``DIFFERENTIAL_TIME_S``: K_d = 1 / (k * t). The paper's K_c = 0.0015 gives
    1.3 control periods against that stiffness, which rocks the feet.

    The sum of both modes is followed by the correction sent to the ankles through a filter
    whose rate and acceleration stay well inside the limiter's (0.1 rad/s, 0.3 rad/s^2).

    The moment compliance evens out a foot that is not flat; it is no answer to a body that
    tips over a sole's edge (a push).
    Nor is the tilt term: it leans the body against the tilt, and once the feet land back flat
    that lean tips it over the other edge (it cannot be undone within the rate bounds). While
    the feet's common centre of pressure is within ``edge_margin_m`` of the soles' heels or
    toes, the common mode's pitch rests (only its leak acts), as hubo-motion-rt's ``flattenFoot``
    complies only inside a force window. (Sideways the feet stand apart: a centre of pressure
    near a sole's side is a drill held out to the side, not a tipping body; so is one foot
    loaded near its toe while the other is not.)

    Args:
        model: the robot model.
        drill: the right hand holds the drill (its mass counts in the reference CoM).
        damping_nm_s_per_rad, k_r, common_leak_s: the common mode.
        chain_stiffness_nm_per_rad, differential_time_s, differential_leak_s: the differential
            mode.
        max_offset_rad: each correction is clipped to +- this (rad) and to the joint limits.
        edge_margin_m: the common mode's pitch rests while a centre of pressure is this close
            to a sole's heel or toe (m); 0 never rests.
    """

    name = "balance"
    reads = (QUAT_WORLD_TORSO, CONTACT, WRENCHES)
    follows = (BALANCERS_REST,)
    log_columns = AnkleBalancer.log_columns

    def __init__(self, model: RobotModel, drill: bool = False,
                 damping_nm_s_per_rad: float = DAMPING_NM_S_PER_RAD,
                 k_r: float = K_R_RAD_S_PER_DEG, common_leak_s: float = COMMON_LEAK_S,
                 chain_stiffness_nm_per_rad: float = CHAIN_STIFFNESS_NM_PER_RAD,
                 differential_time_s: float = DIFFERENTIAL_TIME_S,
                 differential_leak_s: float = DIFFERENTIAL_LEAK_S,
                 max_offset_rad: float = 0.15, edge_margin_m: float = EDGE_MARGIN_M) -> None:
        from hubo_cli.errors import ConfigError
        from hubo_cli.pin_robot import load_pin_robot

        values = (damping_nm_s_per_rad, common_leak_s, chain_stiffness_nm_per_rad,
                  differential_time_s, differential_leak_s, max_offset_rad)
        if not all(math.isfinite(v) and v > 0 for v in values) or not k_r >= 0:
            raise ConfigError("balance gains, time constants and limits must be positive",
                              hint="e.g. damping_nm_s_per_rad=667, common_leak_s=1")
        feet = model.feet
        if not (math.isfinite(edge_margin_m) and 0 <= edge_margin_m < feet.length_m / 2):
            raise ConfigError(f"the sole-edge margin must lie in [0, {feet.length_m / 2:g}) m, "
                              f"got {edge_margin_m}", hint=f"e.g. {EDGE_MARGIN_M}")
        # where along the sole a centre of pressure means a flat foot (m)
        self._flat_x_m = (feet.forward_m - feet.length_m / 2 + edge_margin_m,
                          feet.forward_m + feet.length_m / 2 - edge_margin_m)
        self.edge_margin_m = float(edge_margin_m)
        self.model = model
        self.damping = float(damping_nm_s_per_rad)
        self.k_r = float(k_r)
        self.common_leak_s = float(common_leak_s)
        self.k_d = 1.0 / (float(chain_stiffness_nm_per_rad) * float(differential_time_s))
        self.differential_leak_s = float(differential_leak_s)
        self.max_offset_rad = float(max_offset_rad)
        names = model.joint_names
        self._index = {leg: (names.index(model.limb(leg).joints[4]),
                             names.index(model.limb(leg).joints[5])) for leg, _ in FEET}
        self._signs = ankle_axis_signs(model)
        # floating, with the torso at the origin: a fixed base would leave the torso's mass out
        self._robot = load_pin_robot(model, floating=True, urdf_path=model.urdf_path(drill))
        self._data = self._robot.model.createData()
        import pinocchio as pin

        self._pin = pin
        self._weight_n = self._robot.weight_n
        self._loaded_n = model.estimation.body_on_soles_weight_fraction * self._weight_n
        self._sole_ids = [self._robot.frame_id(f) for f in ("right_sole", "left_sole")]
        self._q = self._robot.configuration(np.zeros(len(names)))  # torso at the origin
        self._last_ref = np.full(len(names), np.nan)  # the command of the last reference
        self._lower = np.array(model.lower_rad, dtype=float)
        self._upper = np.array(model.upper_rad, dtype=float)
        # per leg (rows, FEET order) and ankle axis (columns: pitch, roll), for the compiled
        # filter (_follow_offsets)
        self._ankles = np.array([self._index[leg] for leg, _ in FEET], dtype=np.int64)
        self._ankle_signs = np.array([self._signs[leg] for leg, _ in FEET], dtype=float)
        self._last_reference = 0.0
        self._no_wrench = np.zeros(6)
        self.reset(np.zeros(len(names)), None, None)
        # numba compiles (or loads its cache) on the first call: now, not in the first period
        _follow_offsets(np.zeros(len(names)), self._ankles, self._ankle_signs, *[0.0] * 8, True,
                        *np.zeros((3, 2, 2)), self._lower, self._upper, *[1.0] * 7)
        command_configuration(np.zeros(len(names)), np.zeros(len(names)), np.zeros(len(names)),
                           np.zeros(self._robot.model.nq), self._robot.q_index)
        state = RobotState(0.0, np.zeros(len(names)), np.zeros(len(names)))
        self._step(np.zeros(len(names)), state, state.ft, np.array([1.0, 0.0, 0.0, 0.0]), True,
                   0.005)
        self.reset(np.zeros(len(names)), None, None)

    def reset(self, q_rad: np.ndarray, state: RobotState | None,
              store: Store | None) -> None:
        """Start with no correction."""
        # the filter's state: the common mode in Python floats (pitch, roll), the per-leg
        # parts as (leg, axis) arrays (FEET order; pitch, roll) for the compiled step
        self._common = np.zeros(2)                               # joint space
        self._differential = np.zeros((2, 2))
        self._offsets = np.zeros((2, 2))  # what is sent
        self._rate = np.zeros((2, 2))
        self._reference_now = 0.0
        self._resting = False

    @property
    def reference_moment_nm(self) -> np.ndarray:
        """The last period's reference ground moment (about y, about x; N m)."""
        return np.array([self._reference_now, 0.0])

    @property
    def offsets_rad(self) -> dict[str, np.ndarray]:
        """Per leg, the (pitch, roll) correction sent to its ankle (rad)."""
        return {leg: self._offsets[k].copy() for k, (leg, _) in enumerate(FEET)}

    def _reference_moment(self, q_rad: np.ndarray, q_measured_rad: np.ndarray) -> float:
        """Ground moment about y (N m, summed over the soles) with the centre of pressure
        under the commanded posture's centre of mass (a joint without a command: measured)."""
        if not command_configuration(q_rad, q_measured_rad, self._last_ref, self._q,
                                  self._robot.q_index):
            return self._last_reference  # a held posture: nothing to recompute
        pin = self._pin
        com = pin.centerOfMass(self._robot.model, self._data, self._q, False)
        x = 0.0
        for fid in self._sole_ids:
            oMf = pin.updateFramePlacement(self._robot.model, self._data, fid)
            x += float((oMf.rotation.T @ (com - oMf.translation))[0])
        self._last_reference = -self._weight_n * x / 2
        return self._last_reference

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q = np.array(q_rad, dtype=float)
        store = cycle.store
        if store.get(BALANCERS_REST, False):  # a phase moves the CoM itself: switched off
            if not self._resting:  # drop the correction once, pass the command through
                self.reset(q_rad, state, store)
                self._resting = True
        else:  # switched on (again: from the reset of the rest's start)
            self._resting = False
            if self._step(q, state, store[WRENCHES], store[QUAT_WORLD_TORSO],
                          all(store[CONTACT]), cycle.dt_s):
                cycle.flags.add("balance-bad-sensor")
        (right_pitch, right_roll), (left_pitch, left_roll) = self._offsets.tolist()
        cycle.info["balance.right_pitch_rad"] = right_pitch
        cycle.info["balance.right_roll_rad"] = right_roll
        cycle.info["balance.left_pitch_rad"] = left_pitch
        cycle.info["balance.left_roll_rad"] = left_roll
        return q

    def _step(self, q: np.ndarray, state: RobotState, wrenches: dict, quat_wxyz, both: bool,
              dt: float) -> bool:
        """One period on the command ``q`` (in place) with the ankle wrenches, the torso
        attitude ``quat_wxyz`` (w, x, y, z) and ``both`` feet in contact (the estimate's); True
        when a sensor reads non-finite."""
        reference = self._reference_now = self._reference_moment(q, state.q_rad)
        right, left = (wrenches.get(sensor) for _, sensor in FEET)
        as_array = np.asarray
        return _balance_step(
            q, self._ankles, self._ankle_signs,
            self._no_wrench if right is None else as_array(right, dtype=float), right is not None,
            self._no_wrench if left is None else as_array(left, dtype=float), left is not None,
            as_array(quat_wxyz, dtype=float), both,
            reference, self._loaded_n, self._flat_x_m[0], self._flat_x_m[1],
            self.edge_margin_m > 0, self.damping, self.k_r, self.common_leak_s, self._common,
            self._differential, self._offsets, self._rate, self._lower, self._upper,
            self.max_offset_rad, self.k_d, self.differential_leak_s, MAX_CORRECTION_RATE_RAD_S,
            MAX_CORRECTION_ACCEL_RAD_S2 * dt, SMOOTHING_S, dt)


@nb.njit(cache=True, nogil=True)
def command_configuration(q, q_measured, last, q_pin, index):
    """The command with the measured joints where it has none, into pinocchio's
    configuration ``q_pin`` (at ``index``) and ``last``; False when it equals ``last``."""
    changed = False
    for i in range(q.shape[0]):
        value = q[i] if math.isfinite(q[i]) else q_measured[i]
        if not value == last[i]:
            changed = True
        last[i] = value
        q_pin[index[i]] = value
    return changed


@nb.njit(cache=True, nogil=True)
def _balance_step(q, ankles, signs, right_wrench, has_right, left_wrench, has_left, quat, both,
                  reference, loaded_n, flat_lo, flat_hi, edge_check, damping, k_r, common_leak,
                  common, differential, offsets, rate, lower, upper, limit, k_d, leak, max_rate,
                  max_step, smoothing_s, dt):
    """:class:`DampingBalancer`'s period, compiled (the arithmetic of its Python form, in the
    same order): the feet's moments, the torso tilt (attitude quaternion w, x, y, z), the common
    mode (``common``, pitch and roll, in place) resting its pitch while the feet tip over an
    edge, then :func:`_follow_offsets`. Returns True when a sensor reads non-finite (its
    term is then zero)."""
    bad = False
    right_pitch = right_roll = left_pitch = left_roll = 0.0
    if has_right:
        right_pitch, right_roll = right_wrench[4], right_wrench[3]
    if has_left:
        left_pitch, left_roll = left_wrench[4], left_wrench[3]
    if not (math.isfinite(right_pitch) and math.isfinite(right_roll)
            and math.isfinite(left_pitch) and math.isfinite(left_roll)):
        bad = True
        right_pitch = right_roll = left_pitch = left_roll = 0.0
    # the tilt as hubo_cli.geometry.roll_pitch_of_quat_wxyz computes it
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    r00 = 1 - 2 * (y * y + z * z)
    r10 = 2 * (x * y + w * z)
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    cos_pitch = math.hypot(r00, r10)
    roll = 0.0 if cos_pitch < GIMBAL_LOCK_COS else math.atan2(r21, r22)
    pitch = math.atan2(-r20, cos_pitch)
    tilt_pitch, tilt_roll = math.degrees(pitch), math.degrees(roll)
    if not (math.isfinite(tilt_pitch) and math.isfinite(tilt_roll)):
        bad = True
        tilt_pitch = tilt_roll = 0.0
    fz = moment_y = 0.0
    if has_right:
        fz, moment_y = fz + right_wrench[2], moment_y + right_wrench[4]
    if has_left:
        fz, moment_y = fz + left_wrench[2], moment_y + left_wrench[4]
    mean_pitch, mean_roll = (right_pitch + left_pitch) / 2, (right_roll + left_roll) / 2
    error_pitch = error_roll = 0.0
    if fz > loaded_n:  # the soles carry the body: their moments mean balance
        error_pitch, error_roll = mean_pitch - reference / 2, mean_roll - 0.0 / 2
    rate_pitch = error_pitch / damping + k_r * tilt_pitch - common[0] / common_leak
    rate_roll = error_roll / damping + k_r * tilt_roll - common[1] / common_leak
    if edge_check and fz > loaded_n and not flat_lo < -moment_y / fz < flat_hi:
        rate_pitch = -common[0] / common_leak  # tipping: only the leak
    common[0] = common[0] + rate_pitch * dt
    common[1] = common[1] + rate_roll * dt
    _follow_offsets(q, ankles, signs, right_pitch, right_roll, left_pitch, left_roll,
                    mean_pitch, mean_roll, common[0], common[1], both, differential, offsets,
                    rate, lower, upper, limit, k_d, leak, max_rate, max_step, smoothing_s, dt)
    return bad


@nb.njit(cache=True, nogil=True)
def _follow_offsets(q, ankles, signs, right_pitch, right_roll, left_pitch, left_roll, mean_pitch,
                    mean_roll, common_pitch, common_roll, both, differential, offsets, rate,
                    lower, upper, limit, k_d, leak, max_rate, max_step, smoothing_s, dt):
    """:class:`DampingBalancer`'s per-leg step, compiled (the same float arithmetic in the
    same order as in Python): each ankle axis's differential mode (``k_d`` times its foot's
    moment less the feet's mean, leaking over ``leak`` s), plus the common mode, bounded by
    ``limit``, followed by the offset with bounded rate and acceleration, then added to the
    joint ``q[ankles[leg, axis]]`` within its limits (where it is finite). Updates
    ``differential``, ``offsets``, ``rate`` and ``q`` in place; rows are legs in FEET order,
    columns (pitch, roll)."""
    moments = ((right_pitch, right_roll), (left_pitch, left_roll))
    mean = (mean_pitch, mean_roll)
    common = (common_pitch, common_roll)
    for leg in range(2):
        for k in range(2):
            drive = k_d * (moments[leg][k] - mean[k]) if both else 0.0
            differential[leg, k] = differential[leg, k] + (
                drive - differential[leg, k] / leak) * dt
            wanted = min(max(signs[leg, k] * (common[k] + differential[leg, k]), -limit), limit)
            # follow the wanted correction with bounded rate and acceleration
            rate_wanted = min(max((wanted - offsets[leg, k]) / smoothing_s, -max_rate),
                              max_rate)
            rate[leg, k] = rate[leg, k] + min(max(rate_wanted - rate[leg, k], -max_step),
                                              max_step)
            offsets[leg, k] = offsets[leg, k] + rate[leg, k] * dt
            i = ankles[leg, k]
            qi = q[i]
            if math.isfinite(qi):
                target = min(max(qi + offsets[leg, k], lower[i]), upper[i])
                offsets[leg, k] = target - qi
                q[i] = target


def make_balancer(model: RobotModel, mode: str = "default", **options) -> Module:
    """The balancer of a mode: ``default`` (:class:`DampingBalancer`) or ``paper``
    (:class:`AnkleBalancer`, eq. 11-12 as published)."""
    from hubo_cli.errors import ConfigError, quoted

    if mode == "paper":
        options.pop("drill", None)
        return AnkleBalancer(model, **options)
    if mode == "default":
        return DampingBalancer(model, **options)
    raise ConfigError(f"unknown balance mode {quoted(mode)}",
                      hint=f"use {', '.join(BALANCE_MODES)} (or leave the module out: off)")
