"""The manipulation experiments of the multi-layer paper (IV-C.2): the valve and door objects,
the hand's grip, the recognition errors as task parameters, and the runs with and without the
emergency stopper."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.drivers.sim import SimDriver, import_pybullet
from hubo_cli.drivers.sim_objects import MAX_COMPOUND_SHAPES, create_door, create_valve
from hubo_cli.errors import ConfigError, InputError
from hubo_cli.experiments.manipulation import (
    ManipulationSpec,
    run_manipulation,
    spec_from_parameters,
    start_posture,
)
from hubo_cli.hinged_objects import Door, Valve
from hubo_cli.state import GRAVITY_M_S2

PNG = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------- specs
def test_scene_objects_refuse_bad_values(rng):
    bad = [math.nan, math.inf, -math.inf, -1.0, 0.0, "1", None, True]
    for _ in range(40):
        value = bad[rng.integers(len(bad))]
        field = ["radius_m", "tube_radius_m", "mass_kg", "stem_m"][rng.integers(4)]
        with pytest.raises(ConfigError):
            Valve((0.3, -0.2, 1.0), **{field: value})
        field = ["width_m", "height_m", "thickness_m", "mass_kg", "max_open_rad"][rng.integers(5)]
        with pytest.raises(ConfigError):
            Door(0.3, 0.2, **{field: value})
    for centre in [(0.0, 0.0), (0.0, 0.0, math.nan), ("a", 0, 0), None, (1, 2, 3, 4)]:
        with pytest.raises(ConfigError):
            Valve(centre)
    with pytest.raises(ConfigError):
        Valve((0, 0, 1), radius_m=0.1, tube_radius_m=0.1)
    with pytest.raises(ConfigError):
        Door(0.3, 0.2, opens="sideways")
    for name in ("closer_nm", "closer_nm_per_rad", "closer_nm_s_per_rad", "friction_nm"):
        with pytest.raises(ConfigError):
            Door(0.3, 0.2, **{name: -0.1})


def test_door_closer_pushes_toward_closed_only():
    for opens, sign in (("away", 1.0), ("toward", -1.0)):
        door = Door(0.3, 0.2, opens=opens)
        assert door.closer_torque_nm(0.0, 0.0) == 0.0
        assert door.closer_torque_nm(-sign * 0.1, 0.0) == 0.0  # against the stop: nothing
        open_torque = door.closer_torque_nm(sign * 0.3, 0.0)
        assert open_torque * sign < 0  # back toward closed
        assert abs(open_torque) == pytest.approx(door.closer_nm + door.closer_nm_per_rad * 0.3)
        assert door.limits_rad[0] <= sign * 0.3 <= door.limits_rad[1]


def test_parameters_from_task_files_are_checked(rng):
    spec = spec_from_parameters("turn-valve", {"seen_offset_mm": [131, 0, 33]})
    assert spec.seen_offset_m == pytest.approx((0.131, 0.0, 0.033))
    assert spec.case == "seen-x+131mm-z+33mm" and spec.misrecognised
    assert spec_from_parameters("push-door", {"door_opens": "toward"}).case == "opens-toward"
    assert spec_from_parameters("push-door", {}).case == "nominal"
    assert spec_from_parameters("push-door", {"impedance": True}).impedance
    assert not spec_from_parameters("push-door", {}).impedance
    for value in (1, "yes", None, 0.0):
        with pytest.raises(InputError, match="impedance"):
            spec_from_parameters("turn-valve", {"impedance": value})
    hostile = [[1, 2], [1, 2, 3, 4], "abc", 3.0, [math.nan, 0, 0], [math.inf, 0, 0],
               [True, 0, 0], ["1", 0, 0], [1e9, 0, 0], [0, -501, 0], None, {}]
    for value in hostile:
        with pytest.raises(InputError):
            spec_from_parameters("turn-valve", {"seen_offset_mm": value})
    for _ in range(30):  # random out-of-range or non-numbers for the angles
        value = [math.nan, -1.0, 0.0, 97.0, 1e6, "x", True, [1]][rng.integers(8)]
        with pytest.raises(InputError):
            spec_from_parameters("turn-valve", {"turn_deg": value})
        with pytest.raises(InputError):
            spec_from_parameters("push-door", {"door_deg": value if value != 97.0 else 31})
    for value in ("sideways", 1.0, "", "AWAY"):
        with pytest.raises(InputError):
            spec_from_parameters("push-door", {"door_opens": value})
    with pytest.raises(InputError):
        ManipulationSpec("open-window")


# ---------------------------------------------------------------------------- physics
@pytest.fixture
def bullet():
    p = import_pybullet()
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -GRAVITY_M_S2, physicsClientId=cid)
    p.setTimeStep(0.0025, physicsClientId=cid)
    yield p, cid
    p.disconnect(physicsClientId=cid)


def test_valve_holds_below_its_friction_and_turns_above(bullet):
    p, cid = bullet
    valve = create_valve(p, cid, Valve((0.0, 0.0, 1.0), friction_nm=3.0))
    assert len(p.getCollisionShapeData(valve.body_id, 0, physicsClientId=cid)) \
        <= MAX_COMPOUND_SHAPES

    def turn(torque_nm: float, steps: int) -> float:
        start = valve.angle_rad(p, cid)
        for _ in range(steps):
            p.applyExternalTorque(valve.body_id, 0, [torque_nm, 0, 0], p.WORLD_FRAME,
                                  physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
        return math.degrees(valve.angle_rad(p, cid) - start)

    # 1 s at 2/3 of the friction: creeps 1.1 deg (PyBullet's velocity motor is not rigid);
    # at twice the friction it spins (tens of degrees within 0.5 s)
    assert abs(turn(2.0, 400)) < 5.0
    assert turn(6.0, 200) > 20.0
    # probes on the rim's every twelfth touch it (the whole ring is built: a 24-segment rim
    # lost its left half to PyBullet's 16-shape limit)
    fresh = create_valve(p, cid, Valve((0.0, 1.0, 1.0)))
    probe = p.createCollisionShape(p.GEOM_SPHERE, radius=0.005, physicsClientId=cid)
    for k in range(12):
        a = 2 * math.pi * (k + 0.5) / 12
        at = [0.0, 1.0 - 0.15 * math.sin(a), 1.0 + 0.15 * math.cos(a)]
        ball = p.createMultiBody(0.0, probe, -1, at, physicsClientId=cid)
        assert p.getClosestPoints(ball, fresh.body_id, 0.0, linkIndexB=0,
                                  physicsClientId=cid), k
        p.removeBody(ball, physicsClientId=cid)


def test_door_closes_and_stands_against_its_stop(bullet):
    p, cid = bullet
    away = create_door(p, cid, Door(1.0, 0.5, opens="away"))
    toward = create_door(p, cid, Door(1.0, -1.5, opens="toward"))
    p.resetJointState(away.body_id, 0, 0.5, physicsClientId=cid)
    for _ in range(800):  # 2 s
        for body in (away, toward):
            body.apply_closer(p, cid)
        p.applyExternalTorque(toward.body_id, 0, [0, 0, 30.0], p.WORLD_FRAME,
                              physicsClientId=cid)  # pushed away from the robot: the stop
        p.stepSimulation(physicsClientId=cid)
    # the closer shut the open door (0.5 rad -> 0 within about 0.4 s); the pushed pull door
    # stayed at its stop (0.0 deg measured)
    assert abs(away.angle_rad(p, cid)) < math.radians(1.0)
    assert abs(toward.angle_rad(p, cid)) < math.radians(1.0)


@pytest.mark.physical
def test_grip_pulls_the_hand_the_way_the_valve_pulls(model):
    with SimDriver(model) as sim:
        sim.start(start_posture(model))
        hand = sim.frame_pose("right_hand")[:3, 3]
        # a frictionless valve whose rim runs 6 cm below the hand point: grippable
        sim.add_valve(Valve((float(hand[0]), float(hand[1]), float(hand[2]) - 0.18),
                            radius_m=0.12, friction_nm=0.0))
        assert sim.grasp("right_hand", "valve", 0.05) > 0.05 and not sim.holding("right_hand")
        assert sim.grasp("right_hand", "valve", 0.07) == pytest.approx(0.06, abs=1e-3)
        assert sim.holding("right_hand")
        p, cid = sim._p, sim._cid
        body = sim._objects["valve"].body_id
        grip = next(iter(sim._grips.values()))

        def grip_force_n(torque_nm: float) -> np.ndarray:
            """The grip's mean force on the hand (world, N) over the last 50 of 100 periods
            with the wheel driven by ``torque_nm``. (Hubo's three-axis wrist sensor cannot
            see it: the grip holds the hand at the sensor's axis, across the forearm.)"""
            forces = []
            for _ in range(100):
                original = sim._apply_external_forces

                def push(t_s, original=original):
                    original(t_s)
                    p.applyExternalTorque(body, 0, [torque_nm, 0, 0], p.WORLD_FRAME,
                                          physicsClientId=cid)
                sim._apply_external_forces = push
                sim.step()
                sim._apply_external_forces = original
                forces.append(grip.force_on_hand_n)
            return np.mean(forces[50:], axis=0)

        still, force = grip_force_n(0.0), grip_force_n(3.0)  # clockwise: -y at the top
        # the rim pulls the hand toward -y by 3 N m / 0.18 m = 16.7 N (x and z small)
        assert force[1] - still[1] == pytest.approx(-16.7, abs=3.0)
        assert abs(force[0] - still[0]) < 3.0 and abs(force[2] - still[2]) < 3.0
        assert sim.scene()["held"] == {"right_hand": "valve"}
        assert sim.scene()["objects"]["valve"]["kind"] == "valve"
        sim.release("right_hand")
        assert not sim.holding("right_hand")


# ---------------------------------------------------------------------------- the runs
@pytest.mark.slow
@pytest.mark.physical
def test_valve_turned_on_the_nominal_scene(model, tmp_path):
    s = run_manipulation(model, ManipulationSpec("turn-valve"), out=tmp_path).summary
    # turned 93.19 deg (planned 95) with no stop and no tip, the same on the portable code
    # path; 93.14-93.76 deg on perturbed robots (seeds 1-3): the bound is 5x that spread away
    assert s["grasped_at_s"] is not None and s["t_emergency_s"] is None
    assert s["object_angle_deg"] >= 90.0
    assert not s["fell"] and not s["tipped"] and not s["overloaded"]
    assert (tmp_path / "manipulation.png").read_bytes()[:8] == PNG
    scene = json.loads((tmp_path / "log.json").read_text())["metadata"]["scene"]
    assert scene["objects"]["valve"]["angle_deg"] == pytest.approx(s["object_angle_deg"],
                                                                   abs=0.01)


@pytest.mark.slow
@pytest.mark.physical
def test_door_pushed_open_on_the_nominal_scene(model, tmp_path):
    s = run_manipulation(model, ManipulationSpec("push-door"), out=tmp_path).summary
    # pushed 25.53 deg open (planned 24) on both code paths, 25.5-25.9 on perturbed robots,
    # with 15-19 N at the hand against the closer (42 N at most along the forearm)
    assert s["object_angle_deg"] >= 20.0 and s["t_emergency_s"] is None
    assert not s["fell"] and not s["tipped"]
    assert 5.0 < s["max_axial_force_n"] < 100.0 and s["impedance"] == "off"


@pytest.mark.slow
@pytest.mark.physical
def test_door_that_opens_toward_the_robot_with_and_without_the_stop(model, tmp_path):
    spec = ManipulationSpec("push-door", door_opens="toward")
    stopped = run_manipulation(model, spec, out=tmp_path / "on").summary
    free = run_manipulation(model, spec, estop=False, out=tmp_path / "off").summary
    # the same on both code paths: with the stop flagged at 2.485 s, tilt 2.59 deg, sole lift
    # 9.9 mm (1.45 deg, 5.5 mm since the revert brakes at the emergency limits, this code path
    # only); without it the robot rocks onto its heels (sole lift 31.3 mm against the 20 mm
    # criterion, tilt 8.18 deg) and stays propped on the door; CP error 94.8 against 33.2 mm
    # (23.4 mm now)
    assert stopped["t_emergency_s"] is not None and stopped["emergency_sources"] == [
        "capture-point"]
    assert not stopped["fell"] and not stopped["tipped"] and stopped["max_tilt_deg"] < 5.0
    assert free["t_emergency_s"] is None and free["tipped"]
    assert free["max_cp_error_mm"] > 1.5 * stopped["max_cp_error_mm"]
    # without the stop it does not fall: once the plan's 142 mm push past the leaf is used up
    # it stands on its heels, its CoM 28-34 mm inside the soles (nominal, seeds 3-8), tilted
    # 7.85-8.33 deg at the end (nominal, seeds 1-8), the wrist beyond its 1.21 N m for
    # 1.63-1.77 s (the bound 0.25 s); with the stop it ends at 0.26-0.49 deg (nominal, seeds
    # 1-3, both code paths)
    assert not free["fell"] and free["min_com_inside_mm"] > 10.0
    assert free["end_tilt_deg"] > 5.0 and stopped["end_tilt_deg"] < 1.5
    assert free["wrist_overloaded"]
    assert stopped["object_angle_deg"] == pytest.approx(0.0, abs=0.5)  # it never opened
    for run in ("on", "off"):
        assert (tmp_path / run / "manipulation.png").read_bytes()[:8] == PNG


def test_cli_refuses_bad_recognition_errors(tmp_path):
    out = tmp_path / "run"
    for args in (["turn-valve", "--set", "seen_offset_mm=[1,2]"],
                 ["turn-valve", "--set", "seen_offset_mm=[nan,0,0]"],
                 ["push-door", "--set", "door_opens=sideways"],
                 ["turn-valve", "--set", "estop=false"],
                 ["turn-valve", "--set", "door_opens=away"],
                 ["push-door", "--driver", "ideal"],
                 ["turn-valve", "--set", "seen_offset_mm=[300,0,0]"]):  # inside the robot
        result = CliRunner().invoke(main, ["task", *args, "--out", str(out)])
        assert result.exit_code == 2, (args, result.output)
        assert "Traceback" not in result.output and "error:" in result.output
        assert not out.exists()
    listed = CliRunner().invoke(main, ["task", "list"])
    assert "turn-valve" in listed.output and "push-door" in listed.output


@pytest.mark.slow
@pytest.mark.physical
def test_valve_seen_195_mm_to_the_left_with_and_without_the_stop(model, tmp_path):
    """Seen 195 mm left of where it is (the paper's Fig. 11 b-1): the turning hand meets the
    real rim from outside and the contact lifts the right sole
    before the capture point flags (0.14 s later). The stop's revert brakes the arm to rest
    at the emergency limits before it goes back. Without the stop the robot tips onto its left
    foot, and whether it falls depends on the robot: the nominal one stands there (8.2 deg),
    perturbed robots 2, 3, 4 and 8 of seeds 1-8 turn on the left foot (yaw 17-18 deg at
    10 deg of tilt) and fall backward, 5 and 6 are still tipping when the plan ends (and fall
    at 8.68 and 8.43 s if the hold is 3 s longer). Seed 4 (the lowest foot friction, 0.46)
    fell to 90 deg at 7.63 s (7.65 s on the portable code path); with the stop 1.53 deg and
    7.5-7.8 mm of sole lift (both paths), and 1.09-1.53 deg, 7.1-7.8 mm on the nominal and
    seeds 1-8 (the bounds 3 deg, 2x, and the 20 mm tip criterion, 2.6x)."""
    spec = ManipulationSpec("turn-valve", seen_offset_m=(0.0, 0.195, 0.0))
    stopped = run_manipulation(model, spec, out=tmp_path / "on", perturb_seed=4).summary
    free = run_manipulation(model, spec, estop=False, out=tmp_path / "off",
                            perturb_seed=4).summary
    assert stopped["emergency_sources"] == ["capture-point"]
    assert not stopped["fell"] and not stopped["tipped"] and stopped["max_tilt_deg"] < 3.0
    assert free["t_emergency_s"] is None and free["fell"] and free["min_com_inside_mm"] < 0.0
    for run in ("on", "off"):
        assert (tmp_path / run / "manipulation.png").read_bytes()[:8] == PNG


@pytest.mark.slow
@pytest.mark.physical
def test_valve_seen_131_mm_too_far_with_and_without_the_stop(model, tmp_path):
    """Seen 131 mm too far and 33 mm too high (the paper's Fig. 11 a-1): the hand reaches over
    the real wheel into its panel. With the stop 1.4-1.6 deg and 5-8 mm of sole lift (nominal,
    seeds 1-3); without it 24.8-25.8 mm (nominal, seeds 1-8; the 20 mm tip criterion is
    4.8 mm below, 4.8x the 1.0 mm spread) and 6.2-6.7 deg, but no fall: the plan's 131 mm
    past the wheel is used up with the CoM still 44-51 mm inside the soles (nominal, seeds
    3-8). The wrist sensor's bending moment is beyond the robot's 1.21 N m for 1.28-2.10 s
    without the stop (and 1.0-1.2 s with it: the capture point flags only once the body
    leans). Both code paths."""
    spec = ManipulationSpec("turn-valve", seen_offset_m=(0.131, 0.0, 0.033))
    stopped = run_manipulation(model, spec, out=tmp_path / "on").summary
    free = run_manipulation(model, spec, estop=False, out=tmp_path / "off").summary
    assert stopped["emergency_sources"] == ["capture-point"]
    assert not stopped["fell"] and not stopped["tipped"] and stopped["max_tilt_deg"] < 3.0
    assert free["t_emergency_s"] is None and free["tipped"] and not free["fell"]
    assert free["min_com_inside_mm"] > 20.0 and free["wrist_overloaded"]
