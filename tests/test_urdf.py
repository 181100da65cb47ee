"""The generated URDF agrees with the DH model, is up to date, and its shapes do not collide."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from hubo_cli.kinematics import get_limb
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.urdf import build_urdf, total_mass_kg, urdf_variants

MODEL = load_model("as-built")
URDF_DIR = MODEL.urdf_path().parent
END_FRAMES = [("right-arm", "right_hand", "hand"), ("left-arm", "left_hand", "hand"),
              ("right-leg", "right_sole", "hand"), ("left-leg", "left_sole", "hand"),
              ("right-arm", "right_drill_bit", "drill")]


@pytest.fixture(scope="module")
def pin_model():
    return pin.buildModelFromUrdf(str(MODEL.urdf_path()))


def _q_pin(pm, names, values) -> np.ndarray:
    q = pin.neutral(pm)
    for name, value in zip(names, values, strict=True):
        q[pm.idx_qs[pm.getJointId(name)]] = value
    return q


def test_joints_are_the_model_joints_with_its_limits(pin_model):
    names = [pin_model.names[i] for i in range(1, pin_model.njoints)]
    assert sorted(names) == sorted(MODEL.joint_names)
    for i, name in enumerate(MODEL.joint_names):
        k = pin_model.idx_qs[pin_model.getJointId(name)]
        assert pin_model.lowerPositionLimit[k] == pytest.approx(MODEL.lower_rad[i])
        assert pin_model.upperPositionLimit[k] == pytest.approx(MODEL.upper_rad[i])
        assert pin_model.velocityLimit[k] == pytest.approx(MODEL.velocity_rad_s[i])
        assert 5.0 <= pin_model.effortLimit[k] <= 300.0


@pytest.mark.parametrize(("limb", "frame", "tool"), END_FRAMES)
def test_pinocchio_fk_equals_dh_fk(pin_model, limb, frame, tool):
    dh = get_limb(limb, tool)
    data = pin_model.createData()
    frame_id = pin_model.getFrameId(frame)
    assert frame_id < len(pin_model.frames)
    rng = np.random.default_rng(7)
    worst_pos, worst_rot = 0.0, 0.0
    for q6 in dh.random_q(rng, 1000):
        pin.framesForwardKinematics(pin_model, data, _q_pin(pin_model, dh.spec.joints, q6))
        T_urdf = data.oMf[frame_id].homogeneous
        T_dh = dh.fk(q6)
        worst_pos = max(worst_pos, float(np.linalg.norm(T_urdf[:3, 3] - T_dh[:3, 3])))
        R_err = T_dh[:3, :3].T @ T_urdf[:3, :3]
        worst_rot = max(worst_rot, float(np.linalg.norm(pin.log3(R_err))))
    assert worst_pos < 1e-9
    assert worst_rot < 1e-9


NUMBER = re.compile(r"-?\d+\.\d+(?:e-?\d+)?")
INERTIAL = re.compile(r"<inertial>.*?</inertial>", re.S)
RPY = re.compile(r'rpy="([^"]*)"')


def _bodies(text: str) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(mass, centre of mass, inertia tensor) of every body pinocchio builds from a URDF."""
    pm = pin.buildModelFromXML(text)
    return [(i.mass, i.lever, i.inertia) for i in pm.inertias]


def _rotations(text: str) -> np.ndarray:
    return np.array([pin.rpy.rpyToMatrix(*(float(v) for v in rpy.split()))
                     for rpy in RPY.findall(text)])


def test_committed_urdf_is_what_the_generator_writes():
    """Same text, the same numbers to 1e-9 and rotations (not their roll-pitch-yaw, which is not
    unique at pitch +-90 deg) outside the inertials, the same bodies (mass, centre of mass,
    inertia tensor) inside them: a body's principal axes come from an eigen-decomposition, whose
    last digits, and whose axes where two moments are equal (the drill), vary between LAPACK
    builds."""
    for name, text in urdf_variants(MODEL).items():
        committed = (URDF_DIR / name).read_text()
        stale = f"{name} is stale: run tools/make_urdf.py"
        ours, theirs = INERTIAL.sub("", text), INERTIAL.sub("", committed)
        assert NUMBER.sub("#", ours) == NUMBER.sub("#", theirs), stale
        assert np.allclose(_rotations(ours), _rotations(theirs), atol=1e-9), stale
        ours, theirs = RPY.sub("", ours), RPY.sub("", theirs)
        assert np.allclose([float(v) for v in NUMBER.findall(ours)],
                           [float(v) for v in NUMBER.findall(theirs)], rtol=1e-9, atol=1e-12), stale
        for (m1, c1, I1), (m2, c2, I2) in zip(_bodies(text), _bodies(committed), strict=True):
            assert m1 == pytest.approx(m2, rel=1e-9), stale
            assert np.allclose(c1, c2, atol=1e-12) and np.allclose(I1, I2, atol=1e-12), stale


def test_mass_matches_the_reference_total():
    pm = pin.buildModelFromUrdf(str(MODEL.urdf_path()))
    root = ET.parse(MODEL.urdf_path()).getroot()
    masses = [float(m.get("value")) for m in root.iter("mass")]
    assert sum(masses) == pytest.approx(total_mass_kg(MODEL))
    assert sum(masses) == pytest.approx(38.75, abs=0.05)  # openHubo HUBO 2+ total
    assert pin.computeTotalMass(pm) > 25.0  # the limbs (the torso sits on the fixed base)


def _link_parents() -> dict[str, str]:
    root = ET.parse(MODEL.urdf_path()).getroot()
    return {j.find("child").get("link"): j.find("parent").get("link") for j in root.iter("joint")}


def test_no_collision_between_non_adjacent_links_at_home():
    path = str(MODEL.urdf_path())
    pm = pin.buildModelFromUrdf(path)
    gm = pin.buildGeomFromUrdf(pm, path, pin.GeometryType.COLLISION)
    parents = _link_parents()
    links = [g.name.rsplit("_", 1)[0] for g in gm.geometryObjects]
    for a in range(len(links)):
        for b in range(a + 1, len(links)):
            la, lb = links[a], links[b]
            if la != lb and parents.get(la) != lb and parents.get(lb) != la:
                gm.addCollisionPair(pin.CollisionPair(a, b))
    assert len(gm.collisionPairs) > 150
    data, gdata = pm.createData(), pin.GeometryData(gm)
    q = _q_pin(pm, MODEL.joint_names, home_posture(MODEL))
    pin.computeDistances(pm, data, gm, gdata, q)
    distances = [r.min_distance for r in gdata.distanceResults]
    closest = int(np.argmin(distances))
    pair = gm.collisionPairs[closest]
    assert distances[closest] > 0.005, (links[pair.first], links[pair.second])


def test_feet_are_flat_boxes_whose_bottom_is_the_sole():
    path = str(MODEL.urdf_path())
    pm = pin.buildModelFromUrdf(path)
    gm = pin.buildGeomFromUrdf(pm, path, pin.GeometryType.COLLISION)
    data, gdata = pm.createData(), pin.GeometryData(gm)
    q = _q_pin(pm, MODEL.joint_names, home_posture(MODEL))
    pin.framesForwardKinematics(pm, data, q)
    pin.updateGeometryPlacements(pm, data, gm, gdata, q)
    for side in ("right", "left"):
        sole = data.oMf[pm.getFrameId(f"{side}_sole")]
        joint = "RAR" if side == "right" else "LAR"
        feet = [k for k, g in enumerate(gm.geometryObjects)
                if g.name.startswith(f"{joint}_link") and g.geometry.getNodeType()
                == pin.hppfcl.NODE_TYPE.GEOM_BOX and g.geometry.halfSide[2] < 0.02]
        assert len(feet) == 1
        box, placement = gm.geometryObjects[feet[0]].geometry, gdata.oMg[feet[0]]
        bottom = placement.translation[2] - box.halfSide[2]
        assert bottom == pytest.approx(sole.translation[2], abs=1e-12)
        assert np.allclose(placement.rotation, sole.rotation, atol=1e-12)
        assert np.allclose(sole.rotation, np.eye(3), atol=1e-12)  # home keeps the soles flat


def test_drill_variant_adds_the_drill_mass_only():
    plain, drill = build_urdf(MODEL), build_urdf(MODEL, drill=True)
    assert "right_drill_bit" in plain and "right_drill_bit" in drill
    assert total_mass_kg(MODEL, drill=True) > total_mass_kg(MODEL)
    root = ET.fromstring(drill)
    bit = next(link for link in root.iter("link") if link.get("name") == "right_drill_bit")
    assert bit.find("collision") is None and bit.find("visual") is not None
