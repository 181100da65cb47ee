"""The ideal driver (name ``ideal``): the robot is exactly where it was commanded, no physics.

Used by pipeline tests and benchmarks. Each period the measured joints equal the last applied
command and the velocities are its finite difference; the feet stay flat on the floor, so the
IMU reads the torso orientation the legs give it (the lower sole flat, heading 0: upright in
the home posture), its gyro that orientation's rate over the period and its accelerometer
gravity alone (nothing accelerates: :func:`imu_readings`). The force/torque sensors read
what a robot standing still in that posture would: the wrists the weight of what hangs beyond
them (the hand, the drill with option ``drill``:
:func:`~hubo_cli.estimation.wrenches.hanging_readings`, so the estimate's compensated wrists
read zero); the ankles the foot's weight plus the floor's push, the whole robot's weight (the
URDF's masses) carried by the soles on the floor with their total centre of pressure under the
centre of mass, split between two soles down by the lever rule
(:mod:`hubo_cli.drivers.floor`); a foot in the air reads its own weight alone. Torques are
unknown. Commands pass the same checks as on the other drivers (NaN keeps the joint, position
limits clip).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.drivers import checks
from hubo_cli.drivers.base import Driver, RunContext
from hubo_cli.drivers.floor import FLOOR_BAND_M, floor_arrays, standing_readings
from hubo_cli.errors import ConfigError, DeviceError
from hubo_cli.estimation.wrenches import (
    measured_mask,
    sensor_chains,
    sensor_loads,
)
from hubo_cli.geometry import matrix_to_quat_into
from hubo_cli.kinematics.dh import JIT, chain_fk, kernel_array
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.posture import home_posture
from hubo_cli.state import FT_SENSORS, GRAVITY_M_S2, RobotState


# A period's state in one compiled call (with the command check's kernel, send's): the numpy
# version (two FK calls, a quaternion, small array operations) cost several times more than the
# work. Its results are bit for bit those of Limb.fk + matrix_to_quat_wxyz
# (tests/test_driver_ideal.py compares them). The signature is declared, so the kernel loads
# from numba's cache at import and never compiles during a run.
@nb.njit("void(float64[::1], float64[::1], float64, int64[::1], float64[:, :, ::1], "
         "float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
         "float64[:, :, ::1], float64[::1], float64[::1], float64[::1], float64[::1])", **JIT)
def _reach_command(cmd, q_prev, period_s, starts, base, offset, alpha, a, d, end, q_out, q_copy,
             dq_out, quat_out):
    """One period: q_out = q_copy = cmd, dq_out its finite difference, quat_out the torso
    orientation with the lower sole (first leg on a tie) flat on the floor."""
    for i in range(cmd.shape[0]):
        dq_out[i] = (cmd[i] - q_prev[i]) / period_s
        q_out[i] = cmd[i]
        q_copy[i] = cmd[i]
    T = np.empty((2, 4, 4))
    for k in range(2):
        s = starts[k]
        chain_fk(q_out[s:s + 6], base[k], offset[k], alpha[k], a[k], d[k], end[k], T[k])
    lower = 1 if T[1, 2, 3] < T[0, 2, 3] else 0
    R = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            R[i, j] = T[lower, j, i]  # the sole's orientation in the torso, transposed
    matrix_to_quat_into(R, quat_out)


def imu_readings(quat_prev_wxyz, quat_wxyz, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The gyro (rad/s, torso axes) of a turn from ``quat_prev_wxyz`` to ``quat_wxyz`` over
    ``period_s`` (the rotation vector of q_prev^-1 q over the period) and the accelerometer's
    specific force at rest in ``quat_wxyz``: gravity in the torso axes (m/s^2)."""
    w0, x0, y0, z0 = (float(v) for v in quat_prev_wxyz)
    w1, x1, y1, z1 = (float(v) for v in quat_wxyz)
    # d = conj(q_prev) q, the turn in the torso's axes
    dw = w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1
    dx = w0 * x1 - x0 * w1 - y0 * z1 + z0 * y1
    dy = w0 * y1 + x0 * z1 - y0 * w1 - z0 * x1
    dz = w0 * z1 - x0 * y1 + y0 * x1 - z0 * w1
    if dw < 0.0:
        dw, dx, dy, dz = -dw, -dx, -dy, -dz
    s = math.sqrt(dx * dx + dy * dy + dz * dz)
    scale = 2.0 / period_s if s < 1e-12 else 2.0 * math.atan2(s, dw) / s / period_s
    n2 = w1 * w1 + x1 * x1 + y1 * y1 + z1 * z1
    g = GRAVITY_M_S2 / n2  # R^T e_z is the third row of R
    accel = (2.0 * (x1 * z1 - w1 * y1) * g, 2.0 * (y1 * z1 + w1 * x1) * g,
             (w1 * w1 - x1 * x1 - y1 * y1 + z1 * z1) * g)
    return np.array((dx * scale, dy * scale, dz * scale)), np.array(accel)


class IdealDriver(Driver):
    """State = command. Option ``drill``: the right hand holds the drill (its weight on the
    wrist sensor)."""

    name = "ideal"
    sensors_measured = False  # state = command: a still IMU, the drill's weight alone

    @classmethod
    def run_options(cls, run: RunContext) -> dict:
        """The drill in the right hand."""
        return {"drill": run.tools.get("right-arm") == "drill"}

    def __init__(self, model: RobotModel, drill: bool = False, **options) -> None:
        if options:
            raise ConfigError(f"the ideal driver takes no options but drill "
                              f"(got {', '.join(options)})")
        super().__init__(model)
        masses, coms = sensor_loads(model, bool(drill))
        self._sensors = (*sensor_chains(model), masses, coms, GRAVITY_M_S2, measured_mask(),
                         *floor_arrays(model, bool(drill)), FLOOR_BAND_M)
        self._cmd = np.zeros(len(self.joint_names))
        self._q = self._cmd.copy()
        self._t = 0.0
        self._state: RobotState | None = None
        self._flags: list[str] = []
        self._stopped = False
        self._closed = False
        legs = [Limb(model, name) for name in LEGS]
        starts = [model.limb_slice(name).start for name in LEGS]
        # _reach_command's leg arguments: slice starts, then base, offset, alpha, a, d, end per leg
        self._legs = (np.array(starts, dtype=np.int64),) + tuple(
            np.array([leg.fk_chain[k] for leg in legs], dtype=float) for k in range(6))
        self._lower = np.array(model.lower_rad, dtype=float)  # writable: one signature
        self._upper = np.array(model.upper_rad, dtype=float)

    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Put the robot at ``q0_rad`` (home posture by default), time 0."""
        if self._closed:
            raise DeviceError("the ideal driver is closed", hint="create a new driver")
        q0 = home_posture(self.model) if q0_rad is None else np.asarray(q0_rad, dtype=float)
        if q0.shape != (len(self.joint_names),) or not np.all(np.isfinite(q0)):
            raise ConfigError(f"start posture must be {len(self.joint_names)} finite angles")
        self._cmd = np.clip(q0, self.model.lower_rad, self.model.upper_rad)
        self._q = self._cmd
        self._t = 0.0
        self._stopped = False
        self._flags = []
        self._q, q, _, quat = self._advance()
        self._state = self._make_state(q, np.zeros_like(q), quat, quat)
        return self._state

    def read(self) -> RobotState:
        """The state at the end of the last period."""
        self._require_started()
        return self._state

    def send(self, q_cmd_rad) -> np.ndarray:
        """Apply a command after the common checks; ignored (held) after :meth:`stop`."""
        self._require_started()
        q = self.full_command(self._cmd, q_cmd_rad)
        if self._stopped:
            self._flags.append("stopped")
            return self._cmd.copy()
        out = np.empty(len(q))
        code = checks.sanitize_into(self._cmd, kernel_array(q), self._lower, self._upper, out)
        self._flags += checks.flags_of(code)
        self._cmd = out
        return out.copy()

    def step(self) -> RobotState:
        """Advance one period: the joints reach the last command."""
        self._require_started()
        self._q, q, dq, quat = self._advance()
        self._t += self.period_s
        self._state = self._make_state(q, dq, quat, self._state.imu_quat_wxyz)
        return self._state

    def stop(self) -> None:
        """Hold the last command. Never raises."""
        self._stopped = True

    def close(self) -> None:
        """Nothing to release; later calls raise DeviceError."""
        self._stopped = True
        self._closed = True

    def _require_started(self) -> None:
        if self._closed:
            raise DeviceError("the ideal driver is closed", hint="create a new driver")
        if self._state is None:
            raise DeviceError("the ideal driver has not been started",
                              hint=checks.NOT_STARTED_HINT)

    def _advance(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The joints reach the command: (driver's copy, state's copy, velocities, IMU)."""
        n = len(self._cmd)
        q, q_state, dq, quat = np.empty(n), np.empty(n), np.empty(n), np.empty(4)
        _reach_command(self._cmd, self._q, self.period_s, *self._legs, q, q_state, dq, quat)
        return q, q_state, dq, quat

    def _make_state(self, q: np.ndarray, dq: np.ndarray, quat: np.ndarray,
                    quat_prev: np.ndarray) -> RobotState:
        if self._flags:
            flags, self._flags = list(dict.fromkeys(self._flags)), []
        else:
            flags = []
        if self._stopped and "stopped" not in flags:
            flags.append("stopped")
        gyro, accel = imu_readings(quat_prev, quat, self.period_s)
        readings = np.empty((len(FT_SENSORS), 6))
        standing_readings(q, quat, *self._sensors, readings)
        return RobotState(time_s=self._t, q_rad=q, dq_rad_s=dq, flags=tuple(flags),
                          imu_quat_wxyz=quat, imu_gyro_rad_s=gyro, imu_accel_m_s2=accel,
                          ft=dict(zip(FT_SENSORS, readings, strict=True)))
