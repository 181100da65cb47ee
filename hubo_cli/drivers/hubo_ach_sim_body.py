"""The simulated Hubo as hubo-daemon's body: the PyBullet world of the sim driver behind
``hubo-ref`` and ``hubo-state`` (``hubo hardware sim-daemon``).

Each period the reference in force goes through hubo-daemon's reference filter per joint as its
mode says (mode 0: f <- (f (L - 1) + r) / L with L = 40, mode 1: f <- r; the compliant and
encoder-filter modes need real motors and keep f), the filter's output is the motors' target,
and the simulator (:class:`~hubo_cli.drivers.sim.SimDriver`, its world, motors, contacts,
sensors and ``--perturb`` draws unchanged) runs one 5 ms period. What it measures becomes
``hubo_state``, in hubo-ach's units:

- ``joint[].pos``, ``vel``: the 24 limb joints' encoders (rad, rad/s; with the draw's sensor
  noise); ``joint[].ref``: the filter's output. The joints the simulated robot has not (neck,
  waist, wrist roll, fingers) are ideal motors at the filter's output, as in the fake daemon.
- ``imu[2]`` (the body IMU): the torso's tilt angles a_x, a_y, a_z (rad, the inverse of what the
  hardware driver decodes, :func:`~hubo_cli.drivers.hubo_ach.tilt_from_quat`) and its angular
  rates w_x, w_y, w_z (rad/s, torso axes). The foot tilt sensors (``imu[0]``, ``imu[1]``) are
  not modelled (zero).
- ``ft[4]`` (R hand, L hand, R foot, L foot): m_x, m_y (N m) and f_z (N) as the simulated
  three-axis sensors read them in their own frames (the sim driver's ``RobotState.ft``: the
  environment's wrench and the weight beyond the sensor), the frames the hardware driver
  reads them in.
- ``cur``, ``heat``, ``tmp`` and the boards' ``temp`` stay zero: the model has no motor
  constants, gear ratios or thermal model to turn the simulated joint torques into currents or
  temperatures.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, StateFrame
from hubo_cli.drivers.hubo_ach_daemon import DaemonBody
from hubo_cli.drivers.sim import SimDriver
from hubo_cli.model import RobotModel
from hubo_cli.state import FT_SENSORS


class PhysicsBody(DaemonBody):
    """The simulated robot behind hubo-daemon's channels.

    Args:
        model: the robot model.
        posture_rad: the 42 joints' start positions (hubo-ach order, rad); the simulated robot
            stands in its limb joints.
        perturb_seed: the sim driver's ``--perturb`` draw (None or 0: nominal).
        filter_length: ``HUBO_REF_FILTER_LENGTH``.
        sim_options: further :class:`~hubo_cli.drivers.sim.SimOptions`.
    """

    def __init__(self, model: RobotModel, posture_rad, perturb_seed: int | None = None,
                 filter_length: int = hubo_ach.REF_FILTER_LENGTH, **sim_options) -> None:
        posture = np.asarray(posture_rad, dtype=float)
        if posture.shape != (JOINT_COUNT,) or not np.all(np.isfinite(posture)):
            raise ValueError(f"posture must be {JOINT_COUNT} finite angles (rad)")
        self.filter_length = filter_length
        self.index = np.array([model.hubo_ach["index"][n] for n in model.joint_names])
        self.sim = SimDriver(model, perturb_seed=perturb_seed, **sim_options)
        try:
            self._state = self.sim.start(posture[self.index])
        except Exception:
            self.sim.close()
            raise
        self._filtered = posture.copy()
        # the limb joints' start: within their limits, as the simulator stands them
        self._filtered[self.index] = np.clip(posture[self.index], model.lower_rad,
                                             model.upper_rad)
        self._filter_vel = np.zeros(JOINT_COUNT)

    def advance(self, ref_rad: np.ndarray, mode: np.ndarray, period_s: float) -> None:
        previous = self._filtered
        self._filtered = hubo_ach.reference_filter(previous, ref_rad, mode, self.filter_length)
        self._filter_vel = (self._filtered - previous) / period_s
        self.sim.send(self._filtered[self.index])
        self._state = self.sim.step()

    def state(self, time_s: float) -> StateFrame:
        measured = self._state
        pos, vel = self._filtered.copy(), self._filter_vel.copy()
        pos[self.index], vel[self.index] = measured.q_rad, measured.dq_rad_s
        # FT_SENSORS is hubo-ach's ft[] order (R hand, L hand, R foot, L foot): m_x, m_y, f_z
        ft = np.array([[w[3], w[4], w[2]] for w in (measured.ft[name] for name in FT_SENSORS)])
        return StateFrame(time_s, hubo_ach.tilt_from_quat(measured.imu_quat_wxyz),
                          np.array(measured.imu_gyro_rad_s, dtype=float), ft, pos, vel,
                          ref_rad=self._filtered.copy())

    @property
    def joints_rad(self) -> np.ndarray:
        out = self._filtered.copy()
        out[self.index] = self._state.q_rad
        return out

    @property
    def target_rad(self) -> np.ndarray:
        return self._filtered.copy()

    @property
    def max_tilt_deg(self) -> float:
        """The torso's largest tilt from upright so far (deg, the simulator's truth)."""
        return self.sim.max_tilt_deg

    def close(self) -> None:
        self.sim.close()
