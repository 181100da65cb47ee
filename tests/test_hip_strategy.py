"""The hip strategy: the trunk bows toward a fall once the capture point nears the soles' toe or
heel edge, returns upright afterwards, and lets the standing robot hold 0.2 s torso pushes of
90 N forward and backward in place."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.control.hip_strategy import (
    BOW_JOINTS_RAD,
    MAX_BOW_RAD,
    RETURN_S,
    ROCK_GAIN,
    START_M,
    HipStrategy,
)
from hubo_cli.control.keys import SUPPORT_BOX_WORLD
from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import CAPTURE_POINT_WORLD, T_WORLD_SOLES
from hubo_cli.experiments.standing import BRACE_LIFT_M, posture_of, stand, standing_posture
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

DT = 0.005
BOX_X_M = (-0.06, 0.10)  # the shrunk support box's back and front edges (the standing robot)


def _soles(pitch_rad: float) -> np.ndarray:
    """Both soles pitched by ``pitch_rad`` (> 0: tipped onto their toes), yawed 0.3 rad."""
    c, s, cy, sy = np.cos(pitch_rad), np.sin(pitch_rad), np.cos(0.3), np.sin(0.3)
    T = np.eye(4)
    T[:3, :3] = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array(
        [[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([T, T])


def _run(module: HipStrategy, q_rad: np.ndarray, cp_x_m: float, periods: int,
         soles_pitch_rad: float = 0.0) -> np.ndarray:
    state = RobotState(0.0, q_rad, np.zeros(len(q_rad)))
    out = q_rad
    store = Store()  # what the estimate and the capture-point monitor write
    store[CAPTURE_POINT_WORLD] = np.array([cp_x_m, 0.0])
    store[SUPPORT_BOX_WORLD] = np.array([BOX_X_M[0], BOX_X_M[1], -0.15, 0.15])
    store[T_WORLD_SOLES] = _soles(soles_pitch_rad)
    for k in range(periods):
        out = module.update(q_rad, state, Cycle(k * DT, DT, store=store))
    return out


def _joint(model, name: str) -> int:
    return model.joint_names.index(name)


def test_the_trunk_bows_toward_the_edge_the_capture_point_nears(model):
    q = home_posture(model)
    hip = HipStrategy(model, DT)
    # well inside the soles (a standing robot, a cut): nothing moves
    assert np.array_equal(_run(hip, q, 0.02, 200), q) and hip.bow_rad == 0.0
    # past the front band: the hips flex (trunk forward), the ankles follow, up to the bound
    out = _run(hip, q, BOX_X_M[1], 100)
    assert hip.bow_rad == pytest.approx(MAX_BOW_RAD)
    hp = _joint(model, "RHP")
    assert out[hp] - q[hp] == pytest.approx(BOW_JOINTS_RAD["HP"] * MAX_BOW_RAD, abs=1e-9)
    assert out[_joint(model, "LAP")] > q[_joint(model, "LAP")]
    # the other way for the heels
    back = HipStrategy(model, DT)
    _run(back, q, BOX_X_M[0] + START_M / 4, 400)
    assert back.bow_rad == pytest.approx(-MAX_BOW_RAD)


def test_the_bow_returns_upright_and_damps_the_rocking(model):
    q = home_posture(model)
    hip, still = HipStrategy(model, DT), HipStrategy(model, DT, rock_gain=0.0)
    for module in (hip, still):
        _run(module, q, BOX_X_M[1], 100)
        # the capture point rocks back toward the heels, the soles flat: the bow returns, the
        # capture point does not turn it into a backward one
        _run(module, q, BOX_X_M[0], 60)
        assert 0.0 < module.bow_rad < MAX_BOW_RAD
    assert hip.bow_rad == still.bow_rad
    # the body tips onto its heels (soles pitched 3 deg back) for 0.2 s: the trunk turns back
    # faster than the return alone, by the soles' pitch times ROCK_GAIN (the return's
    # exponential decay acting on the difference too)
    rock = ROCK_GAIN * np.radians(3.0) * RETURN_S * (1.0 - np.exp(-40 * DT / RETURN_S))
    for module in (hip, still):
        _run(module, q, BOX_X_M[0], 40, soles_pitch_rad=np.radians(-3.0))
    assert still.bow_rad - hip.bow_rad == pytest.approx(rock, rel=0.01)
    # ... and onto its toes: toward the toes
    heels = hip.bow_rad
    _run(hip, q, 0.02, 40, soles_pitch_rad=np.radians(3.0))
    assert hip.bow_rad > heels
    out = _run(hip, q, 0.02, 1200)  # 6 s inside the soles, the soles flat: upright again
    assert hip.bow_rad == 0.0 and np.array_equal(out, q)
    assert hip.max_abs_bow_rad == pytest.approx(MAX_BOW_RAD)
    _run(hip, q, BOX_X_M[1], 100)  # a new push bows again
    assert hip.bow_rad == pytest.approx(MAX_BOW_RAD)


def test_a_tilted_floor_holds_no_bow(model):
    """On a floor tilted 0.5 deg (the soles' pitch standing, learnt before the push) the
    bow returns upright as on a level one: the rocking is measured from that pitch."""
    q = home_posture(model)
    hip = HipStrategy(model, DT)
    tilt = np.radians(0.5)
    _run(hip, q, 0.02, 400, soles_pitch_rad=tilt)
    _run(hip, q, BOX_X_M[1], 100, soles_pitch_rad=tilt)
    assert hip.bow_rad == pytest.approx(MAX_BOW_RAD)
    out = _run(hip, q, 0.02, 1200, soles_pitch_rad=tilt)
    assert hip.bow_rad == 0.0 and np.array_equal(out, q)


def test_the_bow_stays_inside_the_joint_limits(model):
    q = home_posture(model)
    hp = _joint(model, "RHP")
    q[hp] = model.lower_rad[hp] + 0.05  # hips already flexed almost to their limit
    out = _run(HipStrategy(model, DT), q, BOX_X_M[1], 100)
    assert np.all(out >= model.lower_rad) and np.all(out <= model.upper_rad)


def test_bad_settings_are_refused(model):
    with pytest.raises(ConfigError):
        HipStrategy(model, DT, max_bow_rad=0.0)
    with pytest.raises(ConfigError):
        HipStrategy(model, DT, start_m=-0.01)
    for rock_gain in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ConfigError):
            HipStrategy(model, DT, rock_gain=rock_gain)


def test_it_is_in_the_standing_pipeline_only_when_asked(model):
    assert "hip" not in SafetyProfile().order()  # tasks, teleop and walks run without it
    order = SafetyProfile(hip_strategy=True).order()
    assert order.index("balance") < order.index("hip") < order.index("limiter")


def _com_and_trunk_in_the_sole_frame(model, q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The whole-body CoM (m) and the torso's rotation, both in the right sole's frame
    (pinocchio on the URDF: independent of the module's own numbers)."""
    import pinocchio as pin

    from hubo_cli.pin_robot import load_pin_robot

    robot = load_pin_robot(model, floating=True)
    data = robot.model.createData()
    q = robot.configuration(q_rad, None)
    com = pin.centerOfMass(robot.model, data, q, False)
    sole = pin.updateFramePlacement(robot.model, data, robot.frame_id("right_sole"))
    return sole.rotation.T @ (com - sole.translation), sole.rotation.T


def test_the_standing_posture_puts_the_com_over_the_soles_centre(model):
    def com_ahead_of_soles_centre_m(q_rad):
        return float(_com_and_trunk_in_the_sole_frame(model, q_rad)[0][0]) - model.feet.forward_m

    assert com_ahead_of_soles_centre_m(home_posture(model)) > 0.003  # 4 mm toward the toes
    assert abs(com_ahead_of_soles_centre_m(standing_posture(model))) < 0.001
    # braced: centred too, the CoM lower (0.628 -> 0.556 m above the soles: 72 of the legs'
    # 100 mm crouch, their own mass sinking less), the legs inside their limits
    braced = posture_of(model, "braced")
    assert abs(com_ahead_of_soles_centre_m(braced)) < 0.001
    drop = (_com_and_trunk_in_the_sole_frame(model, standing_posture(model))[0][2]
            - _com_and_trunk_in_the_sole_frame(model, braced)[0][2])
    assert 0.5 * -BRACE_LIFT_M < drop < -BRACE_LIFT_M
    assert np.all(braced >= model.lower_rad) and np.all(braced <= model.upper_rad)


def test_the_bow_pitches_the_trunk_and_keeps_the_com_over_the_feet(model):
    """BOW_JOINTS_RAD against pinocchio, in the standing posture they were solved in: a 0.2
    rad bow pitches the torso 0.2 rad relative to the soles, moves the whole-body CoM less than
    1 mm along x (0.4 mm) and, the offsets being solved to first order, less than 5 mm in
    height (3.1 mm). (In the braced posture the same bow moves it 3.5 mm toward the bow; see
    BOW_JOINTS_RAD.)"""
    q = standing_posture(model)
    bowed = q.copy()
    for joint, per_rad in BOW_JOINTS_RAD.items():
        for side in "RL":
            bowed[_joint(model, side + joint)] += per_rad * 0.2
    com, R_sole_torso = _com_and_trunk_in_the_sole_frame(model, q)
    com_bowed, R_sole_torso_bowed = _com_and_trunk_in_the_sole_frame(model, bowed)
    assert abs(com_bowed[0] - com[0]) < 0.001 and abs(com_bowed[2] - com[2]) < 0.005
    pitch = R_sole_torso.T @ R_sole_torso_bowed  # the torso's rotation in its former frame
    assert np.degrees(np.arccos(np.clip((np.trace(pitch) - 1) / 2, -1, 1))) == pytest.approx(
        np.degrees(0.2), abs=0.3)


@pytest.mark.physical
@pytest.mark.parametrize("direction", [(1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)])
def test_a_90_n_push_is_held_in_place_with_the_hips(model, direction, tmp_path):
    # 0.2 s on the torso at 1 s, the robot braced (BRACE_LIFT_M) with the hips
    # 8 s: past the 3.2 s at which an ankle-only 85 N push toppled, and back near upright
    result = stand(model, duration_s=8.0, push_n=90.0, push_direction=direction, out=tmp_path)
    # measured (forward / backward, the 2-core development machine; the code path without
    # AVX-512 not measured): peak tilt 20.5 / 19.2 deg (1.9x the 10; bow 0.27 / 0.25 rad),
    # final tilt 0.00 / 0.11 deg (36x), foot shift 0.5 / 0.4 mm as the soles rock on their
    # edges (18x; a step or a slide moves a foot centimetres)
    assert not result.fell
    assert result.max_tilt_deg > 10.0  # the trunk did bow
    assert result.final_tilt_deg < 4.0  # standing again (bow 0)
    assert result.max_foot_shift_mm < 9.0  # no step, no slide
    # the heel-to-toe rocking the bow's return damps: the largest tilt from 3 s after the push
    # on (the issue: within 2 deg), measured 1.08 / 0.92 deg forward / backward braced (1.9x /
    # 2.2x), 3.5-4.2 / 3.4-3.6 unbraced and 8.3 / 7.1 with the return alone
    late = result.times_s >= 1.0 + 3.0
    assert result.tilts_deg[late].max() < 2.0


@pytest.mark.physical
@pytest.mark.parametrize(("seed", "direction"), [(3, (1.0, 0.0, 0.0)), (8, (-1.0, 0.0, 0.0))])
def test_a_90_n_push_on_a_perturbed_robot_is_held_braced(model, seed, direction, tmp_path):
    # perturbation seeds 3 and 8 have the lightest torsos of seeds 1-10 (0.92 and 0.97 x): the
    # push's 18 N s throws them hardest. Unbraced they fell at 90 N (forward / backward; seed 3
    # at 88 N too); braced seed 3 holds 92 N forward (95 falls), seed 8 95 N backward (100
    # falls): 90 N leaves 2 and 5 N. 3 s: the unbraced falls passed 30 deg by 2.1 s
    result = stand(model, duration_s=3.0, push_n=90.0, push_direction=direction,
                   perturb_seed=seed, out=tmp_path)
    # measured (seed 3 forward / seed 8 backward): peak tilt 24.3 / 22.8 deg, foot shift 2.0 /
    # 2.9 mm (bound 9 mm = 3.1x: no step, no slide)
    assert not result.fell
    assert result.max_tilt_deg > 10.0  # the push did tip it and the trunk bowed
    assert result.max_foot_shift_mm < 9.0


def test_the_soles_pitch_is_numpys_on_hostile_poses():
    """The soles' mean pitch in floats equals the numpy formula it replaced (to 1e-12) on
    random rotations, far tilts, and NaN or infinite entries (then 0)."""
    rng = np.random.default_rng(33)
    for k in range(300):
        soles = rng.normal(size=(2, 4, 4))
        if k % 10 == 0:
            soles[rng.integers(2), rng.integers(3), 0] = rng.choice([np.nan, np.inf, -np.inf])
        store = Store()
        store[T_WORLD_SOLES] = soles
        expected = float(np.mean(np.arctan2(-soles[:, 2, 0], np.hypot(soles[:, 0, 0],
                                                                       soles[:, 1, 0]))))
        expected = expected if np.isfinite(expected) else 0.0
        got = HipStrategy._soles_pitch_rad(Cycle(0.0, DT, store=store))
        assert abs(got - expected) <= 1e-12, (soles, got, expected)
