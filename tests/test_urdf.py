"""The generated URDF agrees with the DH model, is up to date, and its shapes do not collide."""

from __future__ import annotations

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


# Generated and committed URDFs are compared by meaning, not by their text: another CPU or numpy
# build changes the last printed digits, and the principal axes of an inertia (np.linalg.eigh)
# may come out with other signs while describing the same body. Lengths agree to 1 nm, angles
# to 1 nrad, masses and inertias to 1e-9 of their size; rotations are compared as matrices and
# inertias as the tensor they describe in the link frame.
NUMBER_RTOL = 1e-9
NUMBER_ATOL = 1e-9


def _rpy_matrix(text: str | None) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*(float(v) for v in (text or "0 0 0").split()))


def _numbers(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split()])


def _inertial_meaning(inertial: ET.Element) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia tensor about it), all in the link frame."""
    origin = inertial.find("origin")
    R = _rpy_matrix(None if origin is None else origin.get("rpy"))
    com = _numbers("0 0 0" if origin is None else origin.get("xyz"))
    i = inertial.find("inertia")
    tensor = np.array([[float(i.get(a)) for a in row] for row in
                       (("ixx", "ixy", "ixz"), ("ixy", "iyy", "iyz"), ("ixz", "iyz", "izz"))])
    return float(inertial.find("mass").get("value")), com, R @ tensor @ R.T


def _close(a, b) -> bool:
    return np.allclose(a, b, rtol=NUMBER_RTOL, atol=NUMBER_ATOL)


def _same_element(a: ET.Element, b: ET.Element, where: str) -> list[str]:
    """What differs between two URDF elements and their children (empty: the same)."""
    if a.tag != b.tag:
        return [f"{where}: <{a.tag}> vs <{b.tag}>"]
    where = f"{where}/{a.tag}" + (f"[{a.get('name')}]" if a.get("name") else "")
    if a.tag == "inertial":
        (ma, ca, ia), (mb, cb, ib) = _inertial_meaning(a), _inertial_meaning(b)
        return [] if _close(ma, mb) and _close(ca, cb) and _close(ia, ib) else [where]
    problems = []
    if set(a.attrib) != set(b.attrib):
        problems.append(f"{where}: attributes {sorted(a.attrib)} vs {sorted(b.attrib)}")
    for key in set(a.attrib) & set(b.attrib):
        va, vb = a.get(key), b.get(key)
        if a.tag == "origin" and key == "rpy":
            same = _close(_rpy_matrix(va), _rpy_matrix(vb))
        else:
            try:
                same = _close(_numbers(va), _numbers(vb))
            except ValueError:  # text, not numbers
                same = va == vb
        if not same:
            problems.append(f"{where} {key}: {va!r} vs {vb!r}")
    if len(a) != len(b):
        return [*problems, f"{where}: {len(a)} vs {len(b)} children"]
    for ca, cb in zip(a, b, strict=True):
        problems += _same_element(ca, cb, where)
    return problems


def test_committed_urdf_is_what_the_generator_writes():
    """Every variant (plain, drill, and the physics ones) means what the generator writes now:
    the same elements, numbers to 1e-9, rotations as matrices, inertias as tensors."""
    for name, text in urdf_variants(MODEL).items():
        committed = ET.parse(URDF_DIR / name).getroot()
        problems = _same_element(committed, ET.fromstring(text), name)
        assert not problems, f"{name} is stale (run tools/make_urdf.py): {problems[:5]}"


def test_the_comparison_sees_a_changed_number_and_ignores_the_last_digits():
    text = urdf_variants(MODEL)["hubo2plus.urdf"]
    root = ET.fromstring(text)
    joint = next(j for j in root.iter("joint") if j.get("type") == "revolute")
    limit = joint.find("limit")
    lower = float(limit.get("lower"))
    limit.set("lower", repr(lower * (1 + 1e-13)))  # another CPU's last bits
    assert not _same_element(ET.fromstring(text), root, "urdf")
    limit.set("lower", repr(lower + 1e-6))  # a real change (1 urad)
    assert _same_element(ET.fromstring(text), root, "urdf")
    # the same inertia with its principal axes' signs flipped (x and y turned by a half turn)
    inertial = next(link.find("inertial") for link in root.iter("link")
                    if link.find("inertial/origin") is not None)
    limit.set("lower", repr(lower))
    origin = inertial.find("origin")
    R = _rpy_matrix(origin.get("rpy")) @ np.diag([-1.0, -1.0, 1.0])
    origin.set("rpy", " ".join(repr(float(v)) for v in pin.rpy.matrixToRpy(R)))
    assert not _same_element(ET.fromstring(text), root, "urdf")
    origin.set("xyz", " ".join(repr(float(v) + 1e-6) for v in _numbers(origin.get("xyz"))))
    assert _same_element(ET.fromstring(text), root, "urdf")


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
    assert bit.find("visual") is not None
    # the drill's body collides (radius from the robot TOML); the bit cuts, it has no shape
    radii = [float(c.find("geometry/cylinder").get("radius")) for c in bit.iter("collision")]
    assert radii == [pytest.approx(MODEL.drill.body_radius_m)]
