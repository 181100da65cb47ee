"""The drill's and the feet's dimensions have one source (the robot TOML, read by the model)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from robot_file_support import robot_file_with

from hubo_cli.control.collision import SelfCollisionChecker
from hubo_cli.errors import ConfigError
from hubo_cli.model import load_model

MODEL = load_model("as-built")


def test_the_urdf_feet_are_the_model_feet():
    root = ET.parse(MODEL.urdf_path()).getroot()
    for link in ("RAR_link", "LAR_link"):
        node = root.find(f"link[@name='{link}']")
        sizes = [tuple(float(v) for v in box.get("size").split())
                 for box in node.iter("box")]
        assert MODEL.feet.size_m in sizes
    corners = MODEL.feet.sole_corners_m()
    assert np.ptp(corners[:, 0]) == pytest.approx(MODEL.feet.length_m)
    assert np.ptp(corners[:, 1]) == pytest.approx(MODEL.feet.width_m)
    assert corners[:, 0].mean() == pytest.approx(MODEL.feet.forward_m)


def test_the_collision_capsules_are_the_model_drill():
    drill = MODEL.drill
    checker = SelfCollisionChecker(MODEL, drill=True)
    shapes = {o.name: o.geometry for o in checker.geom.geometryObjects}
    assert shapes["drill_0"].radius == pytest.approx(drill.body_radius_m)
    assert 2 * shapes["drill_0"].halfLength == pytest.approx(drill.body_length_m)
    assert shapes["drill_1"].radius == pytest.approx(drill.bit_radius_m)
    assert 2 * shapes["drill_1"].halfLength == pytest.approx(drill.bit_tip_m - drill.body_front_m)


def test_a_missing_or_bad_dimension_is_a_config_error(tmp_path):
    text = MODEL.source.read_text()
    missing = tmp_path / "missing.toml"
    missing.write_text(text.replace("width_m = 0.13", ""))
    with pytest.raises(ConfigError, match="missing key") as info:
        load_model(path=missing)
    assert info.value.field == "feet.width_m"
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("body_front_m = -0.09", "body_front_m = 0.09"))
    with pytest.raises(ConfigError, match="negative"):
        load_model(path=bad)


@pytest.mark.parametrize("value", ["0.0", "-0.8", "nan", "inf", '"fast"'])
def test_a_limb_limit_that_is_not_a_positive_number_is_a_config_error(tmp_path, value):
    """The trackers divide by the speed, acceleration and jerk limits: a zero, a sign or a
    word there is the file's error, named with its field, not a traceback mid-period."""
    text = MODEL.source.read_text()
    line = "acceleration_rad_s2 = 0.8  # [hma] arms acceleration"
    assert line in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(line, f"acceleration_rad_s2 = {value}"))
    with pytest.raises(ConfigError) as info:
        load_model(path=bad)
    assert info.value.field is not None and info.value.field.startswith("limbs.")


HOSTILE = ("nan", "inf", "-inf", "0.0", "-1.0", '"1.21"', "true")
SHIPPED_LINES = {  # a line of the shipped file, and a hostile copy of it
    "lower-nan": ("lower_rad = [-1.8, -0.6, -1.3, 0.0, -1.3, -0.2]",
                  "lower_rad = [-1.8, -0.6, -1.3, nan, -1.3, -0.2]"),
    "upper-nan": ("upper_rad = [ 0.0,  0.0,  1.4, 2.5,  1.8,  0.3]",
                  "upper_rad = [ 0.0,  0.0,  1.4, nan,  1.8,  0.3]"),
    "lower-minus-inf": ("lower_rad = [-1.8, -0.6, -1.3, 0.0, -1.3, -0.2]",
                        "lower_rad = [-1.8, -0.6, -1.3, -inf, -1.3, -0.2]"),
    "upper-in-degrees": ("upper_rad = [ 0.0,  0.0,  1.4, 2.5,  1.8,  0.3]",
                         "upper_rad = [ 0.0,  0.0,  80.0, 143.0,  103.0,  17.0]"),
    "a-joint-named-twice": ('joints = ["RSP", "RSR", "RSY", "REB", "RWY", "RWP"]',
                            'joints = ["RSP", "RSP", "RSY", "REB", "RWY", "RWP"]'),
    "the-left-arm-twice": ('joints = ["RSP", "RSR", "RSY", "REB", "RWY", "RWP"]',
                           'joints = ["LSP", "LSR", "LSY", "LEB", "LWY", "LWP"]'),
    "a-joint-without-an-index": ('joints = ["RSP", "RSR", "RSY", "REB", "RWY", "RWP"]',
                                 'joints = ["XSP", "RSR", "RSY", "REB", "RWY", "RWP"]'),
    "two-joints-one-index": ("RSP = 11, RSR = 12", "RSP = 11, RSR = 11"),
    "an-index-past-the-frame": ("RSP = 11", "RSP = 42"),
    "a-negative-index": ("RSP = 11", "RSP = -1"),
    "a-fractional-index": ("RSP = 11", "RSP = 11.5"),
    "no-wrist-torque-limit": ("wrist_torque_limit_nm = 1.21", ""),
}
GENERATED = ([("robot", "control_period_s", v) for v in HOSTILE + ("0.2",)]
             + [("params.as-built", "lA2", v) for v in HOSTILE]
             + [("params.as-built", "lE ", v) for v in HOSTILE[:5]]
             + [("safety", key, v) for key in ("wrist_torque_limit_nm", "ik_hold_distance_m",
                                                "estop_revert_s", "estop_stop_s",
                                                "estop_brake_acceleration_rad_s2",
                                                "estop_brake_jerk_rad_s3") for v in HOSTILE]
             + [("safety", "wrist_torque_limit_nm", "50.5"), ("safety", "estop_revert_s", "6"),
                ("safety", "estop_stop_s", "1e9"), ("limbs.right-arm", "velocity_rad_s", "true"),
                ("feet", "length_m", "inf"), ("tools.drill", "mass_kg", "inf"),
                ("tools.hand", "rx_rad", "nan"), ("tools.drill", "phi_rad", "inf"),
                ("hubo_ach", "startup_ref_delay_s", "nan"), ("hubo_ach", "ref_filter_length",
                                                              "40.5")])


@pytest.mark.parametrize("table,key,value", GENERATED,
                         ids=[f"{t}.{k.strip()}={v}" for t, k, v in GENERATED])
def test_a_robot_file_value_without_physical_sense_is_refused_at_load(tmp_path, table, key,
                                                                      value):
    """Review 22: the robot file's control period, lengths and [safety] were read as they came
    (a NaN wrist torque limit is a wrist-torque stop that never trips, a period of 0 or NaN, a
    length in words); each is now the file's error, naming its field."""
    with pytest.raises(ConfigError) as info:
        load_model(path=robot_file_with(MODEL, tmp_path, table, key, value))
    assert info.value.field == f"{table}.{key.strip()}".replace("params.as-built", "params")


def test_a_hardware_guard_in_words_is_the_files_error_not_a_traceback(tmp_path):
    from hubo_cli.drivers.servo_guard import guard_parameters

    bad = load_model(path=robot_file_with(MODEL, tmp_path, "hardware_guards",
                                          "sole_force_max_n", '"2000 N"'))
    with pytest.raises(ConfigError, match="hardware_guards"):
        guard_parameters(bad)


@pytest.mark.parametrize("key", ["servo_error_limit_rad", "servo_error_window_periods",
                                 "sole_force_max_n", "sole_force_window_periods",
                                 "sole_unloaded_grace_s", "motor_max_temperature_c"])
def test_a_hardware_guard_beyond_any_hubo_is_refused(tmp_path, key):
    """Review 22 left the guards' values unbounded: a sole force limit of 1e9 N, a servo error
    of 100 rad or a motor limit of 1e6 C loaded, each a guard switched off in all but name.
    Each is now refused at its ceiling's first step beyond (GUARD_MAX), naming its field; the
    shipped values and the ceilings themselves load."""
    from hubo_cli.drivers.servo_guard import GUARD_MAX, guard_parameters

    most = GUARD_MAX[key]
    def guards(value, folder):
        (tmp_path / folder).mkdir()
        return guard_parameters(load_model(path=robot_file_with(
            MODEL, tmp_path / folder, "hardware_guards", key, repr(value))))

    assert guards(most, "at")[key] == most
    with pytest.raises(ConfigError, match="no guard on Hubo") as info:
        guards(most * 1.01 if isinstance(most, float) else most + 1, "beyond")
    assert info.value.field == f"hardware_guards.{key}"
    assert guard_parameters(MODEL)[key] <= most  # the shipped file


@pytest.mark.parametrize("case", sorted(SHIPPED_LINES))
def test_robot_file_limits_and_joints_that_cannot_be_the_robots_are_refused(tmp_path, case):
    """A NaN or infinite joint limit was no limit (NaN compares false: the lower <= upper check
    let it through), a limit in degrees passed, and two joints with one name or one hubo-ach
    index (a command sent to one motor twice and to another never) loaded."""
    line, hostile = SHIPPED_LINES[case]
    text = MODEL.source.read_text()
    assert line in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(line, hostile, 1))
    with pytest.raises(ConfigError) as info:
        load_model(path=bad)
    assert info.value.field.split(".")[0] in {"limbs", "hubo_ach", "safety"}


def test_every_shipped_parameter_and_limit_set_passes_the_robot_file_checks():
    for params in ("as-built", "table1"):
        for limits in ("table4", "team-code", "teleop", "walking"):
            assert load_model(params, limits).control_period_s == 0.005
