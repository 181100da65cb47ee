"""The simulated sensors read the same after the speed work: ``SimDriver._measure`` (plain
floats, one pass per sensor) against the straightforward implementation it replaced, kept here
(numpy poses and wrenches), on two identical simulated robots stepped side by side (PyBullet is
deterministic in one process, so both see the same physics) through a perturbed, pushed
standing run with the arms moving; and the F/T arithmetic alone on hostile random contacts,
poses and cutting wrenches."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hubo_cli.drivers.base import grip_flag
from hubo_cli.drivers.sim import GRAVITY_M_S2, SimDriver, _pose, _pose_times, _sensor_reading
from hubo_cli.geometry import matrix_to_quat_wxyz, rotation_log
from hubo_cli.posture import home_posture
from hubo_cli.state import FT_MEASURED, RobotState, Truth

FT_MASK = np.isin(np.arange(6), FT_MEASURED).astype(float)  # f_z, m_x, m_y
TOLERANCE = 1e-12  # relative (and absolute near zero): a few ulp of the largest reading


def _reference_wrench(rows, T_world_sensor, extra=None, extra_moment=None) -> np.ndarray:
    """The sensor's wrench as ``SimDriver._wrench`` computed it before (main 0f41291)."""
    if extra is not None:
        f, at = extra
        rows = [*rows, (*at, *f, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)]
    if not rows and extra_moment is None:
        return np.zeros(6)
    force, moment = np.zeros(3), np.zeros(3)
    for row in rows:
        p, n, fn, f1, d1, f2, d2 = (np.array(row[0:3]), np.array(row[3:6]), row[6], row[7],
                                    np.array(row[8:11]), row[11], np.array(row[12:15]))
        g = n * fn + d1 * f1 + d2 * f2
        force += g
        moment += np.cross(p, g)
    if extra_moment is not None:
        moment += np.asarray(extra_moment)
    R, o = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
    moment -= np.cross(o, force)
    return np.concatenate((R.T @ force, R.T @ moment))


class _ReferenceSimDriver(SimDriver):
    """The simulated robot measuring as before the speed work (main 0f41291), its ankle
    sensors reading the mean of their wrenches over the period's physics steps (round 23)."""

    def _keep_rows(self) -> None:
        """Each earlier physics step's contacts, whole, for the ankles' mean."""
        self._reference_steps = [*getattr(self, "_reference_steps", []), self._contact_rows()]

    def _measure(self) -> RobotState:
        p, cid = self._p, self._cid
        js = p.getJointStates(self._robot, self._idx, physicsClientId=cid)
        q, dq, _, tau = zip(*js, strict=True)
        q, dq, tau = np.array(q), np.array(dq), np.array(tau)
        com, orn = p.getBasePositionAndOrientation(self._robot, physicsClientId=cid)
        T_world_torso = _pose(com, orn) @ self._T_com_torso
        v_com, omega_world = p.getBaseVelocity(self._robot, physicsClientId=cid)
        R = T_world_torso[:3, :3]
        gyro, accel = self._reference_imu(np.asarray(com), np.asarray(v_com),
                                          np.asarray(omega_world), T_world_torso)
        link_states = self._link_states = p.getLinkStates(
            self._robot, self._sensor_link_ids, computeLinkVelocity=1,
            computeForwardKinematics=1, physicsClientId=cid)
        contacts = self._contact_rows()
        steps, self._reference_steps = [*getattr(self, "_reference_steps", []), contacts], []
        ft, contact, filtered = {}, [False, False], self._fz_filtered_n
        for k, (sensor, link_id, k_state, rows_link_sensor, ankle, _,
                mass) in enumerate(self._sensor_table):
            T_link_sensor = np.vstack((np.reshape(rows_link_sensor, (3, 4)), (0, 0, 0, 1)))
            ls = link_states[k_state]
            T_world_sensor = _pose(ls[4], ls[5]) @ T_link_sensor
            if ankle is None:
                wrench = _reference_wrench(contacts.get(link_id, []), T_world_sensor)
            else:  # the mean over the period's physics steps
                wrench = np.mean([_reference_wrench(step.get(link_id, []), T_world_sensor)
                                  for step in steps], axis=0)
            previous, self._sensor_velocity[k] = self._sensor_velocity[k], ls[6]
            a = np.zeros(3) if previous is None else \
                (np.array(ls[6]) - np.array(previous)) / self.period_s
            load = mass * (np.array((0.0, 0.0, -GRAVITY_M_S2)) - a)
            ft[sensor] = (wrench + _reference_wrench([], T_world_sensor, (load, ls[0]))) \
                * FT_MASK
            if ankle is not None:
                fz = float(wrench[2])
                if filtered[ankle] is None:
                    filtered[ankle] = fz
                filtered[ankle] += self._contact_alpha * (fz - filtered[ankle])
                contact[ankle] = filtered[ankle] > self._contact_threshold_n
        self._flags += [grip_flag(frame) for frame in self._grips if self.holding(frame)]
        flags, self._flags = tuple(dict.fromkeys(self._flags)), []
        if self._stopped:
            flags = tuple(dict.fromkeys((*flags, "stopped")))
        quat = matrix_to_quat_wxyz(R)
        state = RobotState(time_s=self._t, q_rad=q, dq_rad_s=dq, imu_quat_wxyz=quat,
                           imu_gyro_rad_s=gyro, imu_accel_m_s2=accel, ft=ft, tau_nm=tau,
                           truth=Truth(T_world_torso, (contact[0], contact[1]), quat.copy()),
                           flags=flags)
        tilt_deg = math.degrees(math.acos(max(-1.0, min(1.0, float(R[2, 2])))))
        self._max_tilt_deg = max(self._max_tilt_deg, tilt_deg)
        return self._noise.measure(state)

    def _reference_imu(self, com_world, v_com_world, omega_world, T_world_torso):
        R = T_world_torso[:3, :3]
        v = v_com_world + np.cross(omega_world, T_world_torso[:3, 3] - com_world)
        last = self._imu_last
        self._imu_last = (v, R)
        if last is None:
            a, gyro = np.zeros(3), R.T @ omega_world
        else:
            a, gyro = (v - last[0]) / self.period_s, rotation_log(last[1].T @ R) / self.period_s
        a[2] += GRAVITY_M_S2
        return gyro, R.T @ a


def _close(a, b, what: str) -> None:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.max(np.abs(b))))
    assert np.max(np.abs(a - b)) <= TOLERANCE * scale, (what, a, b)


def _same_state(new: RobotState, old: RobotState, k: int) -> None:
    for name in ("q_rad", "dq_rad_s", "tau_nm", "imu_quat_wxyz", "imu_gyro_rad_s",
                 "imu_accel_m_s2"):
        _close(getattr(new, name), getattr(old, name), (k, name))
    assert new.ft.keys() == old.ft.keys()
    for sensor in old.ft:
        _close(new.ft[sensor], old.ft[sensor], (k, sensor))
    _close(new.truth.T_world_torso, old.truth.T_world_torso, (k, "T_world_torso"))
    _close(new.truth.quat_world_torso_wxyz, old.truth.quat_world_torso_wxyz, (k, "truth quat"))
    assert new.truth.feet_contact == old.truth.feet_contact, k
    assert new.time_s == old.time_s and new.flags == old.flags, k


@pytest.mark.parametrize("seed", [None, 7])
def test_sensors_read_as_the_reference_on_a_pushed_perturbed_run(model, seed):
    """300 periods (1.5 s): a 120 N push, then the arms swinging (the wrists' loads change),
    nominal and perturbed (the noise drawn alike on both robots from the same seed)."""
    options = {} if seed is None else {"perturb_seed": seed}
    new, old = SimDriver(model, **options), _ReferenceSimDriver(model, **options)
    q0 = home_posture(model)
    arms = [i for i, n in enumerate(model.joint_names) if n[1:] in ("SP", "EB", "WY")]
    try:
        _same_state(new.start(q0), old.start(q0), 0)
        for k in range(1, 300):
            if k == 20:
                for robot in (new, old):
                    robot.push_torso([120.0, 30.0, 0.0], 0.15)
            q = q0.copy()
            q[arms] += 0.4 * math.sin(k * 0.05)
            for robot in (new, old):
                robot.send(q)
            _same_state(new.step(), old.step(), k)
        assert new.max_tilt_deg == old.max_tilt_deg
        assert new.max_tilt_deg > 1.0  # the push moved the robot (measured 3-6 deg)
    finally:
        new.close()
        old.close()


def test_wrench_arithmetic_matches_the_reference_on_hostile_inputs():
    """Random contact rows (0-8 points, forces up to 1 kN, frictions), poses (any rotation,
    links metres away), a cutting force at a point and a pure moment."""
    rng = np.random.default_rng(33)
    for _ in range(500):
        rows = [tuple(rng.normal(0.0, 1.0, 15) * rng.choice([1e-3, 1.0, 1e3], 15))
                for _ in range(rng.integers(0, 9))]
        quat = rng.normal(size=4)
        link = (tuple(rng.normal(0.0, 3.0, 3)), tuple(quat))
        T_link_sensor = _pose(rng.normal(0.0, 0.2, 3), rng.normal(size=4))
        extra = moment = None
        if rng.random() < 0.5:
            extra = (tuple(rng.normal(0.0, 100.0, 3)), tuple(rng.normal(0.0, 2.0, 3)))
            moment = tuple(rng.normal(0.0, 10.0, 3))
        load, load_at = tuple(rng.normal(0.0, 30.0, 3)), tuple(rng.normal(0.0, 2.0, 3))
        T_world_sensor = _pose(*link) @ T_link_sensor
        contact = _reference_wrench(rows, T_world_sensor, extra, moment)
        expected = (contact + _reference_wrench([], T_world_sensor, (load, load_at))) * FT_MASK
        fz, reading = _sensor_reading(
            rows, _pose_times(*link, T_link_sensor[:3].ravel().tolist()), extra, moment, load,
            load_at)
        _close(reading, expected, "reading")
        _close(fz, contact[2], "contact f_z")


def test_the_simulated_sensor_writes_the_components_the_state_says_are_measured():
    """``drivers.sim._sensor_reading`` writes f_z, m_x, m_y in place (plain floats, no mask):
    the set the state and the estimate's ``measured_mask`` name. Changing one means the other."""
    from hubo_cli.estimation.wrenches import measured_mask
    from hubo_cli.state import FT_MEASURED

    assert FT_MEASURED == (2, 3, 4)
    assert measured_mask().tolist() == [0.0, 0.0, 1.0, 1.0, 1.0, 0.0]
