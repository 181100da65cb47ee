"""The HUBO 2+ robot description, read from ``robots/hubo2plus/hubo2plus.toml``.

A :class:`RobotModel` holds one kinematic parameter set (lengths in metres), the four limbs with
their joint names and limits, and the tools. Everything is immutable and cheap to pass around.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from functools import cache, cached_property
from pathlib import Path

import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.resources import data_file

ARMS = ("right-arm", "left-arm")
LEGS = ("right-leg", "left-leg")
LIMB_NAMES = ARMS + LEGS
TOOL_NAMES = ("none", "hand", "drill")
# The robot file's bounds that are not facts of the robot (review 22: they were read unchecked)
FULL_TURN_RAD = 2 * math.pi  # a joint limit or a tool angle past a full turn is not radians
MAX_CONTROL_PERIOD_S = 0.1  # 10 Hz; hubo-ach's loop is 200 Hz, the tests' robots 25 to 500 Hz
SAFETY_KEYS = ("wrist_torque_limit_nm", "ik_hold_distance_m", "estop_revert_s", "estop_stop_s",
               "estop_brake_acceleration_rad_s2", "estop_brake_jerk_rad_s3")
# the most the robot file's [safety] (and so a task file, which may only lower them) may give
STOP_MAX_S = 5.0             # T1 and T2 of the emergency stopper (paper: 0.5 s)
WRIST_TORQUE_MAX_NM = 50.0   # beyond it the wrist-torque stop is no stop on Hubo's wrists
SAFETY_MAX = {"wrist_torque_limit_nm": WRIST_TORQUE_MAX_NM, "estop_revert_s": STOP_MAX_S,
              "estop_stop_s": STOP_MAX_S}


@dataclass(frozen=True)
class LimbSpec:
    """One limb: its joint names (DH order) and per-joint limits (rad, rad/s, rad/s^2, rad/s^3)."""

    name: str
    joints: tuple[str, ...]
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray
    jerk_rad_s3: np.ndarray

    @property
    def is_arm(self) -> bool:
        return self.name.endswith("arm")

    @property
    def side(self) -> int:
        """+1 for a left limb (+y in the neck frame), -1 for a right limb."""
        return 1 if self.name.startswith("left") else -1


@dataclass(frozen=True)
class DrillShape:
    """The drill along its bit axis (the drill tool frame's x), from the bit's middle (m, kg).

    Attributes:
        mass_kg: the whole drill.
        body_length_m, body_radius_m: the motor body, a cylinder behind the bit.
        body_front_m: where the body ends (negative: behind the bit's middle).
        bit_radius_m: the bit, a cylinder from the body's front to its tip.
        bit_half_length_m: the flutes reach this far either side of the bit's middle; their
            front end is the tip.
    """

    mass_kg: float
    body_length_m: float
    body_radius_m: float
    body_front_m: float
    bit_radius_m: float
    bit_half_length_m: float

    @property
    def bit_tip_m(self) -> float:
        """Where the bit ends, ahead of its middle (m)."""
        return self.bit_half_length_m

    @property
    def bit_out_m(self) -> float:
        """The bit's length out of the chuck: from the body's front to its tip (m)."""
        return self.bit_tip_m - self.body_front_m


@dataclass(frozen=True)
class FootShape:
    """A foot: a flat box whose bottom face is the sole plane, in the sole frame (m)."""

    length_m: float
    width_m: float
    thickness_m: float
    forward_m: float

    @property
    def size_m(self) -> tuple[float, float, float]:
        """Length (x), width (y), thickness (z) of the box (m)."""
        return self.length_m, self.width_m, self.thickness_m

    def sole_corners_m(self) -> np.ndarray:
        """The four corners (x, y, 0) of the sole in its own frame (m), counter-clockwise."""
        x0, x1 = self.forward_m - self.length_m / 2, self.forward_m + self.length_m / 2
        y = self.width_m / 2
        return np.array([[x0, -y, 0.0], [x1, -y, 0.0], [x1, y, 0.0], [x0, y, 0.0]])


@dataclass(frozen=True)
class EstimationConfig:
    """The estimation layer's settings (robot file's ``[estimation]``, see
    :mod:`hubo_cli.estimation`).

    Attributes:
        contact_threshold_n: a sole is loaded while its ankle's filtered F_z (the floor's
            force, the foot's weight removed) exceeds this (N).
        contact_cutoff_hz: the first-order low-pass of the ankles' F_z before the threshold.
        contact_release_s: a sole still counts as down this long after it was last loaded.
        com_velocity_cutoff_hz: the first-order low-pass of the CoM's differenced velocity.
        contact_loss_min_s: a foot out of contact longer than this counts as a contact loss
            (the capture-point monitor's and the balance report's count).
        anchor_switch_n: the floating base's anchor passes to the other sole in contact once
            that one carries this much more (compensated ankle F_z).
        anchor_cop_min_fz_n: a sole pressing less than this keeps its last centre of pressure
            (the floating base's rolling-edge check).
        flight_max_fz_n: neither sole pressing this much for ``flight_confirm_s`` is a flight
            (a landing's bounce, a jump): no sole holds the floating base then.
        flight_confirm_s: how long both soles must stay that light before it is a flight.
        zmp_sole_min_fz_n: a sole in contact pressing less than this adds no centre of
            pressure to the ZMP.
        swing_touchdown_n: a capture step's swing sole carrying this much has touched down.
        sole_damping_min_fz_n: the walking stabilizer damps a sole carrying more than this;
            lighter, the sole returns to the pattern.
        body_on_soles_weight_fraction: the soles carry the body while their F_z exceeds this
            share of its weight: only then do the standing balancer (the soles' moments) and
            the CoM stabilizer (the ZMP) use them.
    """

    contact_threshold_n: float = 25.0
    contact_cutoff_hz: float = 5.0
    contact_release_s: float = 0.05
    com_velocity_cutoff_hz: float = 4.0
    contact_loss_min_s: float = 0.02
    anchor_switch_n: float = 40.0
    anchor_cop_min_fz_n: float = 10.0
    flight_max_fz_n: float = 20.0
    flight_confirm_s: float = 0.03
    zmp_sole_min_fz_n: float = 1.0
    swing_touchdown_n: float = 60.0
    sole_damping_min_fz_n: float = 30.0
    body_on_soles_weight_fraction: float = 0.5


@dataclass(frozen=True)
class RobotModel:
    """A HUBO 2+ model for one parameter set and one limit set.

    Attributes:
        params_name: the parameter set's name (``as-built`` or ``table1``).
        lengths_m: link lengths in metres keyed as the paper names them (lA1 ... lE).
        limbs: limb name -> :class:`LimbSpec`.
        joint_names: all limb joints in robot order (right arm, left arm, right leg, left leg).
        drill: the drill's shape (:class:`DrillShape`).
        feet: the feet's shape (:class:`FootShape`).
        hardware_guards: the hardware driver's checks of the measured state (robot file's
            ``[hardware_guards]``, see :mod:`hubo_cli.drivers.servo_guard`).
        motors: the simulated daemon's motor constants (robot file's ``[motors]``, see
            :mod:`hubo_cli.drivers.hubo_ach_motors`).
        estimation: the estimation layer's settings (robot file's ``[estimation]``).
    """

    params_name: str
    limits_name: str
    lengths_m: dict[str, float]
    limbs: dict[str, LimbSpec]
    tools: dict[str, dict]
    hubo_ach: dict
    safety: dict
    control_period_s: float
    source: Path
    drill: DrillShape
    feet: FootShape
    hardware_guards: dict = field(default_factory=dict)
    motors: dict = field(default_factory=dict)
    estimation: EstimationConfig = field(default_factory=EstimationConfig)
    joint_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        names = tuple(j for limb in LIMB_NAMES for j in self.limbs[limb].joints)
        object.__setattr__(self, "joint_names", names)

    def with_limits(self, limits: str) -> RobotModel:
        """The same robot (this file, this parameter set) with the joint-limit set ``limits``."""
        return load_model(self.params_name, limits, self.source)

    def limb(self, name: str) -> LimbSpec:
        """Return one limb's spec; the error lists the limbs that exist."""
        try:
            return self.limbs[name]
        except KeyError:
            raise ConfigError(f"unknown limb {quoted(name)}",
                              hint=f"use one of {', '.join(LIMB_NAMES)}") from None

    def limb_slice(self, name: str) -> slice:
        """Where a limb's six joints sit in :attr:`joint_names`."""
        i = LIMB_NAMES.index(self.limb(name).name) * 6
        return slice(i, i + 6)

    def tool_transform(self, tool: str) -> np.ndarray:
        """T_6_tool: the tool frame seen from DH frame 6 of an arm (4x4, metres)."""
        if tool not in TOOL_NAMES:
            raise ConfigError(f"unknown tool {quoted(tool)}",
                              hint=f"use one of {', '.join(TOOL_NAMES)}")
        T = np.eye(4)
        spec = self.tools[tool]
        if tool == "hand":
            c, s = np.cos(spec["rx_rad"]), np.sin(spec["rx_rad"])
            T[1:3, 1:3] = [[c, -s], [s, c]]
        elif tool == "drill":
            phi = spec["phi_rad"]
            length_m = self.lengths_m[spec["length_param"]]
            c, s = np.cos(phi), np.sin(phi)
            T[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
            T[:3, 3] = [length_m * c, 0.0, -length_m * s]
        return T

    # The whole robot's limits in joint_names order: built once (the drivers clip every command
    # to them), read-only so that no caller can change the cached copy.
    def _all_limbs(self, per_limb) -> np.ndarray:
        values = np.concatenate([per_limb(self.limbs[n]) for n in LIMB_NAMES])
        values.flags.writeable = False
        return values

    @cached_property
    def lower_rad(self) -> np.ndarray:
        return self._all_limbs(lambda limb: limb.lower_rad)

    @cached_property
    def upper_rad(self) -> np.ndarray:
        return self._all_limbs(lambda limb: limb.upper_rad)

    @cached_property
    def velocity_rad_s(self) -> np.ndarray:
        return self._all_limbs(lambda limb: limb.velocity_rad_s)

    @cached_property
    def acceleration_rad_s2(self) -> np.ndarray:
        return self._all_limbs(lambda limb: limb.acceleration_rad_s2)

    @cached_property
    def jerk_rad_s3(self) -> np.ndarray:
        return self._all_limbs(lambda limb: limb.jerk_rad_s3)

    def urdf_path(self, drill: bool = False) -> Path:
        """Path of the robot's URDF (generated for the as-built set); ``drill``: the one with
        the drill (its body and 0.6 kg) on the right hand."""
        urdf = self.source.parent / self.raw_robot["urdf"]
        return urdf.with_name(urdf.stem + "-drill.urdf") if drill else urdf

    @property
    def raw_robot(self) -> dict:
        return _read_toml(self.source)["robot"]

    @property
    def raw_impedance(self) -> dict:
        """The robot file's ``[impedance]`` table (read by :mod:`hubo_cli.control.impedance`)."""
        return _read_toml(self.source).get("impedance", {})

    @property
    def impedance_max_offset_m(self) -> float:
        """The most the hand leaves its reference under the impedance (m; ``[impedance]
        max_offset_m``): the controller's clamp, and the yield a task's plunge keeps."""
        try:
            return float(self.raw_impedance["max_offset_m"])
        except (KeyError, TypeError, ValueError):
            raise ConfigError("[impedance] needs a number max_offset_m", path=str(self.source),
                              hint="the most the hand leaves its reference (m), e.g. 0.03"
                              ) from None

    @property
    def raw_estimation(self) -> dict:
        """The robot file's ``[estimation]`` table (read by :mod:`hubo_cli.estimation`)."""
        return _read_toml(self.source).get("estimation", {})

    @property
    def raw_walking(self) -> dict:
        """The robot file's ``[walking]`` table (read by :mod:`hubo_cli.walking.params`)."""
        return _read_toml(self.source).get("walking", {})

    def raw_table(self, name: str) -> dict:
        """The robot file's table ``[name]`` (empty when absent), for the modules that read
        their own parameters (``[lip_feedback]``, ``[wrench_distribution]``, ``[toe_heel]``)."""
        table = _read_toml(self.source).get(name, {})
        if not isinstance(table, dict):
            raise ConfigError("must be a table", path=str(self.source), field=name)
        return table


@cache
def _read_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from None


def _limb(name: str, raw: dict, override: dict | None, path: Path) -> LimbSpec:
    spec = dict(raw)
    if override:
        spec.update(override)
    try:
        lower = np.asarray(spec["lower_rad"], dtype=float)
        upper = np.asarray(spec["upper_rad"], dtype=float)
        joints = tuple(spec["joints"])
        ones = np.ones(6)
        limb = LimbSpec(name, joints, lower, upper, ones * float(spec["velocity_rad_s"]),
                        ones * float(spec["acceleration_rad_s2"]),
                        ones * float(spec["jerk_rad_s3"]))
    except KeyError as exc:
        raise ConfigError("missing key", path=str(path),
                          field=f"limbs.{name}.{exc.args[0]}") from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"not a number or a list of numbers: {exc}", path=str(path),
                          field=f"limbs.{name}") from None
    if len(joints) != 6 or lower.shape != (6,) or upper.shape != (6,) or not np.all(
            lower <= upper):  # a NaN limit compares false: no limit at all (review 22)
        raise ConfigError("needs six joints with lower <= upper limits", path=str(path),
                          field=f"limbs.{name}")
    if not np.all(np.abs(np.concatenate([lower, upper])) <= FULL_TURN_RAD):
        raise ConfigError(f"a limit beyond +-{FULL_TURN_RAD:.4g} rad (a full turn) or "
                          f"not finite: {lower.tolist()} .. {upper.tolist()}", path=str(path),
                          field=f"limbs.{name}", hint="limits are radians (Table IV's)")
    for key in ("velocity_rad_s", "acceleration_rad_s2", "jerk_rad_s3"):
        _positive(spec[key], path, f"limbs.{name}.{key}")  # the trackers divide by them
    return limb


def _positive(value, path: Path, field: str) -> float:
    """``value`` as a float if it is a finite positive number (a bool, a text or a NaN is not)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            math.isfinite(value) and value > 0):
        raise ConfigError(f"must be a positive number, got {quoted(value)}", path=str(path),
                          field=field)
    return float(value)


def _check_robot(raw: dict, path: Path, lengths: dict, limbs: dict) -> None:
    """What the rest of the robot file must hold before any part of hubo-cli reads it (review
    22: a NaN, a text or a missing key here was taken as it came, and a NaN wrist torque limit
    is a stop that never trips):

    - the control period: a positive number of at most MAX_CONTROL_PERIOD_S;
    - every length of the parameter set: a positive number (mm);
    - ``[safety]``: each of SAFETY_KEYS a positive number (the stops compare against them),
      the wrist torque limit and the stop's times at most SAFETY_MAX;
    - the hand's and the drill's frame angles within a turn; hubo-ach's start delay and filter;
    - the joints: 24 different names, each with its own hubo-ach index (an integer below
      ``joint_count``): two joints with one name or one index command one motor twice and
      another never."""
    period = _positive(raw["robot"].get("control_period_s"), path, "robot.control_period_s")
    if period > MAX_CONTROL_PERIOD_S:
        raise ConfigError(f"must be at most {MAX_CONTROL_PERIOD_S} s, got {period:g}",
                          path=str(path), field="robot.control_period_s",
                          hint="seconds: hubo-ach's loop is 0.005 (200 Hz)")
    for key, value in lengths.items():
        _positive(value, path, f"params.{key}")
    safety = raw.get("safety", {})
    for key in SAFETY_KEYS:
        if key not in safety:
            raise ConfigError("missing key", path=str(path), field=f"safety.{key}")
        value = _positive(safety[key], path, f"safety.{key}")
        most = SAFETY_MAX.get(key)
        if most is not None and value > most:
            raise ConfigError(f"must be at most {most:g}, got {value:g}", path=str(path),
                              field=f"safety.{key}", hint="a larger value is no stop on Hubo")
    names = [n for limb in limbs.values() for n in limb.joints]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(f"joint {', '.join(twice)} named in more than one place",
                          path=str(path), field="limbs", hint="each joint once, in one limb")
    tools = raw.get("tools", {})
    for tool, key in (("hand", "rx_rad"), ("drill", "phi_rad")):
        angle = tools.get(tool, {}).get(key)
        if isinstance(angle, bool) or not isinstance(angle, int | float) or not (
                abs(angle) <= FULL_TURN_RAD):
            raise ConfigError(f"must be an angle within a turn (rad), got {quoted(angle)}",
                              path=str(path), field=f"tools.{tool}.{key}")
    ach = raw.get("hubo_ach", {})
    _positive(ach.get("startup_ref_delay_s"), path, "hubo_ach.startup_ref_delay_s")
    taps = ach.get("ref_filter_length")
    if isinstance(taps, bool) or not isinstance(taps, int) or taps < 1:
        raise ConfigError(f"must be a whole number of taps, got {quoted(taps)}",
                          path=str(path), field="hubo_ach.ref_filter_length")
    index, count = ach.get("index", {}), ach.get("joint_count")
    for n in names:
        i = index.get(n)
        if isinstance(i, bool) or not isinstance(i, int) or not (
                isinstance(count, int) and 0 <= i < count):
            raise ConfigError(f"joint {n} needs an integer index below joint_count "
                              f"({quoted(count)}), got {quoted(i)}", path=str(path),
                              field="hubo_ach.index")
    shared = sorted({n for n in names if [index[m] for m in names].count(index[n]) > 1})
    if shared:
        raise ConfigError(f"joints {', '.join(shared)} share a hubo-ach index", path=str(path),
                          field="hubo_ach.index", hint="each joint its own index (hubo.h)")


def _shape(kind, raw: dict, table: str, path: Path):
    """A shape dataclass from the TOML table ``table`` (dotted): every field a positive number
    of metres or kilograms, except ``body_front_m`` (behind the bit's middle: negative)."""
    spec = raw
    for key in table.split("."):
        spec = spec.get(key, {})
    values = {}
    for f in fields(kind):
        if f.name not in spec:
            raise ConfigError("missing key", path=str(path), field=f"{table}.{f.name}")
        value = spec[f.name]
        sign = -1.0 if f.name == "body_front_m" else 1.0
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and sign * value > 0):  # infinite feet: no support edge
            raise ConfigError(f"must be a {'negative' if sign < 0 else 'positive'} number, "
                              f"got {quoted(value)}", path=str(path), field=f"{table}.{f.name}")
        values[f.name] = float(value)
    return kind(**values)


def _estimation(raw: dict, path: Path) -> EstimationConfig:
    """The ``[estimation]`` table's own keys: every field given, a positive number (the release
    time may be 0)."""
    table = {key: value for key, value in raw.get("estimation", {}).items()
             if not isinstance(value, dict)}  # sub-tables: their observers read them
    unknown = set(table) - {f.name for f in fields(EstimationConfig)}
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(sorted(unknown))}", path=str(path),
                          field="estimation",
                          hint=f"use {', '.join(f.name for f in fields(EstimationConfig))}")
    values = {}
    for f in fields(EstimationConfig):
        if f.name not in table:
            raise ConfigError("missing key", path=str(path), field=f"estimation.{f.name}")
        value = table[f.name]
        ok = (not isinstance(value, bool) and isinstance(value, int | float)
              and math.isfinite(value)
              and (value >= 0 if f.name == "contact_release_s" else value > 0)
              and (value <= 1 or not f.name.endswith("_fraction")))
        if not ok:
            what = "a share in (0, 1]" if f.name.endswith("_fraction") else "a positive number"
            raise ConfigError(f"must be {what}, got {quoted(value)}", path=str(path),
                              field=f"estimation.{f.name}")
        values[f.name] = float(value)
    return EstimationConfig(**values)


def load_model(params: str = "as-built", limits: str = "table4",
               path: Path | None = None) -> RobotModel:
    """Load the HUBO 2+ model (once per file, parameter set and limit set: the shipped file
    named or not is the same model).

    Args:
        params: kinematic parameter set, ``as-built`` (default) or ``table1``.
        limits: ``table4`` (the paper's Table IV) or ``team-code`` (arm joint 5 >= -2.0 rad).
        path: robot TOML file; defaults to the shipped ``robots/hubo2plus/hubo2plus.toml``.
    """
    return _load_model(params, limits, path or _shipped_file())


@cache
def _shipped_file() -> Path:
    return data_file("robots", "hubo2plus/hubo2plus.toml")


@cache
def _load_model(params: str, limits: str, path: Path) -> RobotModel:
    raw = _read_toml(path)
    sets = raw.get("params", {})
    if params not in sets:
        raise ConfigError(f"unknown parameter set {quoted(params)}", path=str(path),
                          hint=f"use one of {', '.join(sets)}")
    limit_sets = raw.get("limit_sets", {})
    if limits != "table4" and limits not in limit_sets:
        raise ConfigError(f"unknown limit set {quoted(limits)}", path=str(path),
                          hint=f"use one of table4, {', '.join(limit_sets)}")
    overrides = limit_sets.get(limits, {})
    limbs = {n: _limb(n, raw["limbs"][n], overrides.get(n), path) for n in LIMB_NAMES}
    _check_robot(raw, path, sets[params], limbs)
    lengths_m = {k: float(v) / 1000.0 for k, v in sets[params].items()}
    return RobotModel(params_name=params, limits_name=limits, lengths_m=lengths_m, limbs=limbs,
                      tools=raw["tools"], hubo_ach=raw["hubo_ach"], safety=raw["safety"],
                      control_period_s=float(raw["robot"]["control_period_s"]), source=path,
                      drill=_shape(DrillShape, raw, "tools.drill", path),
                      feet=_shape(FootShape, raw, "feet", path),
                      hardware_guards=raw.get("hardware_guards", {}),
                      motors=raw.get("motors", {}),
                      estimation=_estimation(raw, path))
