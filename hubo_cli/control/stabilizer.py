"""CoM feedback on the waist (hrpsys Stabilizer, TPCC form), with a hip strategy.

Each period the module takes, in the *feet frame* F (origin midway between the estimated
soles, level, x along the right sole's heading, z up):

* the measured centre of mass ``c`` or its capture point (the estimate's ``COM_WORLD``,
  ``CAPTURE_POINT_WORLD``: one pinocchio pass for every module, in the estimation layer);
* the reference ``c_ref``: the commanded posture's CoM with the torso upright (its own
  pinocchio pass on the command, held while the command does not change);
* the measured ZMP ``z`` (the estimate's ``ZMP_WORLD``: the soles' centres of pressure weighted
  by their normal forces) and its reference ``z_ref = c_ref`` (standing: static);

and moves the commanded CoM by a correction ``d`` (m) that follows Choi's law as hrpsys writes
it (``Stabilizer.cpp``, TPCC)::

    d_dot = -k_z * (z_ref - z) + k_c * (c_ref - c)

bounded in size, speed and acceleration so that the legs' joints stay well inside the
limiter's bands. The correction is realised as hrpsys does, by moving the waist:

* sagittal (x): the torso translates by ``d_x`` over the feet, upright, through the legs'
  closed-form IK (hip pitch, knee and ankle pitch together);
* lateral (y): the hip roll joints of Table IV sit on their limit of 0 in the standing
  posture, so the waist cannot translate sideways; both ankle rolls tilt the body instead by
  the angle that moves the CoM by ``d_y``.

Hip strategy: when the wanted sagittal correction exceeds the waist's bound (the ankles are
saturated), the excess pitches the upper body about the hips (both hip pitch joints, bounded
and leaked back), which moves the upper body's mass the rest of the way.

Feedback needs the feet on the ground: without the body's weight on the ankle sensors (or with
a bad sensor), the correction leaks back to zero.

Status: :class:`~hubo_cli.control.pipeline.SafetyProfile` leaves it out unless asked
(``stabilizer=True``). Measured on the simulated robot, whose legs' acceleration limit is
0.6 rad/s^2: a 0.2 s push of 90 N forward topples the robot with or without it, and one of
90 N backward, which the default balancer alone survives (the body rocks on its heels and
settles), topples it forward: the correction lags the rocking body by its acceleration bound.
Standing it changes nothing (0.03 deg).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.phase import BALANCERS_REST
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_WORLD,
    T_WORLD_SOLES,
    WRENCHES,
    ZMP_WORLD,
)
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import RobotState

K_ZMP = 0.2          # hrpsys k_tpcc_p (1/s)
K_COM = 4.0          # hrpsys k_tpcc_x (1/s)
MAX_SHIFT_M = 0.03   # the waist's correction, each axis
MAX_SHIFT_RATE_M_S = 0.15
MAX_SHIFT_ACCEL_M_S2 = 0.25  # about 0.45 rad/s^2 at the ankle: inside the limiter's 0.6
MAX_HIP_RAD = 0.12
HIP_LEAK_S = 1.0
SHIFT_LEAK_S = 0.5   # without load on the feet, the correction returns in this time
LEGS = (("right-leg", "right-ankle", "right_sole"), ("left-leg", "left-ankle", "left_sole"))


class Stabilizer(Module):
    """CoM/ZMP feedback on the waist (see the module docstring).

    Args:
        model: the robot model.
        dt_s: the control period (s).
        drill: the right hand holds the drill (its mass counts in the CoM).
        k_zmp, k_com: Choi's gains (1/s), >= 0.
        max_shift_m, max_rate_m_s, max_accel_m_s2: bounds of the correction, > 0.
        max_hip_rad: bound of the hip strategy's upper-body pitch (rad), >= 0 (0: no hips).
        use_capture_point: feed back the capture point (CoM + velocity / omega) in place of
            the CoM, so a push is answered while the body is still near its posture.
        com_offset_m: (x, y) added to the reference CoM in the feet frame (m), as
            hubo-motion-rt's ``com_x_offset``; the home posture's CoM moved by it must stay
            inside the support polygon of the two feet.

    Raises:
        ConfigError: a negative gain, a bound that is not positive, or a CoM reference outside
            the support polygon.
    """

    name = "stabilizer"
    reads = (COM_WORLD, CAPTURE_POINT_WORLD, T_WORLD_SOLES, ZMP_WORLD, WRENCHES)
    follows = (BALANCERS_REST,)
    log_columns = ("stabilizer.com_error_x_m", "stabilizer.com_error_y_m",
                   "stabilizer.zmp_error_x_m", "stabilizer.zmp_error_y_m",
                   "stabilizer.shift_x_m", "stabilizer.shift_y_m", "stabilizer.hip_rad")

    def __init__(self, model: RobotModel, dt_s: float, drill: bool = False,
                 k_zmp: float = K_ZMP, k_com: float = K_COM,
                 max_shift_m: float = MAX_SHIFT_M, max_rate_m_s: float = MAX_SHIFT_RATE_M_S,
                 max_accel_m_s2: float = MAX_SHIFT_ACCEL_M_S2,
                 max_hip_rad: float = MAX_HIP_RAD, use_capture_point: bool = True,
                 com_offset_m: tuple[float, float] = (0.0, 0.0)) -> None:
        gains = {"k_zmp": k_zmp, "k_com": k_com, "max_hip_rad": max_hip_rad}
        bounds = {"max_shift_m": max_shift_m, "max_rate_m_s": max_rate_m_s,
                  "max_accel_m_s2": max_accel_m_s2, "dt_s": dt_s}
        for name, value in gains.items():
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"stabilizer {name} must be >= 0, got {value}",
                                  hint=f"e.g. k_zmp={K_ZMP}, k_com={K_COM}")
        for name, value in bounds.items():
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"stabilizer {name} must be > 0, got {value}",
                                  hint=f"e.g. max_shift_m={MAX_SHIFT_M}")
        self.model = model
        self.dt_s = float(dt_s)
        self.k_zmp, self.k_com = float(k_zmp), float(k_com)
        self.max_shift_m = float(max_shift_m)
        self.max_rate_m_s = float(max_rate_m_s)
        self.max_accel_m_s2 = float(max_accel_m_s2)
        self.max_hip_rad = float(max_hip_rad)
        self.use_capture_point = bool(use_capture_point)
        self._robot = load_pin_robot(model, floating=True, urdf_path=model.urdf_path(drill))
        self._data = self._robot.model.createData()
        self._q = np.zeros(self._robot.model.nq)
        self._sole_ids = [self._robot.frame_id(sole) for _, _, sole in LEGS]
        self._weight_n = self._robot.weight_n
        self._loaded_n = model.estimation.body_on_soles_weight_fraction * self._weight_n
        self._legs = {leg: Limb(model, leg) for leg, _, _ in LEGS}
        self._slices = {leg: model.limb_slice(leg) for leg, _, _ in LEGS}
        names = model.joint_names
        self._roll = [names.index(model.limb(leg).joints[5]) for leg, _, _ in LEGS]
        self._hip_pitch = [names.index(model.limb(leg).joints[2]) for leg, _, _ in LEGS]
        self._last_cmd: np.ndarray | None = None
        self._last_ref = np.zeros(3)
        from hubo_cli.posture import home_posture

        home = home_posture(model)
        self._roll_per_m = 1.0 / self._sensitivity(home, self._roll, 1)
        self._hip_per_m = 1.0 / self._sensitivity(home, self._hip_pitch, 0)
        self.com_offset_m = self._checked_offset(com_offset_m, home)
        self.reset(home, None, None)

    def _checked_offset(self, offset_m: tuple[float, float], home: np.ndarray) -> np.ndarray:
        """The CoM offset (m) if the home posture's CoM moved by it lies inside the feet's
        support polygon (their box in the feet frame), else ConfigError."""
        offset = np.asarray(offset_m, dtype=float)
        if offset.shape != (2,) or not np.all(np.isfinite(offset)):
            raise ConfigError(f"the CoM offset must be two finite numbers (m), got {offset_m}",
                              hint="e.g. com_offset_m=(0.0, 0.0)")
        com = self._com_in_feet(home)[:2] + offset
        corners = self.model.feet.sole_corners_m()
        data = self._data
        mid = 0.5 * (data.oMf[self._sole_ids[0]].translation
                     + data.oMf[self._sole_ids[1]].translation)
        R = data.oMf[self._sole_ids[0]].rotation
        points = np.array([(R.T @ (data.oMf[fid].translation + data.oMf[fid].rotation @ c
                                   - mid))[:2] for fid in self._sole_ids for c in corners])
        lo, hi = points.min(axis=0), points.max(axis=0)
        if not np.all((com > lo) & (com < hi)):
            raise ConfigError(
                f"the CoM reference ({com[0] * 1000:+.0f}, {com[1] * 1000:+.0f}) mm lies outside "
                f"the support polygon x [{lo[0] * 1000:+.0f}, {hi[0] * 1000:+.0f}] mm, "
                f"y [{lo[1] * 1000:+.0f}, {hi[1] * 1000:+.0f}] mm (feet frame)",
                hint="keep com_offset_m within the feet")
        return offset

    # ------------------------------------------------------------------ reference
    def _com_in_feet(self, q_rad: np.ndarray) -> np.ndarray:
        """The CoM (x, y, height) in the feet frame F of the posture ``q_rad`` standing
        upright with its soles flat (the reference)."""
        model, data = self._robot.model, self._data
        q = self._robot.configuration(q_rad, None, out=self._q)
        com = pin.centerOfMass(model, data, q, False)
        p = np.zeros(3)
        for fid in self._sole_ids:
            p += 0.5 * pin.updateFramePlacement(model, data, fid).translation
        return data.oMf[self._sole_ids[0]].rotation.T @ (com - p)

    def _sensitivity(self, q_rad: np.ndarray, joints: list[int], axis: int) -> float:
        """d(CoM in F)[axis] / d(angle of both ``joints``), numerically (m/rad)."""
        eps = 1e-4
        up, down = q_rad.copy(), q_rad.copy()
        up[joints] += eps
        down[joints] -= eps
        return float((self._com_in_feet(up)[axis]
                      - self._com_in_feet(down)[axis]) / (2 * eps))

    def _measured_in_feet(self, state: RobotState, store: Store
                          ) -> tuple[np.ndarray, np.ndarray | None] | None:
        """The estimate in F: the CoM (or, with ``use_capture_point``, the capture point;
        x, y) and the ZMP (x, y; None without the body's weight on the ankle sensors or with a
        bad one); None when the estimate is not finite."""
        soles = np.asarray(store[T_WORLD_SOLES], dtype=float)
        com = np.asarray(store[COM_WORLD], dtype=float)
        cp = np.asarray(store[CAPTURE_POINT_WORLD], dtype=float)
        if not (np.all(np.isfinite(soles)) and np.all(np.isfinite(com))
                and np.all(np.isfinite(cp))):
            return None
        mid = 0.5 * (soles[0, :3, 3] + soles[1, :3, 3])
        heading = math.atan2(soles[0, 1, 0], soles[0, 0, 0])
        c, s = math.cos(heading), math.sin(heading)
        R_feet_T = np.array([[c, s], [-s, c]])  # the level feet frame's axes, transposed
        point = cp[:2] if self.use_capture_point else com[:2]
        measured = R_feet_T @ (point - mid[:2])
        total_fz = 0.0
        for _, sensor, _ in LEGS:
            wrench = store[WRENCHES].get(sensor)
            if wrench is None or not np.all(np.isfinite(wrench)):
                return measured, None
            total_fz += max(float(wrench[2]), 0.0)
        zmp = np.asarray(store[ZMP_WORLD], dtype=float)
        if total_fz < self._loaded_n or not np.all(np.isfinite(zmp[:2])):
            return measured, None
        return measured, R_feet_T @ (zmp[:2] - mid[:2])

    # ------------------------------------------------------------------ the module
    def reset(self, q_rad: np.ndarray, state: RobotState | None,
              store: Store | None) -> None:
        self.shift_m = np.zeros(2)
        self.rate_m_s = np.zeros(2)
        self.hip_rad = 0.0
        self.com_error_m = np.zeros(2)
        self.zmp_error_m = np.zeros(2)
        self._resting = False

    def _reference(self, q_cmd: np.ndarray) -> np.ndarray:
        if self._last_cmd is not None and np.array_equal(q_cmd, self._last_cmd):
            return self._last_ref
        self._last_cmd, self._last_ref = q_cmd.copy(), self._com_in_feet(q_cmd)
        return self._last_ref

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q = np.array(q_rad, dtype=float)
        if cycle.store.get(BALANCERS_REST, False):  # a phase moves the CoM itself: off
            if not self._resting:  # drop the correction once, pass the command through
                self.reset(q_rad, state, cycle.store)
                self._resting = True
            return self._report(q, cycle.info)
        self._resting = False
        dt = cycle.dt_s
        q_cmd = np.where(np.isfinite(q), q, state.q_rad)
        reference = self._reference(q_cmd)
        wanted_rate = -self.shift_m / SHIFT_LEAK_S  # no feedback: return to the command
        estimate = self._measured_in_feet(state, cycle.store)
        ok = estimate is not None
        if ok:
            measured, zmp = estimate
            if zmp is not None:
                # c_ref is the command's CoM moved by the correction already sent
                target = reference[:2] + self.com_offset_m
                self.com_error_m = target + self.shift_m - measured
                self.zmp_error_m = target - zmp
                wanted_rate = self.k_com * self.com_error_m - self.k_zmp * self.zmp_error_m
        else:
            cycle.flags.add("stabilizer-bad-sensor")
        # bounded rate and acceleration, then bounded size; the excess goes to the hips
        wanted_rate = np.clip(wanted_rate, -self.max_rate_m_s, self.max_rate_m_s)
        step = self.max_accel_m_s2 * dt
        previous = self.rate_m_s
        self.rate_m_s = self.rate_m_s + np.clip(wanted_rate - self.rate_m_s, -step, step)
        # brake before the bound: the speed that can still stop on it in whole periods
        a_dt = self.max_accel_m_s2 * dt
        for k in range(2):
            ahead = self.shift_m[k] * math.copysign(1.0, self.rate_m_s[k])
            room = max(self.max_shift_m - ahead, 0.0)
            brake = a_dt * (math.sqrt(0.25 + 2 * room / (a_dt * dt)) - 0.5)
            rate = math.copysign(min(abs(self.rate_m_s[k]), brake), self.rate_m_s[k])
            self.rate_m_s[k] = min(max(rate, previous[k] - a_dt), previous[k] + a_dt)
        self.shift_m = np.clip(self.shift_m + self.rate_m_s * dt, -self.max_shift_m,
                               self.max_shift_m)
        saturated = abs(self.shift_m[0]) >= 0.95 * self.max_shift_m
        excess = float(wanted_rate[0]) if saturated and ok else 0.0
        hip_rate = excess * self._hip_per_m - self.hip_rad / HIP_LEAK_S
        hip_rate = max(-0.1, min(0.1, hip_rate))
        self.hip_rad = max(-self.max_hip_rad, min(self.max_hip_rad, self.hip_rad + hip_rate * dt))
        return self._report(self._apply(q, q_cmd), cycle.info)

    def _report(self, q: np.ndarray, info: dict) -> np.ndarray:
        info["stabilizer.com_error_x_m"], info["stabilizer.com_error_y_m"] = (
            float(v) for v in self.com_error_m)
        info["stabilizer.zmp_error_x_m"], info["stabilizer.zmp_error_y_m"] = (
            float(v) for v in self.zmp_error_m)
        info["stabilizer.shift_x_m"] = float(self.shift_m[0])
        info["stabilizer.shift_y_m"] = float(self.shift_m[1])
        info["stabilizer.hip_rad"] = float(self.hip_rad)
        return q

    def _apply(self, q: np.ndarray, q_cmd: np.ndarray) -> np.ndarray:
        """The waist's x shift through the legs' IK, the y shift through the ankle rolls, the
        hip strategy through the hip pitches; NaN joints stay NaN."""
        dx = float(self.shift_m[0])
        if abs(dx) > 1e-7:
            solved = {}
            for leg, _, _ in LEGS:
                sl = self._slices[leg]
                limb = self._legs[leg]
                T_N_sole = limb.fk(q_cmd[sl])
                T_N_sole[0, 3] -= dx  # the torso moves +dx over the sole
                result = limb.solve(T_N_sole, q_cmd[sl])
                if result.status != "exact":
                    break
                solved[leg] = result.q_rad
            if len(solved) == len(LEGS):
                for leg, q_leg in solved.items():
                    sl = self._slices[leg]
                    q[sl] = np.where(np.isfinite(q[sl]), q_leg, q[sl])
        roll = float(self.shift_m[1]) * self._roll_per_m
        lower, upper = self.model.lower_rad, self.model.upper_rad
        for joints, delta in ((self._roll, roll), (self._hip_pitch, self.hip_rad)):
            for i in joints:
                if math.isfinite(q[i]):
                    q[i] = min(max(q[i] + delta, lower[i]), upper[i])
        return q
