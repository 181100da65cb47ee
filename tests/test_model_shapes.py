"""The drill's and the feet's dimensions have one source (the robot TOML, read by the model)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

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
