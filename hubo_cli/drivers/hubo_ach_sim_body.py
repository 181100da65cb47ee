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
- ``imu[2]`` (the body IMU): the torso's tilt angles a_x, a_y (rad, roll and pitch, the inverse
  of what the hardware driver decodes, :func:`~hubo_cli.drivers.hubo_ach.body_imu_tilt`), a_z 0
  (a Hubo's body IMU gives no heading; the simulator's true yaw stays in the simulator) and its
  angular rates w_x, w_y, w_z (rad/s, torso axes). The foot tilt sensors (``imu[0]``,
  ``imu[1]``) are not modelled (zero).
- ``ft[4]`` (R hand, L hand, R foot, L foot): m_x, m_y (N m) and f_z (N) as the simulated
  three-axis sensors read them in their own frames (the sim driver's ``RobotState.ft``: the
  environment's wrench and the weight beyond the sensor), the frames the hardware driver
  reads them in.
- ``joint[].cur``, ``heat``, ``tmp`` and ``status[].tempError``: the motors' currents, heat and
  temperatures from the simulated joint torques (:mod:`hubo_cli.drivers.hubo_ach_motors`, the
  robot file's ``[motors]``). The boards' ``driver[].temp`` stay 0, which hubo-daemon publishes
  for "no temperature reading".
- the simulator's truth on request (``track_truth``, ``--truth-log``): the torso's true
  position and tilt and the soles' true places (:data:`TRUTH_COLUMNS`), what a walk's arrival
  is measured against outside the robot (the hardware driver never sees it).
- a push on the torso on request (:meth:`PhysicsBody.push_torso`, ``--push``): the hardware
  driver has no world to push, the daemon's physics does it.
- motor faults on request (:mod:`hubo_cli.drivers.hubo_ach_faults`): a ``frozen`` joint's
  motor is held where the joint was (its encoder stays there, ``joint[].ref`` goes on following
  the references, ``status[].jam`` set); a ``hot`` motor heats faster than its load makes it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, StateFrame
from hubo_cli.drivers.hubo_ach_daemon import DaemonBody
from hubo_cli.drivers.hubo_ach_faults import Fault
from hubo_cli.drivers.hubo_ach_motors import MotorModel
from hubo_cli.drivers.sim import SimDriver
from hubo_cli.model import RobotModel
from hubo_cli.state import FT_SENSORS
from hubo_cli.tasks.spec import Scene
from hubo_cli.urdf import DRILL_FRAME

# the truth log's columns after time_s: the torso's true position (m) and tilt from upright
# (deg), each sole's true place on the floor (m, m, rad)
TRUTH_COLUMNS = ("torso_x_m", "torso_y_m", "torso_z_m", "torso_tilt_deg",
                 "right_x_m", "right_y_m", "right_yaw_rad", "left_x_m", "left_y_m",
                 "left_yaw_rad")


class PhysicsBody(DaemonBody):
    """The simulated robot behind hubo-daemon's channels (with its motors' faults).

    Args:
        model: the robot model.
        posture_rad: the 42 joints' start positions (hubo-ach order, rad); the simulated robot
            stands in its limb joints.
        perturb_seed: the sim driver's ``--perturb`` draw (None or 0: nominal).
        filter_length: ``HUBO_REF_FILTER_LENGTH``.
        track_tool: called with each published state's time (s) and the right hand's tool's
            true world position (m; the drill bit with ``drill=True``, else the hand): what a
            run's hole would be, measured outside the robot (None: not tracked).
        track_truth: called with each published state's time (s) and the simulator's truth
            (:data:`TRUTH_COLUMNS`; None: not tracked).
        sim_options: further :class:`~hubo_cli.drivers.sim.SimOptions` (``drill=True``: the
            drill in the right hand, as the task's robot holds it).
    """

    fault_kinds = ("frozen", "hot")

    def __init__(self, model: RobotModel, posture_rad, perturb_seed: int | None = None,
                 filter_length: int = hubo_ach.REF_FILTER_LENGTH,
                 track_tool: Callable[[float, np.ndarray], None] | None = None,
                 track_truth: Callable[[float, np.ndarray], None] | None = None,
                 **sim_options) -> None:
        posture = np.asarray(posture_rad, dtype=float)
        if posture.shape != (JOINT_COUNT,) or not np.all(np.isfinite(posture)):
            raise ValueError(f"posture must be {JOINT_COUNT} finite angles (rad)")
        self.filter_length = filter_length
        self.joint_names = model.joint_names
        self.index = np.array([model.hubo_ach["index"][n] for n in model.joint_names])
        self.motors = MotorModel(model)
        self.frozen_rad: dict[int, float] = {}  # limb joint (model order) -> where it stuck
        self.tool_frame = DRILL_FRAME if sim_options.get("drill") else "right_hand"
        self.track_tool = track_tool
        self.track_truth = track_truth
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
        target = self._filtered[self.index]
        for i, q in self.frozen_rad.items():
            target[i] = q
        self.sim.send(target)
        self._state = self.sim.step()
        self.motors.advance(self._state.tau_nm, period_s)

    def place_wall(self, distance_m: float) -> None:
        """A wall with its near face ``distance_m`` ahead (world +x) of where the robot started,
        now: the size and material (cardboard) of the shipped tasks' wall; with ``drill=True``
        the bit cuts it as in ``hubo sim``. A task's simulator run places it once the robot
        holds its tool ready (the raise might sweep through it); the daemon at a set time."""
        wall = Scene()
        self.sim.add_wall(distance_m, wall.wall_height_m, wall.wall_width_m,
                          wall.wall_thickness_m)

    def push_torso(self, force_world_n, duration_s: float) -> None:
        """Push the torso at its centre of mass with a world force (N) for ``duration_s``,
        from now (as ``hubo sim --push`` does on the sim driver)."""
        self.sim.push_torso(force_world_n, duration_s)

    def truth(self) -> np.ndarray:
        """The simulator's truth now (:data:`TRUTH_COLUMNS`)."""
        T_world_torso = self.sim.frame_pose("torso")
        row = [*T_world_torso[:3, 3],
               math.degrees(math.acos(min(1.0, max(-1.0, float(T_world_torso[2, 2])))))]
        for sole in ("right_sole", "left_sole"):
            T = self.sim.frame_pose(sole)
            row += [T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])]
        return np.array(row)

    def begin_fault(self, fault: Fault) -> None:
        i = self.joint_names.index(fault.joint)
        if fault.kind == "frozen":
            self.frozen_rad[i] = float(self._state.q_rad[i])
        elif fault.kind == "hot":
            self.motors.heat(int(self.index[i]), fault.rate_k_s)
        else:
            super().begin_fault(fault)

    def state(self, time_s: float) -> StateFrame:
        measured = self._state
        if self.track_tool is not None:
            self.track_tool(time_s, self.sim.frame_pose(self.tool_frame)[:3, 3])
        if self.track_truth is not None:
            self.track_truth(time_s, self.truth())
        pos, vel = self._filtered.copy(), self._filter_vel.copy()
        pos[self.index], vel[self.index] = measured.q_rad, measured.dq_rad_s
        # FT_SENSORS is hubo-ach's ft[] order (R hand, L hand, R foot, L foot): m_x, m_y, f_z
        ft = np.array([[w[3], w[4], w[2]] for w in (measured.ft[name] for name in FT_SENSORS)])
        jam = np.zeros(JOINT_COUNT, dtype=np.uint8)
        jam[self.index[list(self.frozen_rad)]] = 1
        motors = self.motors
        return StateFrame(time_s, hubo_ach.body_imu_tilt(measured.imu_quat_wxyz),
                          np.array(measured.imu_gyro_rad_s, dtype=float), ft, pos, vel,
                          ref_rad=self._filtered.copy(), tmp_c=motors.tmp_c.copy(),
                          cur_a=motors.cur_a.copy(), heat_j=motors.heat_j.copy(),
                          status={"jam": jam, "tempError": motors.temp_error})

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
