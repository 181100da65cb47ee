"""The simulated HUBO 2+ in PyBullet (driver name ``sim``, the default).

World
    A floor (plane z = 0, friction 1.0) with gravity; the URDF robot (its physics variant, fixed
    links folded into their moving parents by the generator) stands
    on it with both soles flat in the start posture (``home_posture`` unless given). The world
    frame is the neck frame N at start dropped onto the floor: x forward, y left, z up, origin
    on the floor under the neck. Before time 0 the robot settles for ``settle_s`` holding the
    start posture, so the first state already carries its weight on both feet.

Physics and control
    400 Hz physics (``physics_dt_s`` 2.5 ms), two steps per 5 ms control period, 30
    constraint-solver iterations per step (``solver_iterations``), all of them every step
    (``solver_residual_threshold`` is PyBullet's 1e-7, which these settings never reach; an
    early stop at 1e-3 or more changed the balance tests' outcomes). The physics step is what a
    period costs (docs/profile.md); these settings keep the standing, push and cutting motion of
    the former 1 kHz ones (``LEGACY_PHYSICS``, still selectable) within the limits that
    tests/test_sim_credibility.py checks. Joints are in position control (PyBullet motors:
    ``position_gain``, ``velocity_gain``): a motor removes the fraction ``position_gain`` of its
    position error per physics step, so the gain is set per step size to keep the servo's time
    constant (0.3 per 1 ms step = 0.59 per 2.5 ms step, see :func:`position_gain_for`).
    The soles are compliant (``sole_stiffness_n_m`` 1e6 N/m, ``sole_damping_n_s_m`` 1e4 N s/m per
    contact point, as rubber pads; the body sinks 0.06 mm): on rigid soles the closed chain
    through both legs leaves the split of the feet's horizontal forces to the solver's
    iteration history (24 N on one foot and 5 N on the other at 400 Hz, 6 and 4 N at 1 kHz,
    0.1 s after start); compliant soles make it a matter of physics (2.3 and 2.4 N at either
    rate). ``sole_stiffness_n_m=None`` gives rigid soles. The soles' contacts hold their
    friction anchors (``sole_friction_anchor``, PyBullet's ``frictionAnchor``): a contact that
    sticks is held where it first touched, within the friction cone, so a standing foot does not
    creep. Without them the solver's velocity-level friction lets both feet walk away together
    under a few newtons of cutting reaction, far inside the cone: 14 mm over a 60 s cut on a
    perturbed robot (foot friction 0.58), 9 mm at 0.91; the leg encoders and the IMU cannot see
    both feet slide at once, so the measured torso pose, the corrected hand goal and the hole
    drifted with them (hole RMS 5-6 mm instead of 1.5).
    A sole's contact also resists twisting (``sole_torsion_radius_m``): the solver's contact
    points carry no torsional friction each, so a sole that rocks onto one corner or edge (one
    or two points: the stance foot of a capture step, its CoP at the toe) spun freely under the
    swing leg's reaction (0.15 rad a step, up to 0.9 rad in a catch) where a rubber pad's
    contact patch holds it. Each point gets the torsional friction of a uniformly pressed disc
    of radius a, (2/3) mu a N (PyBullet's spinning friction, multiplied by the floor's friction,
    1); a = 1.5 cm, a corner's patch of the rubber pad. On a flat sole (four points 0.13 m from
    its middle) this adds about 8 % to the torsional friction its points' lateral friction
    already gives. (With a = 3 cm the standing balancer's even loading of the feet through a
    push and the paper balancer's ankle clamping in a short run changed past their tests.)
    The URDF's effort limits are the torque limits (tens of
    N m in the arms, 10 N m in the wrists, 100-200 N m in the legs); each motor's speed is capped
    at ``max_speed_factor`` (3) times the model's velocity limit, as a real motor's top speed
    (a jump in the command is followed fast and hard, as on the robot, but not in one step).

Sensors (:class:`~hubo_cli.drivers.base.RobotState`)
    IMU, at the torso frame's origin (the neck frame N) in the torso's axes: the orientation in
    the world, the gyro's angular rate and the accelerometer's specific force, the acceleration
    of that point less gravity (upright at rest [0, 0, +9.81] m/s^2). Both are means over the
    control period, as a sensor's anti-aliasing filter gives them: the rate is the turn from the
    last period's orientation (its rotation vector over the period), the acceleration the
    point's velocity differenced over the period. (The instantaneous rate, sampled every second
    physics step, aliases the soles' vibration: integrated, it drifted 5 deg in 4 s of a walk.)
    The first state, after the settling, reads the instantaneous rate and gravity alone. A
    perturbed robot adds the raw sensors' noise and biases (:mod:`hubo_cli.perturb`).
    Force/torque:
    computed, not read from joint reactions, as Hubo's three-axis sensors read them (f_z, m_x,
    m_y of [fx, fy, fz, mx, my, mz], N and N m; the others 0) in their own frames
    (:func:`~hubo_cli.state.T_frame_sensor`: an ankle's is the sole frame, a wrist's sits at the
    hand frame's origin with z along the forearm): the wrench the environment applies to the
    foot (contacts with the floor or a wall) or to the hand with its tool (contacts plus the
    drilling force), plus the load of the body beyond the sensor (the whole last link of the
    limb: the foot; the hand with the drill), m (g - a) at its centre of mass, a its
    acceleration differenced over the period (its rotational inertia is left out). So a still
    hand in the air reads its own and its tool's weight; standing, an ankle reads f_z = its
    share of the weight minus the foot's. Joint torques are the motors' applied torques. Feet
    contacts (the simulator's truth, for reports): a foot is in contact while the floor's F_z
    on it, low-passed at the robot file's ``estimation.contact_cutoff_hz``, exceeds its
    ``estimation.contact_threshold_n`` (the estimate's contact filter), as hrpsys decides
    it: a foot that only brushes the floor (a rocking sole touching with a few newtons) does not
    count as support.
    With hinged objects in the scene (:meth:`add_valve`, :meth:`add_door`) a wrist reads its
    hand's contacts averaged over the period's physics steps, plus the force of a grip on an
    object (:mod:`hubo_cli.drivers.sim_objects`).

Drilling (:class:`~hubo_cli.scene.CuttingModel`)
    With the drill on the right hand (``drill=True``) and a wall in the scene (:meth:`add_wall`),
    while the bit's flutes (``model.drill.bit_half_length_m`` either side of its middle, the frame
    ``right_drill_bit``) cross the wall, the material reacts on the wrist link every physics
    step: across the bit (in the wall plane, y and z) against the bit's velocity v_t there,

        F = -(coulomb_n * v_t / sqrt(|v_t|^2 + smooth_m_s^2) + viscous_n_s_per_m * v_t),

    along the bit against its feed (thrust, while its point is in the material) and about the
    bit (the spindle's braking torque, while the flutes cut), at the point where the bit crosses
    the wall's mid-plane. The wrist sensor reads all three. The bit cuts rather than collides:
    it has no rigid shape against a wall, so it passes into the wall and only this reaction
    acts; the drill's body (the motor housing, ``model.drill``) is a collision shape of the
    wrist link, so pushed too deep it meets the wall face. The bit sits lE = 0.178 m from the
    hand point along its own axis (which runs through the wrist), so a force F across the bit
    gives a wrist moment of about 0.178 F and the thrust none. With the defaults (0.5 N + 80 N
    s/m) cutting at 10 mm/s gives 1.25 N, about 0.22 N m at the wrist (the paper's cut:
    0.14-0.15 N m average, 0.35 N m peak), 50 mm/s about 0.8 N m and 100 mm/s about 1.5 N m,
    past the wrist's 1.21 N m limit; plunging at 10 mm/s meets 4 N of thrust and the spindle
    0.02 N m.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.drivers import checks
from hubo_cli.drivers.base import Driver, RunContext, SimulatedWorld, grip_flag
from hubo_cli.drivers.sim_objects import (
    Grip,
    HingedBody,
    create_door,
    create_valve,
    make_grip,
)
from hubo_cli.drivers.state_age import StateAgeGuard
from hubo_cli.errors import ConfigError, DeviceError, quoted
from hubo_cli.geometry import (
    matrix_rows_to_quat_wxyz,
    matrix_to_quat_wxyz,
    rotation_log,
    rotation_log_floats,
)
from hubo_cli.hinged_objects import Door, Valve
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.perturb import FOOT_LINKS, CommandDelay, Perturbation
from hubo_cli.perturb import draw as draw_perturbation
from hubo_cli.posture import home_posture
from hubo_cli.scene import CuttingModel
from hubo_cli.state import (
    FT_SENSORS,
    GRAVITY_M_S2,
    RobotState,
    T_frame_sensor,
    Truth,
)
from hubo_cli.urdf import DRILL_FRAME, PHYSICS_DRILL_URDF, PHYSICS_URDF, link_frames

# A simulated state is measured at the simulator's time, its age 0 to the last bit: older than
# half a period for 0.1 s, the hardware check's span (:mod:`hubo_cli.drivers.state_age`), is a
# fault of the code that measures it (review 18's delayed state, 100 ms: a capture-point stop
# nothing explained, which the hardware's 100 ms bound would not have caught either)
STATE_LATE_PERIODS = 0.5
HAND_FRAMES = {"right-wrist": ("RWP_link", "right_hand"), "left-wrist": ("LWP_link", "left_hand")}
HAND_LINK_OF = {frame: link for link, frame in HAND_FRAMES.values()}
SOLE_FRAMES = {"right-ankle": ("RAR_link", "right_sole"), "left-ankle": ("LAR_link", "left_sole")}
SENSOR_FRAMES = HAND_FRAMES | SOLE_FRAMES
SENSOR_LINKS = ("RWP_link", "LWP_link", "RAR_link", "LAR_link")
FRAME_PARENTS = {"right_hand": "RWP_link", "left_hand": "LWP_link", "right_sole": "RAR_link",
                 "left_sole": "LAR_link", DRILL_FRAME: "RWP_link"}



def _flush_c_stdio() -> None:
    """Flush C stdio buffers so that buffered native output lands while it is redirected."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def quiet_native_output():
    """Silence C-level stdout/stderr (PyBullet prints while importing and loading URDFs)."""
    saved = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        yield
        return
    try:
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
            except OSError:
                pass
        yield
    finally:
        _flush_c_stdio()
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


def import_pybullet():
    """Import pybullet without its banner on the terminal."""
    with quiet_native_output():
        import pybullet
    return pybullet


@dataclass(frozen=True)
class Wall:
    """A box wall in front of the robot (world frame, m): its near face at x = distance_m."""

    body_id: int
    distance_m: float
    height_m: float
    width_m: float
    thickness_m: float
    centre_y_m: float = 0.0

    def contains(self, p_world: np.ndarray) -> bool:
        """Whether a world point lies inside the wall box."""
        x, y, z = p_world
        return (self.distance_m <= x <= self.distance_m + self.thickness_m
                and abs(y - self.centre_y_m) <= self.width_m / 2 and 0.0 <= z <= self.height_m)

    def bit_crossing(self, T_world_bit: np.ndarray, half_length_m: float) -> np.ndarray | None:
        """Where a drill bit (middle at the frame origin, along its x axis, ``half_length_m``
        each way) crosses the wall's mid-plane, or None when its flutes miss the wall."""
        crossing = self._crossing(T_world_bit.tolist(), half_length_m)
        return None if crossing is None else np.array(crossing)

    def _crossing(self, rows: list, half_length_m: float) -> tuple[float, float, float] | None:
        """:meth:`bit_crossing` of a pose given as its rows of Python floats, as a tuple."""
        (ax, _, _, mx), (ay, _, _, my), (az, _, _, mz), _ = rows
        if abs(ax) < 1e-6:
            return None
        s = (self.distance_m + self.thickness_m / 2 - mx) / ax
        if abs(s) > half_length_m + self.thickness_m / 2 / abs(ax):
            return None
        y, z = my + s * ay, mz + s * az
        if abs(y - self.centre_y_m) <= self.width_m / 2 and 0.0 <= z <= self.height_m:
            return (mx + s * ax, y, z)
        return None

    def engagement(self, T_world_bit: np.ndarray, half_length_m: float,
                   point_length_m: float) -> tuple[float, float]:
        """How deep a bit (as in :meth:`bit_crossing`) is in the wall: the share (0..1) of the
        wall's thickness its flutes fill, and the share of its point (the last
        ``point_length_m`` before the tip) inside the wall."""
        return self._engagement(float(T_world_bit[0, 0]), float(T_world_bit[0, 3]),
                                half_length_m, point_length_m)

    def _engagement(self, axis_x: float, middle_x: float, half_length_m: float,
                    point_length_m: float) -> tuple[float, float]:
        """:meth:`engagement` of the bit's axis x component and its middle's x (floats)."""
        near, far = self.distance_m, self.distance_m + self.thickness_m

        def inside_m(s0: float, s1: float) -> float:  # x extent of [s0, s1] along the bit
            x0, x1 = middle_x + s0 * axis_x, middle_x + s1 * axis_x
            if x1 < x0:
                x0, x1 = x1, x0
            return max(0.0, min(x1, far) - max(x0, near))

        flutes = inside_m(-half_length_m, half_length_m) / min(
            self.thickness_m, 2 * half_length_m * abs(axis_x))
        point = inside_m(half_length_m - point_length_m, half_length_m) / (
            point_length_m * abs(axis_x))
        return min(1.0, flutes), min(1.0, point)


def _with_guide(force, torque, cutting: CuttingModel, wall: Wall, rows: list, bit_xyz, v):
    """The cutting wrench (force at ``bit_xyz``, torque; world) plus the depth guide's contact
    with the wall face (:meth:`CuttingModel.guide_force_n`), the guide's force moved to
    ``bit_xyz``: both lie on the bit's axis. ``rows``: the bit frame's pose in the world."""
    (ax, _, _, mx), (ay, _, _, my), (az, _, _, mz), _ = rows
    d = cutting.guide_depth_m
    gx, gy, gz = mx - d * ax, my - d * ay, mz - d * az  # the guide's face on the axis
    if not (abs(gy - wall.centre_y_m) <= wall.width_m / 2 and 0.0 <= gz <= wall.height_m):
        return force, torque
    fx, fy, fz = cutting.guide_force_n(gx - wall.distance_m, v)
    rx, ry, rz = gx - bit_xyz[0], gy - bit_xyz[1], gz - bit_xyz[2]
    return ((force[0] + fx, force[1] + fy, force[2] + fz),
            (torque[0] + ry * fz - rz * fy, torque[1] + rz * fx - rx * fz,
             torque[2] + rx * fy - ry * fx))


@dataclass
class _Push:
    force_world_n: np.ndarray
    until_s: float


# ---- physics settings (docs/profile.md) -------------------------------------------------
LEGACY_PHYSICS_DT_S = 0.001    # the former settings: 1 kHz, 5 steps per period
LEGACY_POSITION_GAIN = 0.3     # fraction of a motor's position error removed per 1 ms step
FAST_PHYSICS_DT_S = 0.0025     # the default: 400 Hz, 2 steps per period
# PyBullet's own solverResidualThreshold ((m/s)^2, see SimOptions): never reached by these
# settings, so every step runs all its solver iterations
PYBULLET_RESIDUAL_THRESHOLD = 1e-7


def position_gain_for(physics_dt_s: float) -> float:
    """The motor position gain that closes a joint's error as fast (per second) at step
    ``physics_dt_s`` as 0.3 per 1 ms step does: 1 - 0.7 ** (dt / 1 ms)."""
    steps = physics_dt_s / LEGACY_PHYSICS_DT_S
    return 1.0 - (1.0 - LEGACY_POSITION_GAIN) ** steps


# SimOptions values: the former 1 kHz physics (for comparisons: ``SimDriver(model,
# **LEGACY_PHYSICS)``) and the default. 30 iterations per 2.5 ms step (60 per period, the former
# 100; each costs about 6 us): with 20 the standing lean moves 0.1 deg away from the former
# physics' within 2 s, with 30 0.08 deg. Both keep PyBullet's residual threshold: a larger one
# that saves time changes the balance tests' outcomes (docs/profile.md).
LEGACY_PHYSICS = {"physics_dt_s": LEGACY_PHYSICS_DT_S, "solver_iterations": 20,
                  "solver_residual_threshold": PYBULLET_RESIDUAL_THRESHOLD,
                  "position_gain": LEGACY_POSITION_GAIN, "sole_stiffness_n_m": None}
FAST_PHYSICS = {"physics_dt_s": FAST_PHYSICS_DT_S, "solver_iterations": 30,
                "solver_residual_threshold": PYBULLET_RESIDUAL_THRESHOLD,
                "position_gain": position_gain_for(FAST_PHYSICS_DT_S),
                "sole_stiffness_n_m": 1.0e6, "sole_damping_n_s_m": 1.0e4}


@dataclass
class SimOptions:
    """Tunable settings of the simulation (SI units). The physics defaults are ``FAST_PHYSICS``;
    ``LEGACY_PHYSICS`` holds the former 1 kHz ones.

    ``solver_residual_threshold`` ((m/s)^2; rad^2/s^2 for joint rows) is PyBullet's
    ``solverResidualThreshold``: a step's constraint solver stops before ``solver_iterations``
    once, in one iteration, the largest squared velocity correction of any constraint row
    (contact, friction, joint motor) falls below it."""

    gui: bool = False
    drill: bool = False
    physics_dt_s: float = FAST_PHYSICS["physics_dt_s"]
    solver_iterations: int = FAST_PHYSICS["solver_iterations"]
    solver_residual_threshold: float = FAST_PHYSICS["solver_residual_threshold"]
    position_gain: float = FAST_PHYSICS["position_gain"]
    sole_stiffness_n_m: float | None = FAST_PHYSICS["sole_stiffness_n_m"]
    sole_damping_n_s_m: float = FAST_PHYSICS["sole_damping_n_s_m"]
    sole_friction_anchor: bool = True
    sole_torsion_radius_m: float | None = 0.015
    velocity_gain: float = 1.0
    friction: float = 1.0
    settle_s: float = 0.3
    max_speed_factor: float = 3.0
    cutting: CuttingModel = field(default_factory=CuttingModel)
    perturb_seed: int | None = None  # hubo_cli.perturb: None or 0 = the nominal robot and world
    logged_object: str | None = None  # a hinged object whose angle the log gets (reports)


@contextlib.contextmanager
def _urdf_file(path: Path, text: str):
    """``path`` itself when ``text`` is None, else a temporary file holding ``text``."""
    if text is None:
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="hubo-urdf-") as folder:
        copy = Path(folder) / path.name
        copy.write_text(text, encoding="utf-8")
        yield copy


def _pose(position, quat_xyzw) -> np.ndarray:
    """4x4 pose from a PyBullet position and quaternion (x, y, z, w): the arithmetic of
    :func:`~hubo_cli.geometry.quat_xyzw_to_matrix` in one array build (several calls a period
    read PyBullet's link states)."""
    x, y, z, w = quat_xyzw
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    px, py, pz = position
    return np.array(((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), px),
                     (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x), py),
                     (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y), pz),
                     (0.0, 0.0, 0.0, 1.0)))


def _pose_times(position, quat_xyzw, T_rows: list[float]) -> tuple[float, ...]:
    """The first three rows, flat, of the pose from a PyBullet position and quaternion (the
    arithmetic of :func:`_pose`) times a constant pose given the same way: in Python floats
    (a numpy 4x4 product and its array builds cost more, several times a period)."""
    x, y, z, w = quat_xyzw
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    a00, a01, a02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    a10, a11, a12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    a20, a21, a22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    b00, b01, b02, bx, b10, b11, b12, by, b20, b21, b22, bz = T_rows
    px, py, pz = position
    return (a00 * b00 + a01 * b10 + a02 * b20, a00 * b01 + a01 * b11 + a02 * b21,
            a00 * b02 + a01 * b12 + a02 * b22, a00 * bx + a01 * by + a02 * bz + px,
            a10 * b00 + a11 * b10 + a12 * b20, a10 * b01 + a11 * b11 + a12 * b21,
            a10 * b02 + a11 * b12 + a12 * b22, a10 * bx + a11 * by + a12 * bz + py,
            a20 * b00 + a21 * b10 + a22 * b20, a20 * b01 + a21 * b11 + a22 * b21,
            a20 * b02 + a21 * b12 + a22 * b22, a20 * bx + a21 * by + a22 * bz + pz)


def _sensor_reading(rows: list[tuple], T_world_sensor: tuple[float, ...], extra, extra_moment,
                    load, load_at) -> tuple[float, np.ndarray]:
    """A three-axis F/T sensor's reading and the floor's (contacts') f_z alone (N) in it.

    The external wrench on the sensor's link about the sensor frame's origin, in its axes,
    from its contact rows (see :meth:`SimDriver._contact_rows`), a known force at a point
    (``extra``: force N, point m, or None) and a pure moment (``extra_moment``, N m, or
    None); plus ``load``
    (N) at ``load_at`` (m): the body beyond the sensor, all in the world.
    ``T_world_sensor`` is the sensor's pose's first three rows, flat. Returns ``(f_z of the
    contacts and extra, [0, 0, f_z, m_x, m_y, 0])`` (what :data:`~hubo_cli.state.FT_MEASURED`
    keeps). Plain floats: a foot has four contact points, too few for array operations to
    pay."""
    r00, r01, r02, ox, r10, r11, r12, oy, r20, r21, r22, oz = T_world_sensor
    # the contacts' and the extra force's wrench about the world origin, then the sensor's
    fx = fy = fz = mx = my = mz = 0.0
    for px, py, pz, nx, ny, nz, fn, f1, d1x, d1y, d1z, f2, d2x, d2y, d2z in rows:
        gx = nx * fn + d1x * f1 + d2x * f2
        gy = ny * fn + d1y * f1 + d2y * f2
        gz = nz * fn + d1z * f1 + d2z * f2
        fx, fy, fz = fx + gx, fy + gy, fz + gz
        mx += py * gz - pz * gy
        my += pz * gx - px * gz
        mz += px * gy - py * gx
    if extra is not None:
        (gx, gy, gz), (px, py, pz) = extra
        fx, fy, fz = fx + gx, fy + gy, fz + gz
        mx += py * gz - pz * gy
        my += pz * gx - px * gz
        mz += px * gy - py * gx
    if extra_moment is not None:
        mx, my, mz = mx + extra_moment[0], my + extra_moment[1], mz + extra_moment[2]
    mx, my = mx - (oy * fz - oz * fy), my - (oz * fx - ox * fz)
    mz = mz - (ox * fy - oy * fx)
    contact_fz = fx * r02 + fy * r12 + fz * r22
    contact_mx = mx * r00 + my * r10 + mz * r20
    contact_my = mx * r01 + my * r11 + mz * r21
    # the load's, the same way
    (gx, gy, gz), (px, py, pz) = load, load_at
    mx, my, mz = py * gz - pz * gy, pz * gx - px * gz, px * gy - py * gx
    mx, my = mx - (oy * gz - oz * gy), my - (oz * gx - ox * gz)
    mz = mz - (ox * gy - oy * gx)
    return contact_fz, np.array((0.0, 0.0, contact_fz + (gx * r02 + gy * r12 + gz * r22),
                                 contact_mx + (mx * r00 + my * r10 + mz * r20),
                                 contact_my + (mx * r01 + my * r11 + mz * r21), 0.0))


class SimDriver(Driver, SimulatedWorld):
    """The HUBO 2+ in PyBullet. Options: see :class:`SimOptions` (``gui``, ``drill``, ...).

    Besides the contract it offers scene objects (:meth:`add_wall`, :meth:`add_valve`,
    :meth:`add_door`), a hand's grip on a valve (:meth:`grasp`, :meth:`release`), a torso push
    (:meth:`push_torso`), poses of named frames (:meth:`frame_pose`) and a headless
    snapshot (:meth:`snapshot_png`).
    """

    name = "sim"

    @property
    def world(self) -> SimDriver:
        """The simulator is its own world (scene, pushes, frames, snapshots)."""
        return self

    @classmethod
    def run_options(cls, run: RunContext) -> dict:
        """The window, the drill in the right hand and the wall's cutting coefficients."""
        options = {"gui": run.gui, "drill": run.tools.get("right-arm") == "drill"}
        if run.cutting is not None:
            options["cutting"] = dict(run.cutting)
        if run.perturb_seed:
            options["perturb_seed"] = run.perturb_seed
        return options

    def __init__(self, model: RobotModel, **options) -> None:
        super().__init__(model)
        unknown = set(options) - set(SimOptions.__dataclass_fields__)
        if unknown:
            raise ConfigError(f"unknown sim option(s): {', '.join(sorted(unknown))}",
                              hint=f"use {', '.join(SimOptions.__dataclass_fields__)}")
        if isinstance(options.get("cutting"), Mapping):
            options["cutting"] = CuttingModel(**options["cutting"])
        self.options = SimOptions(**options)
        if self.options.sole_stiffness_n_m is not None and not (
                self.options.sole_stiffness_n_m > 0 and self.options.sole_damping_n_s_m >= 0):
            raise ConfigError("sole stiffness must be > 0 N/m and damping >= 0 N s/m",
                              hint="or sole_stiffness_n_m=None for rigid soles")
        substeps = self.period_s / self.options.physics_dt_s
        if abs(substeps - round(substeps)) > 1e-9 or round(substeps) < 1:
            raise ConfigError(f"physics_dt_s {self.options.physics_dt_s} does not divide the "
                              f"{self.period_s} s control period")
        self.substeps = int(round(substeps))
        self._p = None
        self._cid = -1
        self._robot = -1
        self._walls: list[Wall] = []
        self._pending_walls: list[tuple] = []
        self._objects: dict[str, HingedBody] = {}
        self._pending_objects: dict[str, Valve | Door] = {}
        self._grips: dict[str, Grip] = {}  # hand frame -> its grip
        self._earlier_rows: dict[int, list[tuple]] = {}  # see _period_rows
        self._earlier_steps = 0  # the physics steps kept in _earlier_rows this period
        self._pushes: list[_Push] = []
        self._state: RobotState | None = None
        self._cmd = np.zeros(len(self.joint_names))
        self._flags: list[str] = []
        self._stopped = False
        self._closed = False
        self._t = 0.0
        self._cutting_floats = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        self._cutting_set = False  # the cutting wrench is not zero (reset before each step)
        self._cut_points: list[tuple] = []  # (time s, where the bit crossed a wall), per period
        self._physics_wall_s = 0.0
        self._perturbation = Perturbation()  # drawn from perturb_seed when the world is built
        self._noise = self._perturbation.noise(self.period_s)
        self._imu_last: tuple[tuple, tuple] | None = None  # last (v_world, R_world_torso rows)
        self._max_tilt_deg = 0.0
        self._delay: CommandDelay | None = None
        self._state_age = StateAgeGuard("the simulator",
                                        limit_s=STATE_LATE_PERIODS * self.period_s,
                                        clock="the simulator's clock",
                                        hint="a simulated state is measured when it is made: "
                                             "report this with the command line",
                                        one_clock=True)
        self._physics_step = 0
        tau = 1.0 / (2.0 * math.pi * model.estimation.contact_cutoff_hz)
        self._contact_threshold_n = model.estimation.contact_threshold_n
        self._contact_alpha = self.period_s / (self.period_s + tau)
        self._fz_filtered_n: list[float | None] = [None, None]
        frames = link_frames(model)
        self._T_link_frame = {child: origin for (_, kind, parent, child, origin, _)
                              in frames.joints if kind == "fixed" and child in FRAME_PARENTS}
        self._T_link_bit = self._T_link_frame.get(DRILL_FRAME)  # the drill's bit on its wrist
        if self.options.logged_object is not None:
            self.log_columns = ("object_angle_deg",)

    def log_values(self) -> dict[str, float]:
        """The logged object's hinge angle (deg; NaN before it is placed): the simulator's
        truth, for the reports and plots (a target cannot read it)."""
        name = self.options.logged_object
        if name is None:
            return {}
        body = self._objects.get(name)
        return {"object_angle_deg": math.nan if body is None
                else math.degrees(body.angle_rad(self._p, self._cid))}

    # ------------------------------------------------------------------ set-up
    def _connect(self) -> None:
        if self.options.gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            # PyBullet would end the whole process ("cannot connect to X server")
            raise DeviceError("no display for the PyBullet window (DISPLAY is not set)",
                              hint="run without --gui, or from a desktop session")
        p = import_pybullet()
        self._p = p
        with quiet_native_output():
            self._cid = p.connect(p.GUI if self.options.gui else p.DIRECT)
        if self._cid < 0:
            raise DeviceError("could not open the PyBullet window",
                              hint="run without --gui on a machine without a display")
        if self.options.gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=self._cid)
            p.resetDebugVisualizerCamera(2.3, 25, -14, [0.2, 0, 0.6], physicsClientId=self._cid)

    def _build_world(self, q0: np.ndarray) -> None:
        p, cid = self._p, self._cid
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0, 0, -GRAVITY_M_S2, physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=self.options.physics_dt_s,
                                    numSolverIterations=self.options.solver_iterations,
                                    solverResidualThreshold=self.options.solver_residual_threshold,
                                    physicsClientId=cid)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        floor_visual = p.createVisualShape(p.GEOM_BOX, halfExtents=[5, 5, 0.001],
                                           visualFramePosition=[0, 0, -0.001],
                                           rgbaColor=[0.75, 0.78, 0.8, 1], physicsClientId=cid)
        self._floor = p.createMultiBody(0, plane, floor_visual, physicsClientId=cid)
        p.changeDynamics(self._floor, -1, lateralFriction=self.options.friction,
                         physicsClientId=cid)
        # the physics variant: no fixed links (PyBullet's merge of fixed links misplaces the
        # centre of mass, see hubo_cli.urdf.folded_inertials), the same bodies otherwise
        urdf = self.model.urdf_path().with_name(PHYSICS_DRILL_URDF if self.options.drill
                                                else PHYSICS_URDF)
        urdf_text = self._perturb_world(urdf.read_text(encoding="utf-8"))
        sole = Limb(self.model, "right-leg").fk(q0[self.model.limb_slice("right-leg")])
        self.neck_height_m = float(-sole[2, 3])
        flags = p.URDF_USE_INERTIA_FROM_FILE
        with quiet_native_output(), _urdf_file(urdf, urdf_text) as path:
            self._robot = p.loadURDF(str(path), basePosition=[0, 0, self.neck_height_m],
                                     flags=flags, physicsClientId=cid)
        joints, self._links = {}, {}
        for i in range(p.getNumJoints(self._robot, physicsClientId=cid)):
            info = p.getJointInfo(self._robot, i, physicsClientId=cid)
            joints[info[1].decode()] = i
            self._links[info[12].decode()] = i
        self._idx = [joints[n] for n in self.joint_names]
        self._wrist_link = self._links["RWP_link"]  # the drill's
        self._hand_link_ids = [self._links[link] for link, _ in HAND_FRAMES.values()]
        self._ankle_link_ids = frozenset(self._links[SENSOR_FRAMES[s][0]] for s in FT_SENSORS
                                         if s.endswith("ankle"))
        self._sensor_link_ids = [self._links[n] for n in SENSOR_LINKS]
        # per F/T sensor, in FT_SENSORS order: its link's index in PyBullet and in the sensor
        # links' batch, the link-to-sensor pose (its first three rows, flat), which ankle (0,
        # 1, None), the drill's wrist and the mass beyond the sensor: the whole link (the hand
        # and a held tool, the foot)
        ankles = iter(range(2))
        self._sensor_table = tuple(
            (sensor, self._links[link], SENSOR_LINKS.index(link),
             (self._T_link_frame[frame] @ T_frame_sensor(sensor))[:3].ravel().tolist(),
             next(ankles) if sensor.endswith("ankle") else None, sensor == "right-wrist",
             p.getDynamicsInfo(self._robot, self._links[link], physicsClientId=cid)[0])
            for sensor, (link, frame) in ((s, SENSOR_FRAMES[s]) for s in FT_SENSORS))
        self._sensor_velocity: list[tuple | None] = [None] * len(FT_SENSORS)
        self._effort = [p.getJointInfo(self._robot, j, physicsClientId=cid)[10]
                        for j in self._idx]
        n = len(self._idx)  # the motors' gains, as setJointMotorControlArray takes them
        self._gains = ([self.options.position_gain] * n, [self.options.velocity_gain] * n)
        top_speed = self.options.max_speed_factor * self.model.velocity_rad_s
        for j, q, force, speed in zip(self._idx, q0, self._effort, top_speed, strict=True):
            # the speed cap is kept by later setJointMotorControlArray calls
            p.setJointMotorControl2(self._robot, j, p.POSITION_CONTROL, targetPosition=float(q),
                                    force=force, maxVelocity=float(speed), physicsClientId=cid)
        for link in [-1, *self._links.values()]:
            p.changeDynamics(self._robot, link, lateralFriction=self.options.friction,
                             physicsClientId=cid)
        if self.options.sole_stiffness_n_m is not None:  # compliant soles (rubber pads)
            for link in FOOT_LINKS:
                p.changeDynamics(self._robot, self._links[link],
                                 contactStiffness=self.options.sole_stiffness_n_m,
                                 contactDamping=self.options.sole_damping_n_s_m,
                                 physicsClientId=cid)
        if self.perturbation.foot_friction is not None:
            for link in FOOT_LINKS:
                p.changeDynamics(self._robot, self._links[link],
                                 lateralFriction=self.perturbation.foot_friction,
                                 physicsClientId=cid)
        if self.options.sole_torsion_radius_m is not None:  # a contact patch resists twisting
            mu = (self.options.friction if self.perturbation.foot_friction is None
                  else self.perturbation.foot_friction)
            for link in FOOT_LINKS:
                p.changeDynamics(self._robot, self._links[link],
                                 spinningFriction=2.0 / 3.0 * mu
                                 * self.options.sole_torsion_radius_m, physicsClientId=cid)
        if self.options.sole_friction_anchor:  # sticking soles stay put (no creep)
            for link in FOOT_LINKS:
                p.changeDynamics(self._robot, self._links[link], frictionAnchor=1,
                                 physicsClientId=cid)
        # base = torso link; PyBullet poses the base by its centre of mass
        info = p.getDynamicsInfo(self._robot, -1, physicsClientId=cid)
        self._T_com_torso = np.linalg.inv(_pose(info[3], info[4]))
        self._rows_com_torso = self._T_com_torso[:3].ravel().tolist()  # for _pose_times
        self._place(q0)
        for wall in self._pending_walls:
            self._create_wall(*wall)
        for name, spec in self._pending_objects.items():
            self._create_object(name, spec)

    def _place(self, q0: np.ndarray) -> None:
        p, cid = self._p, self._cid
        T_world_com = np.eye(4)
        T_world_com[2, 3] = self.neck_height_m
        # standing on the (perturbed) floor with both soles flat on it; the base is posed by
        # its inertial axes
        T_world_com = self.perturbation.T_world_floor() @ T_world_com @ np.linalg.inv(
            self._T_com_torso)
        w, x, y, z = matrix_to_quat_wxyz(T_world_com[:3, :3])
        p.resetBasePositionAndOrientation(self._robot, T_world_com[:3, 3].tolist(),
                                          [x, y, z, w], physicsClientId=cid)
        for j, q in zip(self._idx, q0, strict=True):
            p.resetJointState(self._robot, j, float(q), 0.0, physicsClientId=cid)
        self._cmd = np.array(q0, dtype=float)
        self._apply_command()
        for _ in range(int(round(self.options.settle_s / self.options.physics_dt_s))):
            p.stepSimulation(physicsClientId=cid)

    def _perturb_world(self, urdf_text: str) -> str | None:
        """Draw the perturbation (:mod:`hubo_cli.perturb`), tilt the floor, restart the noise
        and the command delay; returns the URDF text to load (None: the file as it is)."""
        self._perturbation = draw_perturbation(self.options.perturb_seed, urdf_text,
                                               self.options.physics_dt_s)
        self._p.resetBasePositionAndOrientation(self._floor, [0, 0, 0],
                                                self.perturbation.floor_quat_xyzw(),
                                                physicsClientId=self._cid)
        self._noise = self.perturbation.noise(self.period_s)
        steps = self.perturbation.delay_steps(self.options.physics_dt_s)
        self._delay = CommandDelay(steps) if steps else None
        self._physics_step = 0
        self._max_tilt_deg = 0.0
        return None if self.perturbation.nominal else self.perturbation.urdf_text(urdf_text)

    def _apply_command(self, q_cmd_rad: np.ndarray | None = None) -> None:
        """Send ``q_cmd_rad`` (default: the last command) to the motors now."""
        q = self._cmd if q_cmd_rad is None else q_cmd_rad
        position_gains, velocity_gains = self._gains
        self._p.setJointMotorControlArray(
            self._robot, self._idx, self._p.POSITION_CONTROL, targetPositions=q.tolist(),
            forces=self._effort, positionGains=position_gains, velocityGains=velocity_gains,
            physicsClientId=self._cid)

    # ------------------------------------------------------------------ contract
    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Build the world, stand the robot in ``q0_rad`` (home posture by default), time 0."""
        if self._closed:
            raise DeviceError("the simulation is closed", hint="create a new driver")
        q0 = home_posture(self.model) if q0_rad is None else np.asarray(q0_rad, dtype=float)
        if q0.shape != (len(self.joint_names),) or not np.all(np.isfinite(q0)):
            raise ConfigError(f"start posture must be {len(self.joint_names)} finite angles")
        q0 = np.clip(q0, self.model.lower_rad, self.model.upper_rad)
        if self._p is None:
            self._connect()
        self._walls = []
        self._objects = {}
        self._grips = {}
        self._earlier_rows = {}
        self._earlier_steps = 0
        self._cut_points = []
        self._pushes = []
        self._stopped = False
        self._t = 0.0
        self._fz_filtered_n = [None, None]
        self._imu_last = None
        self._build_world(q0)
        self._state = self._measure()
        return self._state

    def read(self) -> RobotState:
        """The state measured at the end of the last period."""
        self._require_started()
        return self._state

    def send(self, q_cmd_rad) -> np.ndarray:
        """Set the joint position targets; NaN entries keep their last target, targets are
        clipped to the joint limits. After :meth:`stop` the hold is kept (flag ``stopped``)."""
        self._require_started()
        q = self.full_command(self._cmd, q_cmd_rad)
        if self._stopped:
            self._flags.append("stopped")
            return self._cmd.copy()
        q, flags = checks.sanitize(self.model, self._cmd, q)
        self._flags += flags
        self._cmd = q
        if self._delay is None:
            self._apply_command()
        else:
            self._delay.push(self._physics_step, q)
        return self._cmd.copy()

    def step(self) -> RobotState:
        """Advance one control period (``substeps`` physics steps)."""
        self._require_started()
        p, cid = self._p, self._cid
        t0 = time.perf_counter()
        for k in range(self.substeps):
            if self._delay is not None and (q := self._delay.due(self._physics_step)) is not None:
                self._apply_command(q)
            self._apply_external_forces(self._t + k * self.options.physics_dt_s)
            p.stepSimulation(physicsClientId=cid)
            self._physics_step += 1
            if k < self.substeps - 1:
                self._keep_rows()
        self._physics_wall_s += time.perf_counter() - t0
        self._t += self.period_s
        self._state = self._measure()
        too_old = self._state_age.check(self._t - self._state.time_s, self._state.time_s)
        if too_old is not None:  # (a fault of the measuring code: it holds, as hardware does)
            self.stop()
            raise too_old
        return self._state

    def stop(self) -> None:
        """Hold the last command (the motors keep it); later commands are ignored."""
        if self._stopped or self._p is None or self._closed:
            self._stopped = True
            return
        self._stopped = True
        with contextlib.suppress(Exception):
            self._pushes = []
            if self._delay is not None:
                self._delay.clear()
            self._apply_command()

    def close(self) -> None:
        """Disconnect from PyBullet. Safe to call twice."""
        if self._p is not None and not self._closed:
            with contextlib.suppress(Exception):
                self._p.disconnect(physicsClientId=self._cid)
        self._closed = True
        self._stopped = True

    def _require_started(self) -> None:
        if self._closed:
            raise DeviceError("the simulation is closed", hint="create a new driver")
        if self._state is None:
            raise DeviceError("the simulation has not been started", hint=checks.NOT_STARTED_HINT)

    # ------------------------------------------------------------------ scene
    def add_wall(self, distance_m: float, height_m: float, width_m: float = 1.2,
                 thickness_m: float = 0.01, centre_y_m: float = 0.0) -> Wall | None:
        """Put a static box wall in front of the robot: near face at x = distance_m from the
        neck frame at start, from the floor up to height_m, width_m wide (along y) and
        thickness_m thick (along x). Before :meth:`start` it is created when the world is."""
        if min(distance_m, height_m, width_m, thickness_m) <= 0:
            raise ConfigError("wall distance, height, width and thickness must be positive")
        spec = (distance_m, height_m, width_m, thickness_m, centre_y_m)
        self._pending_walls.append(spec)
        if self._p is not None and self._robot >= 0 and not self._closed:
            return self._create_wall(*spec)
        return None

    def _create_wall(self, distance_m, height_m, width_m, thickness_m, centre_y_m) -> Wall:
        p, cid = self._p, self._cid
        half = [thickness_m / 2, width_m / 2, height_m / 2]
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        visual = p.createVisualShape(p.GEOM_BOX, halfExtents=half,
                                     rgbaColor=[0.76, 0.6, 0.42, 1], physicsClientId=cid)
        body = p.createMultiBody(0, shape, visual, [distance_m + thickness_m / 2, centre_y_m,
                                                    height_m / 2], physicsClientId=cid)
        wall = Wall(body, distance_m, height_m, width_m, thickness_m, centre_y_m)
        self._walls.append(wall)
        return wall

    def add_valve(self, valve: Valve, name: str = "valve") -> None:
        """Put a valve wheel (:class:`~hubo_cli.hinged_objects.Valve`) into the scene; before
        :meth:`start` it is created when the world is."""
        self._add_object(name, valve)

    def add_door(self, door: Door, name: str = "door") -> None:
        """Put a hinged door (:class:`~hubo_cli.hinged_objects.Door`) into the scene."""
        self._add_object(name, door)

    def _add_object(self, name: str, spec: Valve | Door) -> None:
        if name in self._pending_objects:
            raise ConfigError(f"the scene already has an object called {quoted(name)}")
        self._pending_objects[name] = spec
        if self._p is not None and self._robot >= 0 and not self._closed:
            self._create_object(name, spec)

    def _create_object(self, name: str, spec: Valve | Door) -> None:
        """Build it, unless it would stand inside the robot (refused: nothing moved)."""
        p, cid = self._p, self._cid
        body = (create_valve if isinstance(spec, Valve) else create_door)(p, cid, spec)
        inside = p.getClosestPoints(self._robot, body.body_id, 0.0, physicsClientId=cid)
        if inside:
            p.removeBody(body.body_id, physicsClientId=cid)
            self._pending_objects.pop(name, None)
            link = next((k for k, v in self._links.items() if v == inside[0][3]), "torso")
            raise ConfigError(f"the {body.kind} {quoted(name)} would stand inside the robot (it "
                              f"touches {link} where it is placed)",
                              hint="place it farther from the robot (a smaller seen offset)")
        self._objects[name] = body

    def _object(self, name: str) -> HingedBody:
        self._require_started()
        if name not in self._objects:
            raise ConfigError(f"the scene has no object {quoted(name)}",
                              hint=f"objects: {', '.join(self._objects) or 'none'}")
        return self._objects[name]

    def hinge_angle_rad(self, name: str) -> float:
        """A hinged object's joint angle now (rad; see :class:`~hubo_cli.hinged_objects.Valve`,
        :class:`~hubo_cli.hinged_objects.Door` for its sign)."""
        return self._object(name).angle_rad(self._p, self._cid)

    def grasp(self, frame: str, name: str, tolerance_m: float) -> float:
        """Close the hand ``frame`` on object ``name``: when the hand point lies within
        ``tolerance_m`` of what can be gripped (a valve's rim), it holds the object there
        (:func:`~hubo_cli.drivers.sim_objects.make_grip`). Returns how far the hand point
        was from the grip (m; inf when the object has nothing to grip); holds only when that
        is within the tolerance."""
        body = self._object(name)
        if frame not in HAND_LINK_OF:
            raise ConfigError(f"no hand frame {quoted(frame)}", hint="right_hand or left_hand")
        point = self.frame_pose(frame)[:3, 3]
        miss_m = body.grip_distance_m(self._p, self._cid, point)
        if miss_m <= tolerance_m and not self.holding(frame):
            self._grips[frame] = make_grip(self._p, self._cid, self._robot,
                                           self._links[HAND_LINK_OF[frame]], point, body)
        return miss_m

    def release(self, frame: str) -> None:
        """Open the hand ``frame`` (nothing when it holds nothing)."""
        self._grips.pop(frame, None)

    def holding(self, frame: str) -> bool:
        """Whether the hand ``frame`` holds an object (it closed on it and has not slipped)."""
        grip = self._grips.get(frame)
        return grip is not None and not grip.slipped

    def push_torso(self, force_world_n, duration_s: float) -> None:
        """Push the torso at its centre of mass with a world-frame force (N) for duration_s."""
        self._require_started()
        force = np.asarray(force_world_n, dtype=float)
        if force.shape != (3,) or not np.all(np.isfinite(force)) or duration_s < 0:
            raise ConfigError("push needs a finite 3-vector force and a duration >= 0")
        self._pushes.append(_Push(force, self._t + duration_s))

    def _apply_external_forces(self, t_s: float) -> None:
        p, cid = self._p, self._cid
        if self._pushes:
            self._pushes = [push for push in self._pushes if t_s < push.until_s - 1e-12]
        if self._pushes:
            com, _ = p.getBasePositionAndOrientation(self._robot, physicsClientId=cid)
            total = sum(push.force_world_n for push in self._pushes)
            p.applyExternalForce(self._robot, -1, total.tolist(), com, p.WORLD_FRAME,
                                 physicsClientId=cid)
        for body in self._objects.values():
            body.apply_closer(p, cid)
        for grip in self._grips.values():
            grip.apply(p, cid)
        self._cutting_set = False  # until the cutting sets it again
        if self._walls and self.options.drill:
            self._apply_cutting(t_s)

    def _apply_cutting(self, t_s: float) -> None:
        """The wall's reaction to the bit (:class:`~hubo_cli.scene.CuttingModel`): across the
        bit, along it (thrust) and about it (spindle), on the wrist link. Every physics step:
        the arithmetic in Python floats, the one pose product in numpy."""
        p, cid, drill = self._p, self._cid, self.model.drill
        link = self._wrist_link
        ls = p.getLinkState(self._robot, link, 1, 1, physicsClientId=cid)  # velocity, FK
        rows = (_pose(ls[4], ls[5]) @ self._T_link_bit).tolist()
        for wall in self._walls:
            bit_xyz = wall._crossing(rows, drill.bit_half_length_m)
            if bit_xyz is None:
                continue
            # velocity of the link's point at the bit: v + omega x r
            (wx, wy, wz), (vx, vy, vz), (ox, oy, oz) = ls[7], ls[6], ls[0]
            bx, by, bz = bit_xyz
            rx, ry, rz = bx - ox, by - oy, bz - oz
            v = (vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx)
            (ax, _, _, mx), (ay, _, _, _), (az, _, _, _), _ = rows
            flutes, point = wall._engagement(ax, mx, drill.bit_half_length_m,
                                             drill.bit_radius_m)
            cutting = self.options.cutting
            force, torque = cutting.wrench_on_bit(v, (ax, ay, az), flutes, point)
            if cutting.guide_depth_m > 0.0:  # the depth guide on the face: moved to bit_xyz
                force, torque = _with_guide(force, torque, cutting, wall, rows, bit_xyz, v)
            self._cutting_floats = (force, torque, bit_xyz)  # cutting_force_n ... as floats
            self._cutting_set = True
            p.applyExternalForce(self._robot, link, force, bit_xyz, p.WORLD_FRAME,
                                 physicsClientId=cid)
            p.applyExternalTorque(self._robot, link, torque, p.WORLD_FRAME,
                                  physicsClientId=cid)
            if t_s < self._t + 1e-12:  # the period's first physics step
                self._cut_points.append((self._t, np.array(bit_xyz)))
            break

    @property
    def cutting_force_n(self) -> np.ndarray:
        """The wall's force on the bit in the last physics step (N, world; zero when none)."""
        return np.array(self._cutting_floats[0]) if self._cutting_set else np.zeros(3)

    @property
    def cutting_torque_nm(self) -> np.ndarray:
        """The spindle's braking torque on the bit in the last physics step (N m, world)."""
        return np.array(self._cutting_floats[1]) if self._cutting_set else np.zeros(3)

    # ------------------------------------------------------------------ sensing
    # Batched reads: one getLinkStates for the four sensor links (a pose is built only for a
    # sensor something touches), one getContactPoints for the whole robot (grouped by link
    # here), one getJointStates.
    def _contact_rows(self) -> dict[int, list[tuple]]:
        """Contact points of the robot with anything, by robot link index: (position on the
        robot, normal towards the robot, normal force, friction 1, dir 1, friction 2, dir 2)."""
        rows: dict[int, list[tuple]] = {}
        for cp in self._p.getContactPoints(bodyA=self._robot, physicsClientId=self._cid):
            rows.setdefault(cp[3], []).append((*cp[5], *cp[7], cp[9], cp[10], *cp[11], cp[12],
                                               *cp[13]))
        return rows

    def _period_rows(self, link_id: int, rows: list[tuple]) -> list[tuple]:
        """A link's contact rows averaged over the period's physics steps: this step's
        ``rows`` and those kept by :meth:`_keep_rows`, their forces scaled by one over the
        steps' count (the wrench is linear in them, so the sensor reads the steps' mean
        wrench, about the sensor's pose at the period's end). At :meth:`start` no step was
        kept: ``rows`` alone, unscaled.

        The ankle sensors always read so, as an F/T board's anti-aliasing filter averages
        what it samples faster than it reports: the position motors, given a new target every
        period, press the soles harder in one physics step and less in the other (1.40 / 0.60
        of the weight while the joints move), and the last step alone read 0.58-1.6 of the
        weight; the mean is the floor's true push. The contact truth (``_contact_alpha``'s
        filter) takes the same mean."""
        earlier = self._earlier_rows.get(link_id, ())
        share = 1.0 / (1 + self._earlier_steps)
        if share == 1.0:
            return list(rows)
        return [(*r[:6], r[6] * share, r[7] * share, *r[8:11], r[11] * share, *r[12:])
                for r in (*rows, *earlier)]

    def _hand_rows(self, link_id: int, rows: list[tuple]) -> list[tuple]:
        """A hand's rows when the scene has hinged objects: its contacts averaged over the
        period's physics steps (a hand pushing a door slowly meets it in one of the two steps
        and leaves it in the other, 25 N and 0 N: the last step alone read 0 N all along) and
        the force of the grip holding an object (its last step's)."""
        return self._period_rows(link_id, rows) + [g.row() for g in self._grips.values()
                                                   if g.link == link_id and not g.slipped]

    def _keep_rows(self) -> None:
        """Keep this physics step's contacts of the feet (and of the hands among hinged
        objects) for the period's mean (:meth:`_period_rows`): one batched read."""
        links = self._ankle_link_ids
        if self._objects:
            links = links.union(self._hand_link_ids)
        for link, rows in self._contact_rows().items():
            if link in links:
                self._earlier_rows.setdefault(link, []).extend(rows)
        self._earlier_steps += 1

    def _measure(self) -> RobotState:
        p, cid = self._p, self._cid
        js = p.getJointStates(self._robot, self._idx, physicsClientId=cid)
        q, dq, _, tau = zip(*js, strict=True)  # the reaction forces (24 x 6) are not read
        q, dq, tau = np.array(q), np.array(dq), np.array(tau)
        com, orn = p.getBasePositionAndOrientation(self._robot, physicsClientId=cid)
        torso = _pose_times(com, orn, self._rows_com_torso)
        T_world_torso = np.array((torso[0:4], torso[4:8], torso[8:12], (0.0, 0.0, 0.0, 1.0)))
        v_com, omega_world = p.getBaseVelocity(self._robot, physicsClientId=cid)
        gyro, accel = self._imu(com, v_com, omega_world, torso)
        link_states = self._link_states = p.getLinkStates(
            self._robot, self._sensor_link_ids, computeLinkVelocity=1,
            computeForwardKinematics=1, physicsClientId=cid)
        contacts = self._contact_rows()
        cutting = self._cutting_set and any(self._cutting_floats[0])
        ft = {}
        contact = [False, False]
        filtered = self._fz_filtered_n
        velocities = self._sensor_velocity
        period = self.period_s
        for k, (sensor, link_id, k_state, T_link_sensor, ankle, wrist,
                mass) in enumerate(self._sensor_table):
            extra = moment = None
            if wrist and cutting:  # the cutting wrench as Python floats (cutting_force_n ...)
                force, moment, at = self._cutting_floats
                extra = (force, at)
            rows = contacts.get(link_id, ())
            if ankle is not None:  # the period's mean (an F/T board's anti-aliasing filter)
                rows = self._period_rows(link_id, rows)
            elif self._objects:  # a hand among hinged objects
                rows = self._hand_rows(link_id, rows)
            ls = link_states[k_state]
            # the body beyond the sensor loads it with its weight and its inertia, m (g - a),
            # at its centre of mass (a: its velocity differenced over the period)
            previous, velocities[k] = velocities[k], ls[6]
            ax = ay = az = 0.0
            if previous is not None:
                (vx, vy, vz), (ux, uy, uz) = ls[6], previous
                ax, ay, az = (vx - ux) / period, (vy - uy) / period, (vz - uz) / period
            load = (mass * -ax, mass * -ay, mass * (-GRAVITY_M_S2 - az))
            fz, ft[sensor] = _sensor_reading(rows, _pose_times(ls[4], ls[5], T_link_sensor),
                                             extra, moment, load, ls[0])
            if ankle is not None:  # contact: the floor's push alone (the simulator's truth)
                if filtered[ankle] is None:  # at start: no history to filter
                    filtered[ankle] = fz
                filtered[ankle] += self._contact_alpha * (fz - filtered[ankle])
                contact[ankle] = filtered[ankle] > self._contact_threshold_n
        self._earlier_rows, self._earlier_steps = {}, 0
        self._flags += [grip_flag(frame) for frame in self._grips if self.holding(frame)]
        flags, self._flags = tuple(dict.fromkeys(self._flags)), []
        if self._stopped:
            flags = tuple(dict.fromkeys((*flags, "stopped")))
        quat = matrix_rows_to_quat_wxyz((torso[0:3], torso[4:7], torso[8:11]))
        state = RobotState(time_s=self._t, q_rad=q, dq_rad_s=dq, imu_quat_wxyz=quat,
                           imu_gyro_rad_s=gyro, imu_accel_m_s2=accel, ft=ft, tau_nm=tau,
                           truth=Truth(T_world_torso, (contact[0], contact[1]), quat.copy()),
                           flags=flags)
        tilt_deg = math.degrees(math.acos(max(-1.0, min(1.0, torso[10]))))
        self._max_tilt_deg = max(self._max_tilt_deg, tilt_deg)
        return self._noise.measure(state)

    def _imu(self, com_world, v_com_world, omega_world,
             rows_world_torso: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
        """The IMU's gyro (rad/s) and specific force (m/s^2), in the torso axes, at the torso
        frame's origin, as means over the period: the turn from the last period's orientation,
        and the base's velocity carried there (v + omega x r) differenced, gravity removed.
        3-vectors as Python floats (``rows_world_torso``: ``T_world_torso``'s first three rows,
        flat)."""
        r00, r01, r02, tx, r10, r11, r12, ty, r20, r21, r22, tz = rows_world_torso
        w0, w1, w2 = omega_world
        c0, c1, c2 = com_world
        r0, r1, r2 = tx - c0, ty - c1, tz - c2
        u0, u1, u2 = v_com_world
        v = (u0 + (w1 * r2 - w2 * r1), u1 + (w2 * r0 - w0 * r2), u2 + (w0 * r1 - w1 * r0))
        R = (r00, r01, r02, r10, r11, r12, r20, r21, r22)
        last = self._imu_last
        self._imu_last = (v, R)
        if last is None:
            a0 = a1 = a2 = 0.0
            gyro = np.array((r00 * w0 + r10 * w1 + r20 * w2, r01 * w0 + r11 * w1 + r21 * w2,
                             r02 * w0 + r12 * w1 + r22 * w2))
        else:
            (l0, l1, l2), period = last[0], self.period_s
            a0, a1, a2 = (v[0] - l0) / period, (v[1] - l1) / period, (v[2] - l2) / period
            # the turn over the period, R_last^T R, in floats (a period turns far less than a
            # quarter turn; beyond, the array form)
            p00, p01, p02, p10, p11, p12, p20, p21, p22 = last[1]
            turn = (p00 * r00 + p10 * r10 + p20 * r20, p00 * r01 + p10 * r11 + p20 * r21,
                    p00 * r02 + p10 * r12 + p20 * r22, p01 * r00 + p11 * r10 + p21 * r20,
                    p01 * r01 + p11 * r11 + p21 * r21, p01 * r02 + p11 * r12 + p21 * r22,
                    p02 * r00 + p12 * r10 + p22 * r20, p02 * r01 + p12 * r11 + p22 * r21,
                    p02 * r02 + p12 * r12 + p22 * r22)
            log = rotation_log_floats(*turn)
            gyro = (np.array((log[0] / period, log[1] / period, log[2] / period))
                    if log is not None else rotation_log(np.reshape(turn, (3, 3))) / period)
        a2 += GRAVITY_M_S2
        return gyro, np.array((r00 * a0 + r10 * a1 + r20 * a2, r01 * a0 + r11 * a1 + r21 * a2,
                               r02 * a0 + r12 * a1 + r22 * a2))

    # ------------------------------------------------------------------ extras
    def frame_pose(self, frame: str) -> np.ndarray:
        """World pose (4x4, m) of ``torso`` or an end frame (``right_hand``, ``left_hand``,
        ``right_sole``, ``left_sole``, ``right_drill_bit``)."""
        self._require_started()
        if frame == "torso":
            return self._state.truth.T_world_torso.copy()
        if frame not in FRAME_PARENTS:
            raise ConfigError(f"unknown frame {quoted(frame)}",
                              hint=f"use torso, {', '.join(FRAME_PARENTS)}")
        # the sensor links' states read with the state (the physics has not moved since)
        ls = self._link_states[SENSOR_LINKS.index(FRAME_PARENTS[frame])]
        return _pose(ls[4], ls[5]) @ self._T_link_frame[frame]

    def com_world_m(self) -> np.ndarray:
        """The whole body's centre of mass in the world (m) as the physics has it: the masses
        and centres of mass of PyBullet's bodies (tests compare it with the model's)."""
        self._require_started()
        p, cid = self._p, self._cid
        mass = p.getDynamicsInfo(self._robot, -1, physicsClientId=cid)[0]
        base, _ = p.getBasePositionAndOrientation(self._robot, physicsClientId=cid)
        total, moment = mass, mass * np.asarray(base)
        links = sorted(self._links.values())
        for link, state in zip(links, p.getLinkStates(self._robot, links,
                                                      computeForwardKinematics=1,
                                                      physicsClientId=cid), strict=True):
            mass = p.getDynamicsInfo(self._robot, link, physicsClientId=cid)[0]
            total += mass
            moment = moment + mass * np.asarray(state[0])
        return moment / total

    @property
    def perturbation(self) -> Perturbation:
        """The perturbed robot and world of ``perturb_seed`` (nominal without one)."""
        return self._perturbation

    @property
    def max_tilt_deg(self) -> float:
        """The largest true torso tilt from upright since the start (deg)."""
        return self._max_tilt_deg

    @property
    def physics_wall_s(self) -> float:
        """Wall-clock time spent inside stepSimulation since the driver was made (s)."""
        return self._physics_wall_s

    @property
    def walls(self) -> tuple[Wall, ...]:
        """The walls in the scene."""
        return tuple(self._walls)

    def scene(self) -> dict:
        """What has been placed in the world, for the run's log metadata: ``walls`` (centre,
        orientation quaternion w x y z and size x y z of each box, m), ``tools`` per hand and
        ``hole_world_m`` (where the drill bit crossed a wall, once per period, to the micrometre)
        with ``hole_t_s`` (when)."""
        walls = [{"centre_world_m": [w.distance_m + w.thickness_m / 2, w.centre_y_m,
                                     w.height_m / 2], "quat_wxyz": [1.0, 0.0, 0.0, 0.0],
                  "size_m": [w.thickness_m, w.width_m, w.height_m]} for w in self._walls]
        return {"walls": walls, "tools": {"right-arm": "drill" if self.options.drill else "hand",
                                          "left-arm": "hand"},
                "objects": {name: body.to_json(self._p, self._cid)
                            for name, body in self._objects.items()},
                "held": {frame: grip.body.kind for frame, grip in self._grips.items()
                         if not grip.slipped},
                "hole_world_m": np.round(np.reshape([p for _, p in self._cut_points], (-1, 3)),
                                         6).tolist(),  # one rounding of every point
                "hole_t_s": [round(t, 6) for t, _ in self._cut_points]}

    def snapshot_png(self, path: str | Path, width: int = 640, height: int = 480) -> Path:
        """Render the scene headless from the video's camera, framing the whole robot (bit
        and hole marked, a legend bar), as a PNG."""
        self._require_started()
        from hubo_cli.drivers.snapshot import scene_snapshot

        tool = self.frame_pose(DRILL_FRAME if self.options.drill else "right_hand")[:3, 3]
        return scene_snapshot(self._p, self._cid, path, self.scene(), tool, self._robot, width,
                              height)

