"""The ideal driver (name ``ideal``): the robot is exactly where it was commanded, no physics.

Used by pipeline tests and benchmarks. Each period the measured joints equal the last applied
command and the velocities are its finite difference; the feet stay flat on the floor, so the
IMU reads the torso orientation the legs give it (the lower sole flat, heading 0: upright in
the home posture); the force/torque sensors read zero, torques are unknown. Commands pass the
same checks as on the other drivers (NaN keeps the joint, position limits clip).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.drivers import checks
from hubo_cli.drivers.base import Driver
from hubo_cli.errors import ConfigError, DeviceError
from hubo_cli.geometry import matrix_to_quat_wxyz
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState


class IdealDriver(Driver):
    """State = command. No options."""

    name = "ideal"

    def __init__(self, model: RobotModel, **options) -> None:
        if options:
            raise ConfigError(f"the ideal driver takes no options (got {', '.join(options)})")
        super().__init__(model)
        self._cmd = np.zeros(len(self.joint_names))
        self._q = self._cmd.copy()
        self._t = 0.0
        self._state: RobotState | None = None
        self._flags: list[str] = []
        self._stopped = False
        self._closed = False
        self._legs = [(Limb(model, name), model.limb_slice(name)) for name in LEGS]

    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Put the robot at ``q0_rad`` (home posture by default), time 0."""
        if self._closed:
            raise DeviceError("the ideal driver is closed", hint="create a new driver")
        q0 = home_posture(self.model) if q0_rad is None else np.asarray(q0_rad, dtype=float)
        if q0.shape != (len(self.joint_names),) or not np.all(np.isfinite(q0)):
            raise ConfigError(f"start posture must be {len(self.joint_names)} finite angles")
        self._cmd = np.clip(q0, self.model.lower_rad, self.model.upper_rad)
        self._q = self._cmd.copy()
        self._t = 0.0
        self._stopped = False
        self._flags = []
        self._state = self._make_state(np.zeros_like(self._q))
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
        q, flags, _ = checks.sanitize_command(self.model, self._cmd, q)
        self._flags += flags
        self._cmd = q
        return self._cmd.copy()

    def step(self) -> RobotState:
        """Advance one period: the joints reach the last command."""
        self._require_started()
        dq = (self._cmd - self._q) / self.period_s
        self._q = self._cmd.copy()
        self._t += self.period_s
        self._state = self._make_state(dq)
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

    def _make_state(self, dq: np.ndarray) -> RobotState:
        flags, self._flags = list(dict.fromkeys(self._flags)), []
        if self._stopped and "stopped" not in flags:
            flags.append("stopped")
        return RobotState(time_s=self._t, q_rad=self._q.copy(), dq_rad_s=dq, flags=tuple(flags),
                          imu_quat_wxyz=self._imu_quat_wxyz())

    def _imu_quat_wxyz(self) -> np.ndarray:
        """The torso orientation with the lower sole flat on the floor (heading 0)."""
        T_N_soles = [leg.fk(self._q[part]) for leg, part in self._legs]
        T_N_sole = min(T_N_soles, key=lambda T: T[2, 3])
        return matrix_to_quat_wxyz(T_N_sole[:3, :3].T)

