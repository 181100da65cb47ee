"""The PyBullet driver: standing physics, sensors and their frames, scene objects, drilling,
snapshots."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from control_support import compensated_wrenches

from hubo_cli.drivers.sim import CuttingModel, SimDriver
from hubo_cli.errors import ConfigError, DeviceError
from hubo_cli.estimation.build import build_estimator
from hubo_cli.estimation.keys import T_WORLD_TORSO
from hubo_cli.estimation.wrenches import sensor_loads
from hubo_cli.kinematics import get_limb
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.state import GRAVITY_M_S2
from hubo_cli.urdf import total_mass_kg

MODEL = load_model()
G = GRAVITY_M_S2


@pytest.fixture
def sim():
    robot = SimDriver(MODEL)
    yield robot
    robot.close()


def _hold(robot, q, periods):
    state = None
    for _ in range(periods):
        robot.send(q)
        state = robot.step()
    return state


@pytest.mark.physical
def test_stands_on_both_flat_feet_carrying_its_weight(sim):
    sim.start()
    state = _hold(sim, home_posture(MODEL), 100)
    # measured the same on both code paths (AVX-512 / portable): load 380.125 of 380.127 N,
    # right foot 183 N, torso 0.05 mm off its height, tilt 0.005 deg (21x), soles 0.005 deg
    # (40x), gyro 1e-6 rad/s, leg torque 10.9 N m (11x)
    assert state.truth.feet_contact == (True, True)
    weight = total_mass_kg(MODEL) * G
    right, left = state.ft["right-ankle"], state.ft["left-ankle"]
    # the ankle sensors carry the body less the feet below them
    feet_n = sum(sensor_loads(MODEL, drill=False)[0][2:]) * G
    assert right[2] + left[2] == pytest.approx(weight - feet_n, rel=0.02)
    assert 0.35 * weight < right[2] < 0.65 * weight
    sole = get_limb("right-leg").fk(home_posture(MODEL)[MODEL.limb_slice("right-leg")])
    assert state.truth.T_world_torso[2, 3] == pytest.approx(-sole[2, 3], abs=0.003)
    assert np.degrees(np.abs(state.tilt_rad())).max() < 0.1
    assert np.abs(state.imu_gyro_rad_s).max() < 0.01
    for name in ("right_sole", "left_sole"):
        T = sim.frame_pose(name)
        assert T[2, 3] == pytest.approx(0.0, abs=0.003)
        assert T[2, 2] > np.cos(np.radians(0.2))
    compensated = compensated_wrenches(MODEL, state)
    for wrist in ("right-wrist", "left-wrist"):
        assert state.ft[wrist][2] > 1.0  # the hand hangs on the sensor (along the forearm)
        # nothing touches the hands: the weight removed, nothing is left (0.01 N: the
        # simulator's gravity 9.81 against the estimate's 9.80665)
        assert np.abs(compensated[wrist]).max() < 0.01
    for sensor, wrench in state.ft.items():  # Hubo's three-axis sensors: f_z, m_x, m_y
        assert wrench[0] == wrench[1] == wrench[5] == 0.0, sensor
    leg = MODEL.limb_slice("right-leg")
    assert np.abs(state.tau_nm[leg]).max() > 1.0  # the leg motors carry the body
    assert np.allclose(state.q_rad, home_posture(MODEL), atol=1e-3)


@pytest.mark.physical
@pytest.mark.parametrize("joints_rad_s", [
    {"RSP": -0.3, "LSP": -0.3},  # the arms raised
    {"RHP": -0.1, "LHP": -0.1, "RKN": 0.2, "LKN": 0.2, "RAP": -0.1, "LAP": -0.1}])  # a squat
def test_a_standing_robot_moving_its_joints_reads_its_weight_each_period(sim, joints_rad_s):
    """The ankle sensors read the mean of their contact wrenches over the period's physics
    steps (an F/T board's anti-aliasing filter). The motors, given a new target every period,
    press the soles harder in one physics step and less in the other; the last step alone read
    0.88-0.97 of the weight (the arms) and 1.36-1.62 (the squat) on main 8d023ed, the mean
    0.9996-1.0005 (AVX-512 and portable alike): each period within 2 %."""
    q0 = home_posture(MODEL)
    sim.start(q0)
    carried_n = (total_mass_kg(MODEL) - sum(sensor_loads(MODEL, drill=False)[0][2:])) * G
    idx = [MODEL.joint_names.index(name) for name in joints_rad_s]
    rate_rad_s = np.array(list(joints_rad_s.values()))
    _hold(sim, q0, 100)
    for k in range(1, 401):  # 2 s at constant joint speeds
        q = q0.copy()
        q[idx] += rate_rad_s * k * sim.period_s
        sim.send(q)
        state = sim.step()
        if k > 20:  # past the start's acceleration
            fz_n = state.ft["right-ankle"][2] + state.ft["left-ankle"][2]
            assert fz_n == pytest.approx(carried_n, rel=0.02), k
    assert np.abs(state.q_rad[idx] - q[idx]).max() < 0.05  # the joints did move


def test_frame_poses_are_the_physics_as_of_the_last_step(sim):
    """The end frames' poses come from the link states read with the state: after moving
    steps they equal a fresh forward kinematics of the physics, and the hands move."""
    from hubo_cli.drivers.sim import FRAME_PARENTS, _pose

    state = sim.start()
    hand_before = sim.frame_pose("right_hand")[:3, 3]
    for k in range(20):
        sim.send(state.q_rad + 0.2 * np.sin(0.1 * k))
        sim.step()
        for frame, link in FRAME_PARENTS.items():
            ls = sim._p.getLinkState(sim._robot, sim._links[link], computeForwardKinematics=1,
                                     physicsClientId=sim._cid)
            fresh = _pose(ls[4], ls[5]) @ sim._T_link_frame[frame]
            assert np.allclose(sim.frame_pose(frame), fresh, atol=1e-12)
    assert np.linalg.norm(sim.frame_pose("right_hand")[:3, 3] - hand_before) > 0.01


@pytest.mark.physical
def test_frames_and_signs_of_sensors_under_a_forward_push(sim):
    sim.start()
    before = _hold(sim, home_posture(MODEL), 20)
    sim.push_torso([40.0, 0.0, 0.0], 0.2)
    during = _hold(sim, home_posture(MODEL), 20)
    # measured the same on both code paths (AVX-512 / portable): moments down by 18.8 and
    # 21.4 N m (3.8x the 5), tilt after 0.005 deg (the sensors do not read the floor's shear)
    for foot in ("right-ankle", "left-ankle"):
        # the centre of pressure moves forward: the ground's moment about +y turns negative
        assert during.ft[foot][4] < before.ft[foot][4] - 5.0
    after = _hold(sim, home_posture(MODEL), 200)
    assert np.degrees(np.abs(after.tilt_rad())).max() < 0.1


def test_cutting_model_resists_in_plane_motion_growing_with_speed():
    model = CuttingModel()
    slow, fast = np.array([0.0, 0.01, 0.0]), np.array([0.0, 0.1, 0.0])
    f_slow, f_fast = model.force_n(slow), model.force_n(fast)
    assert np.dot(f_slow, slow) < 0 and np.allclose(np.cross(f_slow, slow), 0)
    assert 1.0 < np.linalg.norm(f_slow) < 1.5
    assert np.linalg.norm(f_fast) > 6 * np.linalg.norm(f_slow)
    assert np.allclose(model.force_n(np.zeros(3)), 0)


def _drill_goal():
    """The middle of the paper's horizontal drilling span (bit along N x, 484 mm, z 75 mm)."""
    arm = get_limb("right-arm", "drill")
    q_far_right = np.array([-0.9914, -0.3651, -0.8339, -1.1618, -1.6542, 0.8894])
    q_far_left = np.array([-1.1853, 0.1213, 1.1383, -1.2893, -1.8826, -1.1184])
    T = arm.fk(q_far_right)
    T[1, 3] = (T[1, 3] + arm.fk(q_far_left)[1, 3]) / 2
    return arm, T, arm.solve(T, q_far_right).q_rad


@pytest.mark.physical
def test_drilling_wrist_torque_is_small_when_slow_and_over_the_limit_when_fast():
    arm, T_goal, q_arm = _drill_goal()
    q = home_posture(MODEL)
    sl = MODEL.limb_slice("right-arm")
    q[sl] = q_arm
    with SimDriver(MODEL, drill=True) as robot:
        wall = robot.add_wall(distance_m=0.479, height_m=1.5, width_m=1.2, thickness_m=0.01)
        assert wall is None  # created with the world
        robot.start(q)
        assert robot.walls and robot.walls[0].contains(robot.frame_pose("right_drill_bit")[:3, 3])
        _hold(robot, q, 40)
        moments = {}
        for speed in (0.01, 0.1):
            norms = []
            for _ in range(int(0.4 / robot.period_s)):
                T_goal[1, 3] -= speed * robot.period_s
                q_arm = arm.solve(T_goal, q_arm).q_rad
                q[sl] = q_arm
                norms.append(np.linalg.norm(_hold(robot, q, 1).ft["right-wrist"][3:]))
            moments[speed] = float(np.mean(norms[len(norms) // 2:]))
            assert np.linalg.norm(robot.cutting_force_n) > 0.5
    limit = MODEL.safety["wrist_torque_limit_nm"]
    # measured 0.243 N m slow (the paper's cut: 0.14-0.15 N m mean, 0.35 N m peak) and 1.73 N m
    # fast on both code paths (AVX-512 / portable): bounds 0.37 (1.5x) and the limit, 1.21 N m
    # (1.43x: the limit is what the test is about, so it stays the bound)
    assert 0.1 < moments[0.01] < 0.37
    assert moments[0.1] > limit


@pytest.mark.physical
def test_no_cutting_force_outside_the_wall():
    q = home_posture(MODEL)
    with SimDriver(MODEL, drill=True) as robot:  # exactly zero on both code paths
        robot.start(q)
        robot.add_wall(distance_m=0.6, height_m=1.0)
        state = _hold(robot, q, 20)
        assert not np.any(robot.cutting_force_n)
        # the hand and the drill hang on the sensor, nothing else
        compensated = compensated_wrenches(MODEL, state, {"right-arm": "drill"})
        assert np.abs(compensated["right-wrist"]).max() < 0.01


def test_snapshot_is_a_png_of_the_requested_size(sim, tmp_path):
    sim.start()
    path = sim.snapshot_png(tmp_path / "snap.png", 64, 48)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (64, 48)


def test_gui_without_a_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(DeviceError, match="no display"):
        SimDriver(MODEL, gui=True).start()


def test_bad_options_and_requests_are_refused(sim):
    with pytest.raises(ConfigError, match="unknown sim option"):
        SimDriver(MODEL, colour="red")
    with pytest.raises(ConfigError, match="does not divide"):
        SimDriver(MODEL, physics_dt_s=0.003)
    with pytest.raises(ConfigError):
        sim.add_wall(distance_m=-0.1, height_m=1.0)
    sim.start()
    with pytest.raises(ConfigError, match="unknown frame"):
        sim.frame_pose("nose")
    with pytest.raises(ConfigError):
        sim.push_torso([1.0, 0.0], 0.1)


@pytest.mark.physical
def test_a_jump_in_the_command_is_followed_at_the_motor_top_speed(sim):
    q = home_posture(MODEL)
    sim.start(q)
    elbow = MODEL.joint_names.index("REB")
    q[elbow] = -1.5
    speeds = [abs(_hold(sim, q, 1).dq_rad_s[elbow]) for _ in range(150)]
    # measured 3.0015 of 3.0 rad/s (40x inside) and 7e-7 rad off at the end, both code paths
    top = sim.options.max_speed_factor * MODEL.velocity_rad_s[elbow]
    assert max(speeds) == pytest.approx(top, rel=0.02)
    assert sim.read().q_rad[elbow] == pytest.approx(-1.5, abs=2e-3)



def _creep_under_a_side_push(anchor: bool) -> tuple[float, float]:
    """Both soles' largest horizontal drift in the world and the torso estimate's horizontal
    error (m) after 2 s of a 40 N sideways push on feet of friction 0.5 (far inside the cone)."""
    estimator = build_estimator(MODEL)
    with SimDriver(MODEL, friction=0.5, sole_friction_anchor=anchor) as robot:
        robot.start()
        state = _hold(robot, home_posture(MODEL), 20)
        estimator.reset(state)
        T_truth_estimate = state.truth.T_world_torso @ np.linalg.inv(
            estimator.store[T_WORLD_TORSO])
        soles = ("right_sole", "left_sole")
        before = [robot.frame_pose(name)[:3, 3] for name in soles]
        robot.push_torso([0.0, 40.0, 0.0], 2.0)
        for _ in range(int(2.0 / robot.period_s)):
            robot.send(home_posture(MODEL))
            state = robot.step()
            estimator.update(state)
        drift = max(float(np.linalg.norm((robot.frame_pose(name)[:3, 3] - p)[:2]))
                    for name, p in zip(soles, before, strict=True))
        error = float(np.linalg.norm(((T_truth_estimate @ estimator.store[T_WORLD_TORSO])
                                      - state.truth.T_world_torso)[:2, 3]))
    return drift, error


@pytest.mark.physical
def test_standing_soles_do_not_creep_so_the_torso_estimate_stays_on_the_body():
    # the estimate (estimation/base.py) assumes a loaded sole stays where it stood; the
    # solver's friction without anchors lets both feet walk away together (14 mm over a
    # perturbed robot's 60 s cut), which no onboard sensor sees. Measured (AVX-512 / portable):
    # anchored drift 0.031-0.032 mm (bound 1.9x); free drift 0.226-0.229 mm (1.5x). The
    # floating base's error with the attitude filter is its tilt under the push (the
    # accelerometer feels the push's acceleration; 0.07 deg at the torso's height), not the
    # creep: anchored 1.25 / 1.11 mm (bound 1.5x), free 0.77 / 0.77 mm (it was 0.0024 and
    # 0.209 mm with the simulator's ideal orientation)
    drift, error = _creep_under_a_side_push(anchor=True)
    assert drift < 0.06e-3 and error < 1.9e-3
    drift_free, _ = _creep_under_a_side_push(anchor=False)
    assert drift_free > 0.15e-3


def _solver_iterations_used(robot, steps):
    """The solver iterations each of ``steps`` physics steps of the standing robot ran
    (PyBullet's solver analytics, largest over the islands)."""
    p, cid = robot._p, robot._cid
    p.setPhysicsEngineParameter(reportSolverAnalytics=1, physicsClientId=cid)
    return [max(island["numIterationsUsed"] for island in p.stepSimulation(physicsClientId=cid))
            for _ in range(steps)]


@pytest.mark.physical
def test_the_residual_threshold_reaches_the_solver():
    default, early = SimDriver(MODEL), SimDriver(MODEL, solver_residual_threshold=1e-2)
    try:
        default.start()
        early.start()
        # the default threshold is never reached: every step runs all its iterations
        assert set(_solver_iterations_used(default, 40)) == {default.options.solver_iterations}
        # a loose one ends the steps of a quiet stance early (about 8 of 30 on the cut; 10.95
        # here on both code paths, 1.9x under the bound)
        assert np.mean(_solver_iterations_used(early, 40)) < 0.7 * early.options.solver_iterations
    finally:
        default.close()
        early.close()
