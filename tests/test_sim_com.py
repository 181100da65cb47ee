"""The simulator's bodies are the model's: the physics' centre of mass equals pinocchio's on the
URDF (the capture-point monitor's) in random postures, with and without the drill."""

import numpy as np
import pinocchio as pin
import pytest

from hubo_cli.drivers.sim import SimDriver
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture

pytestmark = pytest.mark.physical


@pytest.mark.parametrize("drill", [False, True])
def test_physics_com_equals_the_model_com_in_random_postures(model, rng, drill):
    urdf = model.urdf_path()
    if drill:
        urdf = urdf.with_name(urdf.stem + "-drill.urdf")
    robot = load_pin_robot(model, floating=True, urdf_path=urdf)
    data = robot.model.createData()
    home = home_posture(model)
    worst = 0.0
    with SimDriver(model, drill=drill, settle_s=0.01) as sim:
        for _ in range(4):
            q = np.clip(home + rng.normal(0.0, 0.4, home.size), model.lower_rad, model.upper_rad)
            state = sim.start(q)
            q_pin = robot.configuration(state.q_rad, state.truth.T_world_torso)
            com_model = pin.centerOfMass(robot.model, data, q_pin, False)
            worst = max(worst, float(np.linalg.norm(sim.com_world_m() - com_model)))
    assert worst < 0.001  # measured 5e-16 m on both code paths (AVX-512 / portable)


def test_a_foot_is_in_contact_while_its_low_passed_load_exceeds_25_n(model):
    """hrpsys's contact decision: F_z low-passed at 5 Hz above 25 N. A foot lifted off the floor
    at once (from 170 N to nothing) still counts for 2.1 time constants of the filter (66 ms),
    so one period's flicker of a rocking sole does not drop it from the support polygon."""
    home = home_posture(model)
    lifted = home.copy()
    for joint, delta in (("LHP", -0.3), ("LKN", 0.6), ("LAP", -0.3)):
        lifted[model.joint_names.index(joint)] += delta
    dt = model.control_period_s
    with SimDriver(model) as sim:
        state = sim.start(home)
        assert state.truth.feet_contact == (True, True)
        assert min(state.ft["right-ankle"][2], state.ft["left-ankle"][2]) > 100.0
        fz, touching = [], []
        for _ in range(40):  # 0.2 s: the foot comes up before the robot tips far
            sim.send(lifted)
            state = sim.step()
            fz.append(state.ft["left-ankle"][2])
            touching.append(state.truth.feet_contact[1])
    fz, touching = np.array(fz), np.array(touching)
    unloaded = int(np.argmax(fz < 1.0))  # first period without load
    assert fz[unloaded:].max() < 1.0 and touching[unloaded] and not touching[-1]
    lost = int(np.argmax(~touching))
    # 14 periods (0.07 s) on both code paths (AVX-512 / portable): the filter's own timing,
    # 4 periods inside either bound; the loads before the lift 184 N (1.8x the 100)
    assert 0.05 <= (lost - unloaded) * dt <= 0.09
