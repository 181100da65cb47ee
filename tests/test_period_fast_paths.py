"""The per-period shortcuts give what the plain code gives: the log's compiled torso and hand
poses against numpy's forward kinematics, the default balancer's compiled per-leg step against
the same filter written in Python, and the run's garbage-collector freeze is undone."""

from __future__ import annotations

import gc
import math

import numpy as np

from hubo_cli.control.balance import FEET, _follow_offsets
from hubo_cli.control.log import PeriodLog, load_log, pose_columns, rotation_from_rpy
from hubo_cli.control.settled import settled_objects
from hubo_cli.geometry import rpy_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState, Truth


def test_log_hand_poses_match_numpy_kinematics(tmp_path):
    model = load_model()
    rng = np.random.default_rng(3)
    q = home_posture(model) + rng.uniform(-0.3, 0.3, len(model.joint_names))
    T_world_torso = np.eye(4)
    T_world_torso[:3, :3] = rpy_to_matrix(0.02, -0.05, 0.4)
    T_world_torso[:3, 3] = (0.1, -0.2, 0.9)
    state = RobotState(0.0, q, np.zeros(len(q)),
                       truth=Truth(T_world_torso, (True, True), np.array([1.0, 0.0, 0.0, 0.0])))
    log = PeriodLog(tmp_path / "log.csv", model.joint_names, (), model=model)
    log.write(0, 0.0, 0, 0.0, 0.0, set(), q, q, q, None, state=state)
    log.close()
    data = load_log(tmp_path)
    for frame, arm in (("torso", None), ("right_hand", "right-arm"), ("left_hand", "left-arm")):
        expected = T_world_torso if arm is None else T_world_torso @ Limb(model, arm, "hand").fk(
            q[model.limb_slice(arm)])
        x, y, z, roll, pitch, yaw = (float(data[c][0]) for c in pose_columns(frame))
        assert np.allclose((x, y, z), expected[:3, 3], atol=1e-9), frame
        assert np.allclose(rotation_from_rpy(roll, pitch, yaw), expected[:3, :3],
                           atol=1e-9), frame


def _python_step(q, ankles, signs, moments, mean, common, both, differential, offsets, rate,
                 lower, upper, limit, k_d, leak, max_rate, max_step, smoothing_s, dt):
    """The balancer's per-leg filter as it was written in Python floats."""
    for leg in range(2):
        for k in range(2):
            drive = k_d * (moments[leg][k] - mean[k]) if both else 0.0
            differential[leg][k] += (drive - differential[leg][k] / leak) * dt
            wanted = min(max(signs[leg][k] * (common[k] + differential[leg][k]), -limit), limit)
            rate_wanted = min(max((wanted - offsets[leg][k]) / smoothing_s, -max_rate),
                              max_rate)
            rate[leg][k] += min(max(rate_wanted - rate[leg][k], -max_step), max_step)
            offsets[leg][k] += rate[leg][k] * dt
            i = ankles[leg][k]
            if math.isfinite(q[i]):
                target = min(max(q[i] + offsets[leg][k], lower[i]), upper[i])
                offsets[leg][k] = target - q[i]
                q[i] = target


def test_compiled_balancer_step_matches_python():
    assert len(FEET) == 2
    rng = np.random.default_rng(7)
    ankles = np.array([[4, 5], [10, 11]])
    signs = np.array([[1.0, -1.0], [1.0, 1.0]])
    lower, upper = -np.ones(12) * 0.4, np.ones(12) * 0.4
    q = rng.uniform(-0.35, 0.35, 12)
    q[11] = math.nan  # no command: the offset still runs, the joint stays NaN
    state = np.zeros((3, 2, 2))
    py_q, py_state = q.tolist(), state.tolist()
    settings = (0.15, 5e-6, 2.0, 0.1, 0.3 * 0.005, 0.05, 0.005)
    for period in range(400):
        moments = rng.normal(0.0, 30.0, (2, 2))
        mean = moments.mean(axis=0)
        common = rng.normal(0.0, 0.05, 2)
        both = period % 50 != 0
        _follow_offsets(q, ankles, signs, *moments.ravel(), *mean, *common, both, *state,
                        lower, upper, *settings)
        _python_step(py_q, ankles.tolist(), signs.tolist(), moments.tolist(), mean.tolist(),
                     common.tolist(), both, *py_state, lower.tolist(), upper.tolist(),
                     *settings)
    assert np.allclose(q, py_q, rtol=0.0, atol=1e-12, equal_nan=True)
    assert math.isnan(q[11])
    assert np.allclose(state, py_state, rtol=0.0, atol=1e-12)
    assert np.abs(state[1]).max() > 1e-3  # the offsets moved: the comparison means something


def test_settled_objects_undoes_its_freeze():
    before = gc.get_freeze_count()
    with settled_objects():
        assert gc.get_freeze_count() > before
        with settled_objects():  # nested: frozen once
            inner = gc.get_freeze_count()
        assert gc.get_freeze_count() == inner
    assert gc.get_freeze_count() == before


def test_the_control_loop_runs_with_the_settled_objects_frozen():
    """A full collection scanning the process's settled objects stalled a walk's period for
    38-43 ms (eight periods without a command; round 23): every control loop now runs with
    the objects that existed before it frozen, and gives them back to the collector after."""
    from hubo_cli.control.loop import ControlLoop
    from hubo_cli.drivers.ideal import IdealDriver

    model = load_model()
    frozen = []

    def target(t_s, state):
        frozen.append(gc.get_freeze_count())
        return None, {}

    before = gc.get_freeze_count()
    loop = ControlLoop(IdealDriver(model), [], target)
    loop.driver.start()
    assert loop.run(0.05).ended == "finished"
    assert frozen and min(frozen) > before
    assert gc.get_freeze_count() == before
