"""Generate the HUBO 2+ URDF from the robot model (``tools/make_urdf.py`` writes it to disk).

Kinematics
    The root link ``torso`` *is* the neck frame N (origin at shoulder height on the centre
    line, x forward, y left, z up). Every limb joint rotates about the z axis of its DH frame,
    so the link frames reproduce the DH model exactly: the origin of joint i is
    ``A_{i-1} @ Rz(offset_i)`` where ``A_0 = T_N_0`` (the limb's base transform) and
    ``A_k = Tz(d_k) Tx(a_k) Rx(alpha_k)`` (the fixed part of DH row k). Link i is therefore DH
    frame i-1 turned by theta_i. The end frames are fixed links: ``right_hand``/``left_hand``
    (tool "hand"), ``right_drill_bit`` (tool "drill", on the right arm) and
    ``right_sole``/``left_sole`` (the sole frames). The waist (``WST``) and the neck (``NKY``)
    are fixed joints: the model has no joints there.

Mass and inertia
    From the openHubo HUBO 2+ numbers (``INERTIAL_ROWS``, copied from the project's reference
    table). There every body frame is parallel to the torso at the zero pose, with its origin at
    the body's joint anchor, so the centre of mass in N at the zero pose is anchor + com. Those
    points are then moved onto the as-built geometry by a piecewise-linear stretch along the
    limb (shoulder, elbow, wrist for the arms; waist, hip, knee, ankle, sole for the legs; an
    offset past the last landmark) and by the change of shoulder/hip half-width; x is kept. The
    inertia tensors keep their values and axes. Bodies that the table lists without a centre of
    mass are placed as documented in ``_extra_masses``. Each inertia is written in its principal
    axes (diagonal tensor, rotated inertial origin) so that PyBullet, which reads only the
    diagonal, and pinocchio agree.

Collision
    Boxes, cylinders and spheres placed on the zero-pose geometry (``_collision_shapes``); no two
    shapes of links that are not parent and child touch in the home posture. The feet are flat
    boxes whose bottom face is the sole plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import ConfigError
from hubo_cli.geometry import matrix_to_rpy
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LIMB_NAMES, DrillShape, RobotModel

# ------------------------------------------------------------------------------------ data
# openHubo HUBO 2+ inertial numbers (see /work/shared/reference/hubo2plus-inertial.csv):
# joint, mass (kg), com (m, body frame), inertia about the com (kg m^2: Ixx Iyy Izz Ixy Ixz Iyz),
# joint anchor in the torso frame at the zero pose (m). Body names follow the URDF's joints.
INERTIAL_ROWS = {
    "TORSO": (7.5033387994, None,
              (0.102019218, 0.0832723937, 0.0864930148, 2.4546177e-05, 0.00713022243,
               -0.00131732551), (0.0, 0.0, 0.0)),
    "WST": (3.417193968804, (-0.0122581163, -0.00247314993, -0.0486356061),
            (0.0180348538, 0.00912381721, 0.0220513612, 3.175306e-05, -0.000513489041,
             -6.9061669e-05), (0.000008, -0.000013, -0.201256)),
    "NK2": (0.274250901076, (0.0106885816, -3.0086449e-05, 0.0321229536),
            (0.00164033032, 0.00153942788, 0.00190392514, -1.08171e-07, -9.5397797e-05,
             1.253758e-06), (0.0, -0.000021, 0.148299)),
    "RHY": (0.826125012988, (0.0347065003, -3.7480007e-05, -0.0726152732),
            (0.00151817591, 0.00286333372, 0.00211437397, -2.135861e-06, 0.000434128327,
             1.57525e-07), (0.000133, -0.088513, -0.277724)),
    "LHY": (0.826125012988, (0.0347065003, 3.7480007e-05, -0.0726152732),
            (0.00151817591, 0.00286333372, 0.00211437397, 2.135861e-06, 0.000434128327,
             -1.57525e-07), (0.000008, 0.088487, -0.277724)),
    "RHR": (1.93265668478, (-0.0497479126, -0.0125311166, -0.0156436646),
            (0.00403487201, 0.00332706652, 0.00317173339, -7.9452031e-05, -0.000125342881,
             0.000551964047), (0.052133, -0.088513, -0.368729)),
    "LHR": (1.93265668478, (-0.0497479126, 0.0125311166, -0.0156436646),
            (0.00403487201, 0.00332706652, 0.00317173339, 7.9452031e-05, -0.000125342881,
             -0.000551964047), (0.052908, 0.088487, -0.368729)),
    "RHP": (2.820095294731, (0.0195048914, 0.0595774808, -0.175201758),
            (0.0295102263, 0.027377052, 0.00838035284, -0.000184398776, -0.000370291227,
             -0.000656580164), (0.000133, -0.154088, -0.368729)),
    "LHP": (2.820095294731, (0.0195048914, -0.0595774808, -0.175201758),
            (0.0295102263, 0.027377052, 0.00838035284, 0.000184398776, -0.000370291227,
             0.000656580164), (0.000008, 0.154061, -0.368729)),
    "RKN": (1.809116607048, (0.0128254334, 0.00727567052, -0.171431348),
            (0.023215644, 0.0208342308, 0.00592039841, -0.000251648144, -0.00129343059,
             -0.00278067635), (0.000133, -0.109587, -0.648736)),
    "LKN": (1.809116607048, (0.0128254334, -0.00727567052, -0.171431348),
            (0.023215644, 0.0208342308, 0.00592039841, 0.000251648144, -0.00129343059,
             0.00278067635), (0.000008, 0.109560, -0.648736)),
    "RAP": (1.635010626057, (0.0198702461, 0.0459692551, 0.0115069411),
            (0.00231658614, 0.00330410608, 0.00279494608, -1.8740179e-05, 0.000369899,
             -6.3815303e-05), (0.000133, -0.134342, -0.928678)),
    "LAP": (1.635010626057, (0.0198702461, -0.0459692551, 0.0115069411),
            (0.00231658614, 0.00330410608, 0.00279494608, 1.8740179e-05, 0.000369899,
             6.3815303e-05), (0.000008, 0.134316, -0.928678)),
    "RAR": (1.003176884538, (-0.0515094078, -0.00216398213, -0.0693880695),
            (0.00295182656, 0.00524792423, 0.00516817393, -3.2321137e-05, 0.000141769152,
             -5.9540355e-05), (0.071312, -0.087742, -0.928678)),
    "LAR": (1.003176884538, (-0.0515094078, 0.00216398213, -0.0693880695),
            (0.00295182656, 0.00524792423, 0.00516817393, 3.2321137e-05, 0.000141769152,
             5.9540355e-05), (0.071187, 0.087715, -0.928678)),
    "RSP": (0.646654803406, (0.0167207215, -0.0570406792, 9.918731e-06),
            (0.000893730666, 0.000930159822, 0.00124322512, 0.000156483989, 4.98007e-07,
             -1.57095e-07), (0.0, -0.141500, 0.0)),
    "LSP": (0.646654803406, (0.0167207215, 0.0570406792, 9.918731e-06),
            (0.000893730666, 0.000930159822, 0.00124322512, -0.000156483989, 4.98007e-07,
             1.57095e-07), (0.0, 0.141500, 0.0)),
    "RSR": (0.413367772877, (-0.0362079738, 8.3124345e-05, -0.00126684832),
            (0.00026928334, 0.00037678951, 0.000360354691, -4.52571e-07, 3.236618e-06,
             -9.93935e-07), (0.026900, -0.213500, 0.0)),
    "LSR": (0.413367772877, (-0.0362079738, -8.3124345e-05, -0.00126684832),
            (0.00026928334, 0.00037678951, 0.000360354691, 4.52571e-07, 3.236618e-06,
             9.93935e-07), (0.026900, 0.213500, 0.0)),
    "RSY": (1.154608561577, (0.00456121126, -3.1057603e-05, -0.0907823775),
            (0.00366578854, 0.00364731371, 0.000606330376, -2.054362e-06, 0.00041844822,
             3.0964786e-05), (0.0, -0.213500, -0.024500)),
    "LSY": (1.154608561577, (0.00456121126, 3.1057603e-05, -0.0907823775),
            (0.00365478854, 0.00364731371, 0.000606330376, 2.054362e-06, 0.00041844822,
             -3.0964786e-05), (0.0, 0.213500, -0.024500)),
    "REB": (0.440940029986, (-0.0217349102, -0.0178313944, -0.0610872682),
            (0.000502700471, 0.000494150112, 0.000131786442, -3.645865e-06, -1.4138784e-05,
             -7.655278e-06), (0.021994, -0.195500, -0.182005)),
    "LEB": (0.440940029986, (-0.0217349102, 0.0178313944, -0.0610872682),
            (0.000502700471, 0.000494150112, 0.000131786442, 3.645865e-06, -1.4138784e-05,
             7.655278e-06), (0.021994, 0.195500, -0.182005)),
    "RWY": (0.53773814955, (-0.00122019208, -0.000635233335, -0.0238043186),
            (0.000634569731, 0.00056391751, 0.000305422235, 4.62486e-07, 6.206816e-06,
             -3.5404433e-05), (0.0, -0.213500, -0.293413)),
    "LWY": (0.53773814955, (-0.00122019208, 0.000635233335, -0.0238043186),
            (0.000634569731, 0.00056391751, 0.000305422235, -4.62486e-07, 6.206816e-06,
             3.5404433e-05), (0.0, 0.213500, -0.293413)),
    "RWP": (0.104392998329, (-0.000258199377, -0.0114419867, -0.0461472428),
            (9.7432742e-05, 0.000144494281, 0.000122681345, 5.22155e-07, -1.17317e-06,
             -9.492703e-06), (0.0, -0.203500, -0.345963)),
    "LWP": (0.104392998329, (-0.000258199377, 0.0114419867, -0.0461472428),
            (9.7432742e-05, 0.000144494281, 0.000122681345, -5.22155e-07, -1.17317e-06,
             9.492703e-06), (0.0, 0.203500, -0.345963)),
}
NECK_PITCH_MASS_KG = 0.1          # NK1 in the table, no centre of mass: at its anchor
NECK_ANCHOR_N = (0.0, 0.0, 0.148299)
PALM_MASS_KG = 0.06               # rightPalm / leftPalm, no centre of mass: at the palm anchor
FINGERS_MASS_KG = 0.14            # the fingers (not in the table's rows; total hand 0.14 kg)
PALM_ANCHOR_Z_M = -0.4237         # palm anchor height in the table's geometry
FOOT_MASS_KG = 0.203176884538     # rightFoot / leftFoot, no centre of mass: the foot plate
TORSO_COM_N = (0.0, 0.0, -0.06)   # [chosen] the table gives none: centre line, 6 cm below N

# The table's landmarks (zero pose, torso frame) and their as-built counterparts (model lengths).
_TABLE = {"lA1": 0.2135, "elbow_z": -0.182005, "wrist_z": -0.345963, "lL1": 0.0885,
          "waist_z": -0.201256, "hip_z": -0.368729, "knee_z": -0.648736,
          "ankle_z": -0.928678, "sole_z": -1.035037}

# Effort limits (N m): [chosen] of the order of Hubo 2+'s motor + harmonic drive outputs
# (200 W motors in the hips, knees and ankles, 90 W or less in the arms, small wrist motors).
EFFORT_NM = {"SP": 60.0, "SR": 60.0, "SY": 30.0, "EB": 40.0, "WY": 10.0, "WP": 10.0,
             "HY": 60.0, "HR": 150.0, "HP": 150.0, "KN": 200.0, "AP": 150.0, "AR": 100.0}
JOINT_DAMPING = 0.0

END_FRAMES = {"right-arm": ("right_hand",), "left-arm": ("left_hand",),
              "right-leg": ("right_sole",), "left-leg": ("left_sole",)}
DRILL_FRAME = "right_drill_bit"


def tool_frame(limb: str, tool: str) -> str:
    """The URDF frame of the end effector ``tool`` held by ``limb`` (the drill: its bit)."""
    if tool == "drill":
        if limb != "right-arm":
            raise ConfigError("the drill is modelled in the right hand only",
                              hint="use arm = \"right\" for drill tasks")
        return DRILL_FRAME
    if limb not in END_FRAMES:
        raise ConfigError(f"unknown limb {limb!r}", hint=f"use one of {', '.join(END_FRAMES)}")
    return END_FRAMES[limb][0]

_COLOURS = {"body": "0.85 0.85 0.88 1", "joint": "0.35 0.35 0.4 1", "foot": "0.2 0.2 0.25 1",
            "drill": "0.9 0.45 0.1 1"}


# ------------------------------------------------------------------------------------ maths
def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def _trans(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _num(value: float) -> str:
    value = float(value)
    if abs(value) < 1e-15:
        value = 0.0
    return repr(value)


def _vec(values) -> str:
    return " ".join(_num(v) for v in values)


def _origin(T: np.ndarray) -> str:
    return f'<origin xyz="{_vec(T[:3, 3])}" rpy="{_vec(matrix_to_rpy(T[:3, :3]))}"/>'


def _inertia_tensor(ixx, iyy, izz, ixy, ixz, iyz) -> np.ndarray:
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def _box_inertia(mass_kg: float, size_m) -> np.ndarray:
    x, y, z = size_m
    return mass_kg / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


@dataclass
class Inertial:
    """A rigid body's mass (kg), centre of mass and inertia about it, both in N at zero pose."""

    mass_kg: float
    com_N: np.ndarray
    inertia_N: np.ndarray

    def __add__(self, other: Inertial) -> Inertial:
        mass = self.mass_kg + other.mass_kg
        com = (self.mass_kg * self.com_N + other.mass_kg * other.com_N) / mass
        inertia = np.zeros((3, 3))
        for body in (self, other):
            r = body.com_N - com
            inertia += body.inertia_N + body.mass_kg * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
        return Inertial(mass, com, inertia)


# ------------------------------------------------------------------------------------ geometry
@dataclass(frozen=True)
class Landmarks:
    """Zero-pose landmark points of the as-built geometry in N (m)."""

    lengths_m: dict

    def arm_z(self) -> tuple[list[float], list[float]]:
        L = self.lengths_m
        new = [0.0, -L["lA2"], -L["lA2"] - L["lA3"]]
        return [0.0, _TABLE["elbow_z"], _TABLE["wrist_z"]], new

    def leg_z(self) -> tuple[list[float], list[float]]:
        L = self.lengths_m
        hip = -L["lT"] - L["lL2"]
        new = [0.0, -L["lT"], hip, hip - L["lL3"], hip - L["lL3"] - L["lL4"],
               hip - L["lL3"] - L["lL4"] - L["lL5"]]
        old = [0.0, _TABLE["waist_z"], _TABLE["hip_z"], _TABLE["knee_z"], _TABLE["ankle_z"],
               _TABLE["sole_z"]]
        return old, new

    def stretch(self, p_table: np.ndarray, kind: str) -> np.ndarray:
        """Move a zero-pose point of the table's geometry onto the as-built one."""
        old, new = self.arm_z() if kind == "arm" else self.leg_z()
        p = np.array(p_table, dtype=float)
        z = p[2]
        # piecewise linear through the landmarks (which decrease), slope 1 past the ends
        if z >= old[0]:
            p[2] = new[0] + (z - old[0])
        elif z <= old[-1]:
            p[2] = new[-1] + (z - old[-1])
        else:
            for k in range(len(old) - 1):
                if old[k + 1] <= z <= old[k]:
                    f = (z - old[k]) / (old[k + 1] - old[k])
                    p[2] = new[k] + f * (new[k + 1] - new[k])
                    break
        if kind == "arm":
            p[1] += math.copysign(self.lengths_m["lA1"] - _TABLE["lA1"], p[1])
        elif kind == "leg" and abs(p[1]) > 0.03:  # leg bodies, not the pelvis
            p[1] += math.copysign(self.lengths_m["lL1"] - _TABLE["lL1"], p[1])
        return p


def _table_inertial(joint: str, kind: str, marks: Landmarks) -> Inertial:
    mass, com, inertia, anchor = INERTIAL_ROWS[joint]
    com_table = np.array(anchor) + (np.array(com) if com is not None else np.array(TORSO_COM_N))
    com_N = marks.stretch(com_table, kind) if kind in ("arm", "leg") else com_table
    return Inertial(mass, com_N, _inertia_tensor(*inertia))


@dataclass
class LinkFrames:
    """Zero-pose frames of every URDF link in N (4x4) and the joint/link tree."""

    T_N_link: dict
    joints: list  # (name, type, parent, child, origin 4x4, limits dict or None)


def _limb_frames(model: RobotModel, limb_name: str, parent: str, T_N_parent: np.ndarray,
                 frames: LinkFrames) -> None:
    limb = Limb(model, limb_name, "none")
    base, _, offset, alpha, a, d, _, _ = limb.chain
    spec = limb.spec
    T_parent = T_N_parent
    A = np.linalg.inv(T_N_parent) @ base
    for i, joint in enumerate(spec.joints):
        origin = A @ _rot("z", offset[i])
        link = f"{joint}_link"
        limits = {"lower": spec.lower_rad[i], "upper": spec.upper_rad[i],
                  "velocity": spec.velocity_rad_s[i], "effort": EFFORT_NM[joint[1:]]}
        frames.joints.append((joint, "revolute", parent, link, origin, limits))
        T_parent = T_parent @ origin
        frames.T_N_link[link] = T_parent
        parent = link
        A = _trans(z=d[i]) @ _trans(x=a[i]) @ _rot("x", alpha[i])
    frames.T_N_link[f"{limb_name}:dh6"] = T_parent @ A


def link_frames(model: RobotModel) -> LinkFrames:
    """All link frames at the zero pose and the joints between them."""
    frames = LinkFrames({"torso": np.eye(4)}, [])
    T_N_pelvis = _trans(z=-model.lengths_m["lT"])
    T_N_head = _trans(z=NECK_ANCHOR_N[2])
    frames.joints.append(("WST", "fixed", "torso", "pelvis", T_N_pelvis, None))
    frames.joints.append(("NKY", "fixed", "torso", "head", T_N_head, None))
    frames.T_N_link["pelvis"] = T_N_pelvis
    frames.T_N_link["head"] = T_N_head
    for limb_name in LIMB_NAMES:
        is_arm = limb_name.endswith("arm")
        parent = "torso" if is_arm else "pelvis"
        _limb_frames(model, limb_name, parent, frames.T_N_link[parent], frames)
        last = f"{model.limb(limb_name).joints[-1]}_link"
        T_link_dh6 = np.linalg.inv(frames.T_N_link[last]) @ frames.T_N_link[f"{limb_name}:dh6"]
        if is_arm:
            end = T_link_dh6 @ model.tool_transform("hand")
        else:
            end = T_link_dh6 @ Limb(model, limb_name).T_6_end
        name = END_FRAMES[limb_name][0]
        frames.joints.append((f"{last}_to_{name}", "fixed", last, name, end, None))
        frames.T_N_link[name] = frames.T_N_link[last] @ end
        if limb_name == "right-arm":
            bit = T_link_dh6 @ model.tool_transform("drill")
            frames.joints.append((f"{last}_to_{DRILL_FRAME}", "fixed", last, DRILL_FRAME, bit,
                                  None))
            frames.T_N_link[DRILL_FRAME] = frames.T_N_link[last] @ bit
    return frames


# ------------------------------------------------------------------------------------ links
def _link_inertials(model: RobotModel) -> dict[str, Inertial]:
    """Inertial of each link, in N at the zero pose."""
    marks = Landmarks(model.lengths_m)
    out = {"torso": _table_inertial("TORSO", "torso", marks),
           "pelvis": _table_inertial("WST", "leg", marks)}
    neck_pitch = Inertial(NECK_PITCH_MASS_KG, np.array(NECK_ANCHOR_N),
                          _box_inertia(NECK_PITCH_MASS_KG, (0.04, 0.04, 0.04)))
    out["head"] = _table_inertial("NK2", "torso", marks) + neck_pitch
    L = model.lengths_m
    for limb_name in LIMB_NAMES:
        spec = model.limb(limb_name)
        kind = "arm" if spec.is_arm else "leg"
        for joint in spec.joints:
            out[f"{joint}_link"] = _table_inertial(joint, kind, marks)
        side = spec.side
        if spec.is_arm:
            palm = marks.stretch(np.array([0.0, side * 0.202432, PALM_ANCHOR_Z_M]), "arm")
            hand = PALM_MASS_KG + FINGERS_MASS_KG
            out[f"{spec.joints[-1]}_link"] += Inertial(hand, palm,
                                                       _box_inertia(hand, (0.08, 0.04, 0.1)))
        else:
            sole_z = -L["lT"] - L["lL2"] - L["lL3"] - L["lL4"] - L["lL5"]
            foot = model.feet
            centre = np.array([foot.forward_m, side * L["lL1"], sole_z + foot.thickness_m / 2])
            out[f"{spec.joints[-1]}_link"] += Inertial(
                FOOT_MASS_KG, centre, _box_inertia(FOOT_MASS_KG, foot.size_m))
    return out


@dataclass(frozen=True)
class Shape:
    """A collision/visual primitive: ``box`` (size), ``cylinder`` (radius, length along local
    z) or ``sphere`` (radius), posed by T_N_shape at the zero pose."""

    kind: str
    T_N_shape: np.ndarray
    dims: tuple
    colour: str = "body"


def _segment(p0, p1, radius: float, colour: str = "body") -> Shape:
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    z = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = (p0 + p1) / 2
    return Shape("cylinder", T, (radius, length), colour)


def _box(centre, size, colour: str = "body") -> Shape:
    return Shape("box", _trans(*centre), tuple(size), colour)


def _sphere(centre, radius: float, colour: str = "joint") -> Shape:
    return Shape("sphere", _trans(*centre), (radius,), colour)


# The torso's collision box in N (m): its centre and its size along x, y, z.
TORSO_BOX_N_M = ((-0.01, 0.0, -0.045), (0.18, 0.30, 0.25))


def torso_front_m() -> float:
    """How far the front of the torso's box lies ahead of the neck, along N's x (m)."""
    (x, _, _), (depth, _, _) = TORSO_BOX_N_M
    return x + depth / 2


# The hand's collision box (palm and fingers): its centre this far past the wrist pitch axis
# along the forearm, and its size across the forearm (x, y at the zero pose) and along it (m).
HAND_BOX_CENTRE_M = 0.07
HAND_BOX_SIZE_M = (0.08, 0.04, 0.13)


def hand_front_m(model: RobotModel) -> float:
    """How far the hand's front face (its collision box's end) lies past the hand point along
    the forearm, the hand frame's x (m; 14.35 mm as built): the box ends 0.135 m past the
    wrist pitch axis, the hand point lA4 past it."""
    return HAND_BOX_CENTRE_M + HAND_BOX_SIZE_M[2] / 2 - model.lengths_m["lA4"]


def _collision_shapes(model: RobotModel) -> dict[str, list[Shape]]:
    """Primitive shapes per link, on the zero-pose geometry (N, m)."""
    L = model.lengths_m
    shapes: dict[str, list[Shape]] = {
        "torso": [_box(*TORSO_BOX_N_M)],
        "pelvis": [_box((-0.01, 0.0, -L["lT"] - 0.05), (0.16, 0.26, 0.12))],
        "head": [_sphere((0.0, 0.0, NECK_ANCHOR_N[2] + 0.08), 0.08, "body")],
    }
    for limb_name in LIMB_NAMES:
        spec = model.limb(limb_name)
        j = spec.joints
        y = spec.side * (L["lA1"] if spec.is_arm else L["lL1"])
        if spec.is_arm:
            elbow, wrist = -L["lA2"], -L["lA2"] - L["lA3"]
            shapes[f"{j[0]}_link"] = [_sphere((0, y, 0.0), 0.045)]
            shapes[f"{j[2]}_link"] = [_segment((0, y, -0.06), (0, y, elbow + 0.03), 0.045)]
            shapes[f"{j[3]}_link"] = [_sphere((0, y, elbow), 0.04)]
            shapes[f"{j[4]}_link"] = [_segment((0, y, elbow - 0.045), (0, y, wrist + 0.03),
                                               0.04)]
            shapes[f"{j[5]}_link"] = [_box((0, y, wrist - HAND_BOX_CENTRE_M), HAND_BOX_SIZE_M)]
        else:
            hip = -L["lT"] - L["lL2"]
            knee, ankle = hip - L["lL3"], hip - L["lL3"] - L["lL4"]
            sole = ankle - L["lL5"]
            shapes[f"{j[2]}_link"] = [_segment((0, y, hip - 0.07), (0, y, knee), 0.055)]
            shapes[f"{j[3]}_link"] = [_sphere((0, y, knee), 0.05),
                                      _segment((0, y, knee), (0, y, ankle + 0.06), 0.05)]
            fx, fy, fz = model.feet.size_m
            shapes[f"{j[5]}_link"] = [
                _box((model.feet.forward_m, y, sole + fz / 2), (fx, fy, fz), "foot"),
                _box((0.0, y, (sole + fz + ankle) / 2 - 0.005), (0.07, 0.07, ankle - sole - fz
                                                                 - 0.01), "joint")]
    return shapes


def _geometry_xml(shape: Shape) -> str:
    if shape.kind == "box":
        return f'<box size="{_vec(shape.dims)}"/>'
    if shape.kind == "cylinder":
        return f'<cylinder radius="{_num(shape.dims[0])}" length="{_num(shape.dims[1])}"/>'
    return f'<sphere radius="{_num(shape.dims[0])}"/>'


def _inertial_xml(inertial: Inertial, T_N_link: np.ndarray) -> list[str]:
    R = T_N_link[:3, :3]
    com_link = R.T @ (inertial.com_N - T_N_link[:3, 3])
    I_link = R.T @ inertial.inertia_N @ R
    eigval, eigvec = np.linalg.eigh(I_link)
    if np.linalg.det(eigvec) < 0:
        eigvec[:, 2] = -eigvec[:, 2]
    T = np.eye(4)
    T[:3, :3] = eigvec
    T[:3, 3] = com_link
    ixx, iyy, izz = (float(v) for v in eigval)
    return ["    <inertial>", f"      {_origin(T)}",
            f'      <mass value="{_num(inertial.mass_kg)}"/>',
            f'      <inertia ixx="{_num(ixx)}" ixy="0.0" ixz="0.0" iyy="{_num(iyy)}" '
            f'iyz="0.0" izz="{_num(izz)}"/>', "    </inertial>"]


def _drill_parts(drill: DrillShape, T_N_bit: np.ndarray) -> tuple[Inertial, list[Shape]]:
    """The drill: a body along the bit axis behind the bit's middle, and the bit itself."""
    x_axis = T_N_bit[:3, 0]
    bit_mid = T_N_bit[:3, 3]
    body_front = bit_mid + drill.body_front_m * x_axis
    body_back = body_front - drill.body_length_m * x_axis
    body = _segment(body_back, body_front, drill.body_radius_m, "drill")
    bit = _segment(body_front, bit_mid + drill.bit_tip_m * x_axis, drill.bit_radius_m, "joint")
    r, length = drill.body_radius_m, drill.body_length_m
    inertia_local = drill.mass_kg * np.diag([(3 * r * r + length * length) / 12] * 2
                                            + [r * r / 2])
    R = body.T_N_shape[:3, :3]
    inertial = Inertial(drill.mass_kg, body.T_N_shape[:3, 3].copy(), R @ inertia_local @ R.T)
    return inertial, [body, bit]


def build_urdf(model: RobotModel, drill: bool = False, fold_fixed: bool = False) -> str:
    """The URDF text for ``model`` (the as-built set is the shipped one).

    Args:
        model: robot model (lengths, limits).
        drill: add the drill to the right hand: its mass, its body and bit as visuals, its
            body (the motor housing) as a collision shape. The bit has none: it cuts into a
            wall rather than meeting it (the simulator's cutting model is its contact).
        fold_fixed: leave out the fixed links (pelvis, head, the end frames) and fold their
            mass and shapes into the moving link they hang from: the variant the simulator
            loads (see :func:`folded_inertials`).
    """
    frames = link_frames(model)
    inertials = _link_inertials(model)
    shapes = _collision_shapes(model)
    name = "hubo2plus-drill" if drill else "hubo2plus"
    lines = ['<?xml version="1.0"?>',
             "<!-- Generated by tools/make_urdf.py from robots/hubo2plus/hubo2plus.toml "
             f"(parameter set {model.params_name!r}). Do not edit by hand. -->",
             "<!-- Root link torso = neck frame N (x forward, y left, z up). Limb joints rotate "
             "about z of their DH frames; WST and NKY are fixed. -->"]
    if fold_fixed:
        lines.append("<!-- Physics variant: fixed links folded into their moving parents "
                     "(same masses, inertias and shapes; no end frames). -->")
    lines.append(f'<robot name="{name}">')
    colours = sorted(_COLOURS)
    for colour in colours:
        lines.append(f'  <material name="{colour}"><color rgba="{_COLOURS[colour]}"/></material>')
    visuals = {link: list(link_shapes) for link, link_shapes in shapes.items()}
    if drill:
        drill_inertial, drill_shapes = _drill_parts(model.drill, frames.T_N_link[DRILL_FRAME])
        inertials = dict(inertials, **{DRILL_FRAME: drill_inertial})
        visuals[DRILL_FRAME] = visuals.get(DRILL_FRAME, []) + drill_shapes
        shapes = dict(shapes, **{DRILL_FRAME: shapes.get(DRILL_FRAME, []) + drill_shapes[:1]})
    joints = frames.joints
    link_names = ["torso"] + [child for (_, _, _, child, _, _) in joints]
    if fold_fixed:
        owner = _moving_ancestors(frames)
        inertials = folded_inertials(frames, inertials)
        for table in (shapes, visuals):
            folded: dict[str, list[Shape]] = {}
            for link, link_shapes in table.items():
                folded.setdefault(owner[link], []).extend(link_shapes)
            table.clear()
            table.update(folded)
        joints = [(joint, kind, owner[parent], child,
                   np.linalg.inv(frames.T_N_link[owner[parent]]) @ frames.T_N_link[parent]
                   @ origin, limits)
                  for joint, kind, parent, child, origin, limits in joints if kind != "fixed"]
        link_names = ["torso"] + [child for (_, _, _, child, _, _) in joints]
    for link in link_names:
        T_N_link = frames.T_N_link[link]
        lines.append(f'  <link name="{link}">')
        inertial = inertials.get(link)
        if inertial is not None:
            lines += _inertial_xml(inertial, T_N_link)
        else:  # a frame only: massless (PyBullet would otherwise give it 1 kg)
            lines += ["    <inertial>", '      <mass value="0.0"/>',
                      '      <inertia ixx="0.0" ixy="0.0" ixz="0.0" iyy="0.0" iyz="0.0" '
                      'izz="0.0"/>',
                      "    </inertial>"]
        for shape in visuals.get(link, []):
            T = np.linalg.inv(T_N_link) @ shape.T_N_shape
            lines += ["    <visual>", f"      {_origin(T)}",
                      f"      <geometry>{_geometry_xml(shape)}</geometry>",
                      f'      <material name="{shape.colour}"/>', "    </visual>"]
        for shape in shapes.get(link, []):
            T = np.linalg.inv(T_N_link) @ shape.T_N_shape
            lines += ["    <collision>", f"      {_origin(T)}",
                      f"      <geometry>{_geometry_xml(shape)}</geometry>", "    </collision>"]
        lines.append("  </link>")
    for joint, kind, parent, child, origin, limits in joints:
        lines.append(f'  <joint name="{joint}" type="{kind}">')
        lines += [f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
                  f"    {_origin(origin)}"]
        if kind == "revolute":
            lines += ['    <axis xyz="0 0 1"/>',
                      f'    <limit lower="{_num(limits["lower"])}" upper="{_num(limits["upper"])}"'
                      f' effort="{_num(limits["effort"])}" velocity="{_num(limits["velocity"])}"/>',
                      f'    <dynamics damping="{_num(JOINT_DAMPING)}" friction="0.0"/>']
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _moving_ancestors(frames: LinkFrames) -> dict[str, str]:
    """Each link -> itself if a revolute joint (or nothing: the root) moves it, else the
    nearest such ancestor through fixed joints."""
    fixed_parent = {child: parent for (_, kind, parent, child, _, _) in frames.joints
                    if kind == "fixed"}

    def owner(link: str) -> str:
        return owner(fixed_parent[link]) if link in fixed_parent else link

    return {link: owner(link) for link in frames.T_N_link if ":" not in link}


def folded_inertials(frames: LinkFrames, inertials: dict[str, Inertial]) -> dict[str, Inertial]:
    """Each moving link's inertial with those of the fixed links hanging from it added (in N at
    the zero pose).

    PyBullet's ``URDF_MERGE_FIXED_LINKS`` mishandles the inertial origin of a link with fixed
    children (a known bullet3 bug): with the shipped URDF the physics' centre of mass came out
    17-21 mm higher than the model's, and with the masses moved onto the parent beforehand
    35 mm. Loading without the merge is exact but keeps seven extra bodies in the dynamics
    (30 % more per step). So the simulator loads a variant with no fixed links at all.
    """
    owner = _moving_ancestors(frames)
    folded: dict[str, Inertial] = {}
    for link, inertial in inertials.items():
        target = owner[link]
        folded[target] = folded[target] + inertial if target in folded else inertial
    return folded


PHYSICS_URDF = "hubo2plus-physics.urdf"
PHYSICS_DRILL_URDF = "hubo2plus-drill-physics.urdf"


def urdf_variants(model: RobotModel) -> dict[str, str]:
    """File name -> URDF text of every shipped variant (plain robot, robot with the drill)."""
    return {"hubo2plus.urdf": build_urdf(model, drill=False),
            "hubo2plus-drill.urdf": build_urdf(model, drill=True),
            PHYSICS_URDF: build_urdf(model, drill=False, fold_fixed=True),
            PHYSICS_DRILL_URDF: build_urdf(model, drill=True, fold_fixed=True)}


def total_mass_kg(model: RobotModel, drill: bool = False) -> float:
    """The robot's mass (kg) as the URDF carries it."""
    mass = sum(i.mass_kg for i in _link_inertials(model).values())
    return mass + (model.drill.mass_kg if drill else 0.0)
