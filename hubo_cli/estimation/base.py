"""The floating base and the soles in the world, from the legs' kinematics anchored at the loaded
sole, with the estimated attitude.

One sole is the anchor: its heading and its contact point in the world are held while it
carries the robot (a sole that carries load is taken not to slip; a slip is not seen, as on
the real robot). The contact point is the sole's centre of pressure (its compensated ankle
wrench, ``WRENCHES``, kept inside the sole's outline): a sole that rolls onto its toe or heel
edge (a push, a capture step) turns about that edge and its middle rises, as it does. Each
period, from the legs' forward kinematics of the measured joints (T_torso_sole, the limbs'
chains, :mod:`hubo_cli.kinematics.limb`) and the attitude ``QUAT_WORLD_TORSO``:

* the torso's rotation is the attitude turned about the world's vertical so that the anchor
  sole keeps its heading (the tilt is the attitude's, the heading the legs': the IMU's yaw
  drifts), then turned about the anchor's contact point by the anchor's slip round the
  vertical that the gyro sees and the legs do not (:func:`_slip_turn`): the gyro's yaw rate
  beyond the legs', less its bias, summed; that sum's mean over the last ``SLIP_WINDOW``
  periods changing by more than ``SLIP_TURN_RAD`` from the window before is a slip, counted
  while it lasts; otherwise the change is the bias's error, learnt with ``SLIP_BIAS_TAU_S``
  (the legs' noise averages out in the windows; the bias, unknown at the start, counts only
  while a sole slips); while one sole alone carries the robot rolling on its edge (its
  centre of pressure within ``EDGE_M`` of the outline: a push's capture step) the turn fades
  with ``HEADING_TAU_S``, as the earlier on-edge turn did (kept unfaded, the 150 N capture step's
  lunge fell on the portable path). The fast gait's stance soles twist 40-130 mrad/s on the
  floor under the swing leg's yaw moment, up to 7 deg over a 2 m walk, and a push twists a capture
  step's stance foot by degrees (planned on the legs' heading alone the step landed 5 cm
  long and the robot fell). When the other sole takes the anchor it keeps its pose as
  estimated, the turn included, and the turn starts again from zero; when the contact point
  moves on the sole while a turn is on, the held anchor shifts with it so that the turned
  torso does not jump (:meth:`FloatingBase._keep_pivot_continuous`);
* the torso's position puts the anchor sole's contact point of this period where that point
  of the sole was in the last period's estimate (a flat sole whose centre of pressure moves
  stays where it is; one rolling on an edge keeps the edge on the floor);
* both soles follow from the torso through the legs.

The anchor changes when it loses contact (``CONTACT``) and the other sole has it, or when the
other sole in contact carries the robot file's ``estimation.anchor_switch_n`` more than it (the
compensated ankle F_z): a foot that lifts is still in contact for the debounce's delay, and
held as the anchor meanwhile it would carry the whole estimate up with it (a capture step's
swing foot lifted the estimated torso by 30 mm and sank the stance sole as far). A sole that
has just landed takes the anchor by weight only once it has stood ``LANDED_PERIODS`` (its
touchdown's force peak passes the anchor's load for a few periods), unless the anchor lifts
off (presses less than ``anchor_cop_min_fz_n``): the anchor passed back and forth while the
loads crossed at a touchdown, and each pass through the legs' kinematics carried the encoders'
and the attitude's noise and error into the estimate (~1 mm a pass: perturbed robots'
estimates drifted 10 mm sideways and 1 deg in heading over a 1 m walk). The new anchor keeps
the pose estimated for it (the mean of its last LANDED_PERIODS estimates on the floor), so the
estimate does not jump. (Also taking a sole that gave the anchor up back where it was then,
while it stays in contact, was tried: with it the 150 N capture step's return step never left
the floor, the back foot loaded with 130-140 N to the end.)

In flight (neither sole pressing ``estimation.flight_max_fz_n`` for ``flight_confirm_s`` in a
row, after one has pressed since the start: a landing's bounce, a jump, a lifted robot) no sole
holds the estimate: the torso stays where it was, its tilt the attitude's and its heading
kept, and the soles follow it through the legs; the anchor takes up from where its sole then
is. A 150 N capture step's landed foot bounces for 55-85 ms below 20 N and slides back
meanwhile: held, it carried the estimate 26-30 mm forward, the CoM's velocity to twice the
truth's and the capture point to within 13 mm of the capture-point stop (past it on another
machine: a false stop, a fall). A walk's touchdowns have both soles light for up to 20 ms (4
periods): without the confirmation they dropped the anchor and perturbed walks ended 11-38 mm
off (docs/history/balance.md). Soles that never pressed (a robot started hanging) sense no
flight.

Start: the world frame is the simulator's (:mod:`hubo_cli.drivers.sim`): the torso's neck frame
at the start, dropped onto the floor (x forward, y left, z up, the origin on the floor under the
neck). The torso's heading is taken as zero and its position over the origin; the anchor is the
more loaded sole, laid flat on the floor (z = 0, its heading kept). So the estimate and the
simulator's truth start together on the nominal robot (the truth has settled 0.3 s by then).

Non-finite joints or attitude keep the last estimate.
"""

from __future__ import annotations

import math
from collections import deque

import numba as nb
import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import (
    CONTACT,
    QUAT_WORLD_TORSO,
    T_TORSO_SOLES,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
)
from hubo_cli.estimation.observer import Observer
from hubo_cli.estimation.wrenches import joint_vector
from hubo_cli.geometry import pose_laid_flat, quat_to_matrix_into
from hubo_cli.kinematics.dh import chain_fk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.motion.limits import all_finite
from hubo_cli.state import ANKLE_SENSORS, RobotState

LANDED_PERIODS = 20  # [chosen] a sole takes the anchor where it stood these last periods
HEADING_TAU_S = 1.0  # [chosen] the slip's turn fades with this while one sole alone rolls on
#                      its edge (a push's capture step: the earlier on-edge turn faded so)
EDGE_M = 0.015  # [chosen] a centre of pressure this close to the sole's outline: it rolls on
#                 an edge (the walking stabilizer keeps it 25 mm inside)
SLIP_WINDOW = 20  # [chosen] periods (0.1 s) over which the heading's disagreement is averaged
SLIP_TURN_RAD = 0.0025  # [chosen] the disagreement's mean changing this much from one window to
#                         the next is a slip (25 mrad/s: 2.9 times the perturbation's largest
#                         yaw bias, 8.7 mrad/s; the legs' noise averaged, ~0.5 mrad; the fast
#                         gait's twists run 40-130 mrad/s)
SLIP_BIAS_TAU_S = 1.0  # [chosen] the gyro's yaw bias learnt from the windows without a slip
#                        (0.5 and 2 s did worse on the fast walks' logged signals, seeds 1-10)
# :func:`_slip_turn`'s state (one float array, for the compiled kernels): the disagreement's
# sum (rad), the last window's mean of it (rad), the periods counted, the slip's turn (rad),
# the yaw bias (rad/s), then the ring of the last 2 SLIP_WINDOW sums
SLIP_SUM, SLIP_MEAN, SLIP_PERIODS, SLIP_TURN, SLIP_BIAS, SLIP_SUMS = range(6)
SLIP_STATE = SLIP_SUMS + 2 * SLIP_WINDOW


@nb.njit(cache=True, nogil=True)
def legs_fk(q, index, base, offset, alpha, a, d, end, out) -> bool:
    """T_torso_sole of both legs (``out``, 2 x 4 x 4); False (``out`` untouched) when a joint
    is not finite."""
    qk = np.empty((2, 6))
    for k in range(2):
        for j in range(6):
            v = q[index[k, j]]
            if not math.isfinite(v):
                return False
            qk[k, j] = v
    for k in range(2):
        chain_fk(qk[k], base[k], offset[k], alpha[k], a[k], d[k], end[k], out[k])
    return True


@nb.njit(cache=True, nogil=True)
def _heading(R) -> float:
    return math.atan2(R[1, 0], R[0, 0])


@nb.njit(cache=True, nogil=True)
def _place(quat_wxyz, T_torso_soles, anchor, T_world_anchor, cx, cy, T_world_torso,
           T_world_soles):
    """The torso and soles in the world (in place) from the attitude, the legs and the anchor
    sole's last pose ``T_world_anchor``: its heading kept, its point (cx, cy) on the sole
    (sole frame, m) kept where it was."""
    R = np.empty((3, 3))
    quat_to_matrix_into(quat_wxyz, R)
    T_ta = T_torso_soles[anchor]
    # the anchor's heading through the chain, against its held heading
    c00 = R[0, 0] * T_ta[0, 0] + R[0, 1] * T_ta[1, 0] + R[0, 2] * T_ta[2, 0]
    c10 = R[1, 0] * T_ta[0, 0] + R[1, 1] * T_ta[1, 0] + R[1, 2] * T_ta[2, 0]
    turn = _heading(T_world_anchor) - math.atan2(c10, c00)
    ct, st = math.cos(turn), math.sin(turn)
    T = T_world_torso
    for c in range(3):
        T[0, c] = ct * R[0, c] - st * R[1, c]
        T[1, c] = st * R[0, c] + ct * R[1, c]
        T[2, c] = R[2, c]
    for r in range(3):
        held = (T_world_anchor[r, 0] * cx + T_world_anchor[r, 1] * cy
                + T_world_anchor[r, 3])  # where the contact point was
        p = np.empty(3)  # the contact point in the torso frame
        for i in range(3):
            p[i] = T_ta[i, 0] * cx + T_ta[i, 1] * cy + T_ta[i, 3]
        T[r, 3] = held - (T[r, 0] * p[0] + T[r, 1] * p[1] + T[r, 2] * p[2])
    T[3, 0], T[3, 1], T[3, 2], T[3, 3] = 0.0, 0.0, 0.0, 1.0
    for k in range(2):
        S, W = T_torso_soles[k], T_world_soles[k]
        for r in range(4):
            for c in range(4):
                W[r, c] = (T[r, 0] * S[0, c] + T[r, 1] * S[1, c] + T[r, 2] * S[2, c]
                           + T[r, 3] * S[3, c])


@nb.njit(cache=True, nogil=True)
def _turn_in_place(T, c, s, px, py) -> None:
    """T (4 x 4, in place) = the turn by the angle of (cos, sin) = (c, s) about the vertical
    through (px, py) (world), times T."""
    tx, ty = px - (c * px - s * py), py - (s * px + c * py)
    for col in range(4):
        x, y = T[0, col], T[1, col]
        T[0, col] = c * x - s * y + tx * T[3, col]
        T[1, col] = s * x + c * y + ty * T[3, col]


@nb.njit(cache=True, nogil=True)
def _slip_turn(slip, twist_rad_s, dt) -> float:
    """The stance sole's slip round the vertical this period (rad), from the heading's
    disagreement ``twist_rad_s`` (the gyro's yaw rate beyond the legs'), less the yaw bias,
    summed: the sum's mean over the last SLIP_WINDOW periods against the window before; while
    they differ by more than SLIP_TURN_RAD a sole slips and the mean's move counts, period by
    period (the mean moves smoothly: no jump; counting the window's whole change at once when
    a slip starts did worse on the fast walks' signals, and jumped). The legs' per-period
    noise (0.1-0.2 rad/s as a rate) averages out in the windows; the bias's error (up to the
    perturbation's 0.0087 rad/s) stays under the threshold, so it counts only while a sole
    slips, not over the whole walk, and is learnt from the windows without a slip.
    ``slip``: its state, in place (:data:`SLIP_STATE`: the indices below, then the sums of
    the last 2 SLIP_WINDOW periods from SLIP_SUMS)."""
    w = SLIP_WINDOW
    slip[SLIP_SUM] += (twist_rad_s - slip[SLIP_BIAS]) * dt  # beyond the legs', less the bias
    n = int(slip[SLIP_PERIODS])
    slip[SLIP_SUMS + n % (2 * w)] = slip[SLIP_SUM]
    n += 1
    slip[SLIP_PERIODS] = n
    if n < 2 * w:
        return 0.0
    new, old = 0.0, 0.0
    for k in range(w):
        new += slip[SLIP_SUMS + (n - 1 - k) % (2 * w)]
        old += slip[SLIP_SUMS + (n - 1 - w - k) % (2 * w)]
    new, old = new / w, old / w
    turn = new - slip[SLIP_MEAN] if n > 2 * w else 0.0  # the mean's move this period
    if abs(new - old) <= SLIP_TURN_RAD:  # no slip: the change is the bias's error
        turn = 0.0
        slip[SLIP_BIAS] += (new - old) / (w * SLIP_BIAS_TAU_S)
    slip[SLIP_MEAN] = new
    return turn


@nb.njit(cache=True, nogil=True)
def _place_turned(quat_wxyz, T_torso_soles, anchor, T_world_anchor, cx, cy, gyro, use_gyro,
                  R_legs, rolling, keep, dt, slip, T_world_torso, T_world_soles, T_anchor_out,
                  R_out):
    """:func:`_place`, then the slip's turn about the anchor's contact point (see
    :meth:`FloatingBase._place`): the legs' own anchor pose into ``T_anchor_out``, the legs'
    torso rotation into ``R_out``; ``slip`` (:func:`_slip_turn`'s state, its turn slip[SLIP_TURN])
    updated in place. ``use_gyro``: ``gyro`` is finite and ``R_legs`` is last period's."""
    _place(quat_wxyz, T_torso_soles, anchor, T_world_anchor, cx, cy, T_world_torso,
           T_world_soles)
    A = T_world_soles[anchor]
    for r in range(4):
        for c in range(4):
            T_anchor_out[r, c] = A[r, c]
    for r in range(3):
        for c in range(3):
            R_out[r, c] = T_world_torso[r, c]
    R = R_out
    if use_gyro:
        # both rates about the world's vertical: the gyro's, and the legs' (the rotation from
        # the last period's, small: its skew part)
        yaw_rate = R[2, 0] * gyro[0] + R[2, 1] * gyro[1] + R[2, 2] * gyro[2]
        step_10 = R[1, 0] * R_legs[0, 0] + R[1, 1] * R_legs[0, 1] + R[1, 2] * R_legs[0, 2]
        step_01 = R[0, 0] * R_legs[1, 0] + R[0, 1] * R_legs[1, 1] + R[0, 2] * R_legs[1, 2]
        legs_rate = 0.5 * (step_10 - step_01) / dt
        twist = yaw_rate - legs_rate  # the stance foot's twist, and the gyro's bias
        if math.isfinite(twist):
            slip[SLIP_TURN] += _slip_turn(slip, twist, dt)
        if rolling:
            slip[SLIP_TURN] *= keep
    turn = slip[SLIP_TURN]
    if turn:
        A = T_anchor_out
        px = A[0, 0] * cx + A[0, 1] * cy + A[0, 3]
        py = A[1, 0] * cx + A[1, 1] * cy + A[1, 3]
        c, s = math.cos(turn), math.sin(turn)
        _turn_in_place(T_world_torso, c, s, px, py)
        for k in range(2):
            _turn_in_place(T_world_soles[k], c, s, px, py)


class LegsKinematics:
    """Both legs' forward kinematics, T_torso_sole (the limbs' chains,
    :mod:`hubo_cli.kinematics.limb`), from the measured joints: one home for the estimation
    layer's leg kinematics (the floating base, the attitude's tilt from the legs)."""

    def __init__(self, model: RobotModel) -> None:
        rows = []
        for leg in LEGS:
            base, offset, alpha, a, d, end = Limb(model, leg).fk_chain
            sl = model.limb_slice(leg)
            rows.append((np.arange(sl.start, sl.stop), base, offset, alpha, a, d, end))
        self._chain = (np.array([r[0] for r in rows], dtype=np.int64),
                       *(np.ascontiguousarray([r[k] for r in rows], dtype=float)
                         for k in range(1, 7)))
        self._joints = len(model.joint_names)
        legs_fk(np.zeros(self._joints), *self._chain, np.empty((2, 4, 4)))  # compile now

    def solve(self, q_rad, T_torso_soles: np.ndarray) -> bool:
        """T_torso_sole of (right, left) into ``T_torso_soles`` (2 x 4 x 4); False (left
        untouched) when the joints are not ``model``'s number of finite angles."""
        return bool(legs_fk(*self.kernel_arguments(q_rad), T_torso_soles))

    def kernel_arguments(self, q_rad) -> tuple[np.ndarray, ...]:
        """:func:`legs_fk`'s arguments before its output, for ``q_rad`` (NaN when not
        ``model``'s number of angles): for a kernel that calls it."""
        return (joint_vector(q_rad, self._joints), *self._chain)


def centre_of_pressure(wrench, min_fz_n: float) -> tuple[float, float] | None:
    """A sole's centre of pressure (x, y in its frame, m) from its ankle's compensated wrench
    [fx fy fz mx my mz]; None while it presses less than ``min_fz_n`` or reads non-finite."""
    fz, mx, my = float(wrench[2]), float(wrench[3]), float(wrench[4])
    if not (fz > min_fz_n and math.isfinite(mx) and math.isfinite(my)):
        return None
    return -my / fz, mx / fz


def _gyro(state: RobotState) -> np.ndarray | None:
    """The IMU's rate (3,; rad/s, torso axes), None unless three finite numbers."""
    gyro = state.imu_gyro_rad_s
    if type(gyro) is not np.ndarray or gyro.dtype != np.float64 or gyro.shape != (3,) \
            or not gyro.flags.c_contiguous:
        try:
            gyro = np.ascontiguousarray(np.asarray(gyro, dtype=float).reshape(3))
        except (TypeError, ValueError):
            return None
    return gyro if all_finite(gyro) else None


def _turn_about(point: np.ndarray, angle_rad: float) -> np.ndarray:
    """The turn (4x4) by ``angle_rad`` about the vertical through ``point`` (world)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    turn = np.eye(4)
    turn[:2, :2] = ((c, -s), (s, c))
    turn[:2, 3] = point[:2] - turn[:2, :2] @ point[:2]
    return turn


class FloatingBase(Observer):
    """Writes ``T_WORLD_TORSO`` and ``T_WORLD_SOLES`` (see the module docstring).

    Args:
        model: the robot model (the legs' kinematics).

    Attributes:
        anchor: the sole holding the estimate (0 right, 1 left).
    """

    name = "floating-base"
    reads = (QUAT_WORLD_TORSO, WRENCHES, CONTACT)
    follows = (T_TORSO_SOLES,)  # the attitude's legs, when it runs; else its own
    writes = (T_WORLD_TORSO, T_WORLD_SOLES)

    def __init__(self, model: RobotModel) -> None:
        self._legs = LegsKinematics(model)
        self._T_torso_soles = self._own_legs = np.tile(np.eye(4), (2, 1, 1))
        self.anchor = 0
        self._T_world_anchor = np.eye(4)
        self._T_world_torso = np.eye(4)
        self._T_world_soles = np.tile(np.eye(4), (2, 1, 1))
        self._quat = np.array([1.0, 0.0, 0.0, 0.0])
        corners = model.feet.sole_corners_m()
        self._sole_box = (float(corners[:, 0].min()), float(corners[:, 0].max()),
                          float(corners[:, 1].min()), float(corners[:, 1].max()))
        self._contact_point = (0.0, 0.0)  # on the anchor sole (sole frame, m)
        self._dt_s = model.control_period_s
        self._cop_min_fz_n = model.estimation.anchor_cop_min_fz_n
        self._anchor_switch_n = model.estimation.anchor_switch_n
        self._flight_max_fz_n = model.estimation.flight_max_fz_n
        self._flight_periods = max(1, int(round(model.estimation.flight_confirm_s
                                                / self._dt_s)))
        self._light_periods = 0  # periods in a row with both soles lighter than flight_max
        self._pressed = False  # a sole has pressed since the reset (else no flight is sensed)
        self._keep = HEADING_TAU_S / (HEADING_TAU_S + self._dt_s)  # the on-edge fade
        self._slip = np.zeros(SLIP_STATE)  # :func:`_slip_turn`'s state
        self._no_gyro, self._no_gyro_R = np.zeros(3), np.zeros((3, 3))
        self._R_legs: np.ndarray | None = None  # the legs' torso rotation, last period
        # the other sole's last estimates on the floor: x, y, z, cos and sin of its heading
        self._landed: deque[tuple[float, ...]] = deque(maxlen=LANDED_PERIODS)
        _place_turned(self._quat, self._T_torso_soles, 0, self._T_world_anchor, 0.0, 0.0,
                      self._no_gyro, True, np.eye(3), False, 1.0, self._dt_s,
                      np.zeros_like(self._slip),
                      np.eye(4), np.zeros((2, 4, 4)),
                      np.empty((4, 4)), np.empty((3, 3)))  # compiled now
        all_finite(self._quat)

    def _inputs(self, state: RobotState, store: Store) -> bool:
        """The legs' kinematics and the attitude of this period; False when not finite."""
        quat = np.asarray(store[QUAT_WORLD_TORSO], dtype=float)
        if not all_finite(quat):
            return False
        self._quat = quat
        legs = store.get(T_TORSO_SOLES, self)  # (itself: no stage wrote them)
        if legs is self:
            if not self._legs.solve(state.q_rad, self._own_legs):
                return False
            legs = self._own_legs
        elif legs is None:  # not finite
            return False
        self._T_torso_soles = legs
        return True

    def reset(self, state: RobotState, store: Store) -> None:
        wrenches = store[WRENCHES]
        fz = [float(wrenches[s][2]) for s in ANKLE_SENSORS]
        self.anchor = 1 if fz[1] > fz[0] else 0  # a NaN compares False: the right sole
        self._T_world_torso = np.eye(4)
        self._T_world_soles = np.tile(np.eye(4), (2, 1, 1))
        self._R_legs = None
        self._slip[:] = 0.0
        self._landed.clear()
        self._light_periods = 0
        self._pressed = any(f >= self._flight_max_fz_n for f in fz)  # (a NaN: not pressed)
        if not self._inputs(state, store):
            self._write(store)
            return
        # the torso over the origin heading along x, its tilt the attitude's
        R = np.empty((3, 3))
        quat_to_matrix_into(self._quat, R)
        heading = math.atan2(R[1, 0], R[0, 0])
        T_start = np.eye(4)
        T_start[:3, :3] = np.array([[math.cos(heading), math.sin(heading), 0.0],
                                    [-math.sin(heading), math.cos(heading), 0.0],
                                    [0.0, 0.0, 1.0]]) @ R
        self._T_world_anchor = pose_laid_flat(T_start @ self._T_torso_soles[self.anchor])
        self._place()
        self._write(store)

    def _centre_of_pressure(self, store: Store) -> tuple[float, float]:
        """The anchor sole's centre of pressure (sole frame, m) inside its outline; the last
        one while it presses less than ``anchor_cop_min_fz_n`` or reads non-finite."""
        point = centre_of_pressure(store[WRENCHES][ANKLE_SENSORS[self.anchor]],
                                   self._cop_min_fz_n)
        if point is None:
            return self._contact_point
        x_lo, x_hi, y_lo, y_hi = self._sole_box
        return min(max(point[0], x_lo), x_hi), min(max(point[1], y_lo), y_hi)

    def _place(self, contact_point: tuple[float, float] = (0.0, 0.0),
                gyro_rad_s: np.ndarray | None = None, rolling: bool = False) -> None:
        """This period's torso and soles: the legs' placement (the anchor's held contact point
        and heading), turned about the contact point by the anchor's slip the gyro sees
        (``gyro_rad_s``: the IMU's rate in the torso frame; None: none)."""
        T_world_torso, T_world_soles = np.empty((4, 4)), np.empty((2, 4, 4))
        T_world_anchor, R_legs = np.empty((4, 4)), np.empty((3, 3))
        use_gyro = gyro_rad_s is not None and self._R_legs is not None
        _place_turned(self._quat, self._T_torso_soles, self.anchor, self._T_world_anchor,
                      contact_point[0], contact_point[1],
                      gyro_rad_s if use_gyro else self._no_gyro, use_gyro,
                      self._R_legs if use_gyro else self._no_gyro_R, rolling, self._keep,
                      self._dt_s, self._slip,
                      T_world_torso, T_world_soles, T_world_anchor, R_legs)
        self._T_world_anchor = T_world_anchor  # the legs' own
        self._contact_point = contact_point
        self._R_legs = R_legs
        self._T_world_torso, self._T_world_soles = T_world_torso, T_world_soles

    def _keep_pivot_continuous(self, point: tuple[float, float]) -> None:
        """The gyro's turn is about the anchor's contact point: when that point moves on the
        sole (a centre of pressure crossing from one edge to the other), shift the held anchor
        so that the turned torso does not jump (by the turn times the point's move: 12.5 mm in
        one period, a 150 N backward capture step's stance sole turned 91 mrad while its centre
        of pressure crossed 129 mm: the capture point came within 4 mm of the monitor's line,
        past it on another CPU; docs/history/walking.md)."""
        turn = float(self._slip[SLIP_TURN])
        if not turn or point == self._contact_point:
            return
        A = self._T_world_anchor
        (x0, y0), (x1, y1) = self._contact_point, point
        dx = A[0, 0] * (x0 - x1) + A[0, 1] * (y0 - y1)  # the old point less the new (world)
        dy = A[1, 0] * (x0 - x1) + A[1, 1] * (y0 - y1)
        c, s = math.cos(turn), math.sin(turn)
        A = A.copy()
        A[0, 3] += dx - (c * dx - s * dy)  # (I - R(turn)) (old - new)
        A[1, 3] += dy - (s * dx + c * dy)
        self._T_world_anchor = A

    def _take_anchor(self, side: int) -> None:
        """Sole ``side`` takes the anchor as estimated, the gyro's turn included: its place and
        heading the mean of its last LANDED_PERIODS estimates on the floor (one period's
        estimate carries the encoders' and the IMU's noise through the legs into every later
        step: perturbed robots' estimates drifted 10 mm in a 1 m walk)."""
        self.anchor = side
        T = self._T_world_soles[side].copy()
        if self._landed:
            x, y, z, c, s = np.mean(self._landed, axis=0)
            T = _turn_about(T[:3, 3], math.atan2(s, c) - math.atan2(T[1, 0], T[0, 0])) @ T
            T[:3, 3] = x, y, z
        self._T_world_anchor = T
        self._landed.clear()
        self._contact_point = (0.0, 0.0)  # its own, read next period
        self._R_legs, self._slip[SLIP_TURN] = None, 0.0

    def _write(self, store: Store) -> None:
        store[T_WORLD_TORSO] = self._T_world_torso
        store[T_WORLD_SOLES] = self._T_world_soles

    def _fly(self) -> None:
        """A period in flight: the torso where it was, tilted as the attitude says, its heading
        kept; the soles through the legs; the anchor where its sole now is."""
        R = np.empty((3, 3))
        quat_to_matrix_into(self._quat, R)
        turn = _heading(self._T_world_torso[:3, :3]) - _heading(R)
        c, s = math.cos(turn), math.sin(turn)
        T_world_torso = np.eye(4)
        T_world_torso[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R
        T_world_torso[:3, 3] = self._T_world_torso[:3, 3]
        self._T_world_torso = T_world_torso
        self._T_world_soles = T_world_torso @ self._T_torso_soles
        self._T_world_anchor = self._T_world_soles[self.anchor].copy()
        self._R_legs, self._slip[SLIP_TURN] = None, 0.0
        self._landed.clear()

    def update(self, state: RobotState, store: Store) -> None:
        if self._inputs(state, store):
            wrenches = store[WRENCHES]
            fz = [float(wrenches[ANKLE_SENSORS[0]][2]), float(wrenches[ANKLE_SENSORS[1]][2])]
            flight_n = self._flight_max_fz_n
            light = fz[0] < flight_n and fz[1] < flight_n
            self._light_periods = self._light_periods + 1 if light else 0  # NaN: not light
            self._pressed = self._pressed or fz[0] >= flight_n or fz[1] >= flight_n
            # a robot whose soles never pressed (started hanging) has no flight to sense:
            # the anchor holds
            if self._pressed and self._light_periods >= self._flight_periods:
                self._fly()
                self._write(store)
                return
            contact = store[CONTACT]
            point = self._centre_of_pressure(store)
            x_lo, x_hi, y_lo, y_hi = self._sole_box
            on_edge = min(point[0] - x_lo, x_hi - point[0], point[1] - y_lo,
                          y_hi - point[1]) < EDGE_M
            self._keep_pivot_continuous(point)
            self._place(point, _gyro(state),
                        bool(contact[0]) != bool(contact[1]) and on_edge)
            other = 1 - self.anchor
            fz_anchor = fz[self.anchor]
            heavier = fz[other] > fz_anchor + self._anchor_switch_n
            # a sole just landed takes the anchor by weight only once it has stood (its
            # touchdown's force peak passed), unless the anchor lifts off
            settled = len(self._landed) == LANDED_PERIODS or not fz_anchor >= self._cop_min_fz_n
            if not contact[other]:
                self._landed.clear()
            elif (heavier and settled) or not contact[self.anchor]:
                self._take_anchor(other)
            else:  # on the floor, not yet the anchor: where it stands, for when it is
                (c, _, _, x), (s, _, _, y), (_, _, _, z) = self._T_world_soles[other, :3].tolist()
                self._landed.append((x, y, z, c, s))
        self._write(store)
