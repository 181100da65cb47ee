"""The task file format (``tasks/*.toml``) and its loader.

A task is data. Top level: ``name``, ``description`` (one line) and either ``steps`` (run by
the step runner, :mod:`hubo_cli.tasks.runner`) or ``experiment`` (a built-in procedure:
``push-wall``, ``turn-valve``, ``push-door``, given its ``[parameters]``). Tables:

``[parameters]``
    Named values with their defaults. Anywhere else in the file the string ``"$name"`` stands for
    the parameter's value; the command line overrides them (``--set name=value``). A dotted
    name sets a field of the ``stance``, ``scene`` or ``safety`` tables directly, checked as
    the file's own (``--set stance.start_mm=[-1000,0]``; lists in TOML's brackets).
``[stance]``
    ``wall_distance_mm`` (neck to wall face along x, or ``"auto"``: the workspace map's best
    distance for the tool held orthogonal to the wall), ``centre_mm`` ([y, z] of the work frame's
    origin in the stance frame, or ``"auto"``: centred in the reachable area), ``arm``
    (``right``), ``tool`` (``drill``), ``start_mm`` (optional [x, y]: the robot starts this far
    from the working stance, x forward and y left in the stance frame, and walks there first;
    [-1000, 0] is 1 m behind it).
``[scene.wall]``
    ``width_mm``, ``height_mm``, ``thickness_mm`` of the wall and ``misplaced_mm``: how much
    farther the simulated wall stands than the plan puts it (negative: nearer; default 0), a
    wall the robot's recognition misjudged (``[scene.cutting]``: the
    simulated material's reaction to the drill, any field of
    :class:`hubo_cli.scene.CuttingModel` by name: ``coulomb_n``, ``viscous_n_s_per_m``,
    ``thrust_n``, ``thrust_n_s_per_m``, ``spindle_torque_nm``, ``smooth_m_s``, and the drill's
    depth guide ``guide_depth_m``, ``guide_stiffness_n_m``, ``guide_damping_n_s_m``,
    ``guide_friction``).
``[safety]``
    ``estop_sources`` (of ``operator``, ``capture-point``, ``wrist-torque``,
    ``stale-input``; the first three always), ``wrist_torque_limit_nm`` (at most the robot
    file's), ``revert_s`` (T1), ``stop_s`` (T2) (at most the robot file's ``estop_revert_s``,
    ``estop_stop_s``). A file or ``--set`` only tightens these; a
    stop source is removed on the command line alone (``--estop-sources``, ``--no-estop``).
``[[steps]]``
    In order, each with a ``kind`` and an optional ``name``:

    - ``move``: the tool to ``to_mm`` = [y, z] in the wall frame (omitted: the start of the next
      ``follow``), ``depth_mm`` from the wall face (negative: in front of it), taking
      ``duration_s`` or at ``speed_mm_s``. The first step must be a move; it runs in joint space
      from the start posture and the wall appears once the robot holds the tool there.
    - ``plunge``: straight along the bit to ``depth_mm`` at ``speed_mm_s``; with the drill
      (and for a ``retract``) at most the drill body's distance behind the bit's middle less
      the impedance's ``max_offset_m`` (60 mm on the shipped robot); with the hand, at most
      where its front meets the face (-14.35 mm: it cuts nothing; ``thrust_n`` presses).
    - ``follow``: cut along a path in the wall plane at ``speed_mm_s`` (speeding up and slowing
      down at each corner at ``accel_mm_s2``, default 50): ``path = "rectangle"``
      (``width_mm``, ``height_mm``, ``centre_mm`` = [y, z], ``start`` = ``upper-left`` |
      ``upper-right`` | ``lower-left`` | ``lower-right``, ``direction`` = ``ccw`` | ``cw``, as
      seen from behind the robot) or ``path = "polyline"`` (``points_mm`` = [[y, z], ...]).
    - ``retract``: straight back along the bit to ``depth_mm`` at ``speed_mm_s``.
    - ``wait``: hold still for ``duration_s``.

    ``plunge``, ``follow`` and ``wait`` take an optional ``thrust_n``: the force (N, > 0) with
    which the tool presses into the wall along the bit during the step (default 0: position
    control only). A task with a thrust runs the hand under force control: the
    ImpedanceController yields along the bit and holds the measured thrust at the step's, so
    the depth follows the wall rather than the plan (a wall nearer or farther than planned is
    still cut); across the bit the tool keeps its path. The reference ramps over
    ``FORCE_RAMP_S`` at each change and is 0 outside these steps.

Frames: the wall frame W has its origin on the wall face at ``centre_mm``, x into the wall
(the bit's direction), y to the robot's left and z up, parallel to the stance frame S (the home
neck frame). Lengths are in millimetres in the file and metres in the objects built from it.
A malformed file raises :class:`~hubo_cli.errors.ConfigError` naming the file, the line and the
field (``steps[3].speed_mm_s``: steps are numbered from 1, as ``hubo task show`` lists them).
"""

from __future__ import annotations

import errno
import math
import os
import stat
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

from hubo_cli.control.stop_choice import SOFT_SOURCES, TASK_SOURCES, stops_words
from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import STOP_MAX_S, WRIST_TORQUE_MAX_NM
from hubo_cli.resources import data_dir
from hubo_cli.scene import CuttingModel
from hubo_cli.streams import open_nonblocking, reader_of
from hubo_cli.tasks.toml_lines import field_line
from hubo_cli.tasks.tool import tool_front_m

if TYPE_CHECKING:
    from hubo_cli.model import RobotModel

STEP_KINDS = ("move", "plunge", "follow", "retract", "wait")
ESTOP_SOURCES = SOFT_SOURCES
CORNERS = {"upper-left": (1, 1), "upper-right": (-1, 1), "lower-left": (1, -1),
           "lower-right": (-1, -1)}  # (sign of y, sign of z): the robot's left is +y
# The built-in experiments and the parameters each one's procedure reads (tasks.runner and
# experiments.manipulation read them): a file declaring another would set nothing, unseen
# (review 28: push-door's wrist_torque_limit_nm = 0.1 and a misspelt door_dge ran as defaults).
EXPERIMENT_PARAMETERS = {"push-wall": ("direction", "interpolator", "estop"),
                         "turn-valve": ("seen_offset_mm", "turn_deg", "impedance", "estop"),
                         "push-door": ("door_opens", "door_deg", "impedance", "estop")}
EXPERIMENTS = tuple(EXPERIMENT_PARAMETERS)
# Physical sense, checked at load time (a value beyond these is a typo, not a task): no Hubo arm
# reaches further than about 0.6 m from its shoulder, so no path spans more than LENGTH_MAX_MM;
# its 1 rad/s joints move the tool at about 0.5 m/s at most; steps and stops are short.
LENGTH_MAX_MM = 1000.0       # sizes, positions and depths in the wall frame (mm)
TOOL_MASS_MAX_KG = 3.0  # a tool's mass: the arm's payload (Hubo 2+'s hand lifts about 2 kg)
TOOL_SPEED_MAX_MM_S = 500.0  # tool speed: the arm's 1 rad/s joints at its 0.5 m reach
# the slowest tool speed: at 0.1 mm/s a task's whole 30 minutes (PLAN_MAX_S) cover 180 mm, the
# shipped tasks' 500 mm cut alone takes 83 minutes; the paper's operator cut at about 10 mm/s
TOOL_SPEED_MIN_MM_S = 0.1
TOOL_ACCEL_MAX_MM_S2 = 2000.0
# and the gentlest ramp: the slowest speed in a second (review 28: 5e-324 mm/s^2 passed as
# positive, became 0 m/s^2 and the planner took its default instead)
TOOL_ACCEL_MIN_MM_S2 = TOOL_SPEED_MIN_MM_S
STEP_MAX_S = 600.0           # one move or wait
WALL_MAX_MM = 10000.0
THRUST_MAX_N = 15.0          # the impedance spring's 500 N/m over its 30 mm offset limit
MISPLACED_MAX_MM = 100.0     # a wall misjudged by more is not a recognition error to test
MAX_TASK_BYTES = 1 << 20      # a task file is a few kB of TOML
START_MAX_MM = 10000.0       # a walk to the working stance (``hubo walk``'s longest goal)
# Lower bounds, where physics gives one (a value below is most often a size written in metres):
# a drilled hole or slot is at least the bit's diameter across (the robot file's bit_radius_m),
# and a wall thinner than WALL_THICKNESS_MIN_MM is a sheet of paper, not cardboard to drill
# (single-wall corrugated board is 1 to 7 mm; the shipped tasks' is 5 mm).
WALL_THICKNESS_MIN_MM = 0.5
UNITS_HINT = "units? values are in mm"
_NO_ESTOP_HINT = "to run without the stopper, say so on the command line: --no-estop"


# ---------------------------------------------------------------------------- the objects
@dataclass(frozen=True)
class Stance:
    """Where the robot stands relative to the wall.

    Attributes:
        wall_distance_m: neck to wall face along x (m); None = auto.
        centre_m: (y, z) of the wall frame's origin in S (m); None = auto.
        arm: ``right`` or ``left``; tool: the arm's tool (``drill``, ``hand``).
        start_m: (x, y) of where the robot starts, in the working stance's frame (m; x
            forward, y left); None = it starts on the working stance.
        tool_mass_kg: the drill as weighed (kg; ``tool_mass_kg``); None = the robot file's
            ``[tools.drill] mass_kg``. The wrist's force estimate removes this weight.
    """

    wall_distance_m: float | None
    centre_m: tuple[float, float] | None
    arm: str = "right"
    tool: str = "drill"
    start_m: tuple[float, float] | None = None
    tool_mass_kg: float | None = None

    @property
    def limb(self) -> str:
        return f"{self.arm}-arm"


@dataclass(frozen=True)
class Scene:
    """The wall (m), the material's reaction to the drill, and how much farther the wall
    stands than the plan puts it (m; negative: nearer)."""

    wall_width_m: float = 1.2
    wall_height_m: float = 2.0
    wall_thickness_m: float = 0.005
    cutting: CuttingModel = field(default_factory=CuttingModel)
    wall_misplaced_m: float = 0.0


@dataclass(frozen=True)
class Safety:
    """Emergency-stop settings: enabled sources, wrist torque threshold (N m), T1 and T2 (s)."""

    estop_sources: tuple[str, ...] = TASK_SOURCES
    wrist_torque_limit_nm: float = 1.21  # the loader's default is the robot file's
    revert_s: float = 0.5
    stop_s: float = 0.5


@dataclass(frozen=True)
class Step:
    """One step of a task (positions in the wall frame W, m; see the module docstring).

    Attributes:
        kind: one of STEP_KINDS.
        name: what the user calls it.
        number: 1-based position in the task.
        to_m: move: (y, z) target, None = the start of the next follow.
        depth_m: move/plunge/retract: the tool's depth past the wall face (negative: before it).
        points_m: follow: the path's corners (y, z).
        speed_m_s: move (optional), plunge, follow, retract.
        accel_m_s2: follow: the bit's acceleration at each corner (None: the planner's).
        duration_s: move (optional), wait.
        thrust_n: plunge, follow, wait: the force the tool presses into the wall with (N;
            0: position control).
        path: follow: ``rectangle`` or ``polyline`` (what the file said, for ``show``).
        shape: follow rectangle: width, height, start, direction (for ``show``).
    """

    kind: str
    name: str
    number: int
    to_m: tuple[float, float] | None = None
    depth_m: float | None = None
    points_m: tuple[tuple[float, float], ...] = ()
    speed_m_s: float | None = None
    accel_m_s2: float | None = None
    duration_s: float | None = None
    thrust_n: float = 0.0
    path: str = ""
    shape: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"step {self.number} '{self.name}'"

    def describe(self) -> str:
        """One line for ``hubo task show`` (mm, mm/s, s)."""
        def mm(v: float) -> str:
            return f"{v * 1000:g}"

        def at() -> str:
            if self.speed_m_s is not None:
                return f" at {mm(self.speed_m_s)} mm/s"
            return f" in {self.duration_s:g} s"

        pressing = f", pressing {self.thrust_n:g} N" if self.thrust_n else ""
        if self.kind == "move":
            where = ("the start of the next path" if self.to_m is None
                     else f"y {mm(self.to_m[0])}, z {mm(self.to_m[1])} mm")
            return f"move the tool to {where}, depth {mm(self.depth_m)} mm{at()}"
        if self.kind in ("plunge", "retract"):
            return f"{self.kind} to depth {mm(self.depth_m)} mm{at()}{pressing}"
        if self.kind == "follow":
            if self.path == "rectangle":
                s = self.shape
                what = (f"rectangle {mm(s['width_m'])} x {mm(s['height_m'])} mm from the "
                        f"{s['start']} corner, {s['direction']}")
            else:
                what = f"polyline of {len(self.points_m)} points"
            return f"cut along a {what}{at()}{pressing}"
        return f"wait {self.duration_s:g} s{pressing}"


@dataclass(frozen=True)
class TaskSpec:
    """A loaded task: its source file, resolved parameters and parts (see the module docstring)."""

    name: str
    description: str
    path: Path
    parameters: dict
    defaults: dict
    stance: Stance = field(default_factory=lambda: Stance(None, None))
    scene: Scene = field(default_factory=Scene)
    safety: Safety = field(default_factory=Safety)
    steps: tuple[Step, ...] = ()
    experiment: str | None = None
    fields_set: dict = field(default_factory=dict)
    text: str = field(default="", repr=False)  # the file as read (a FIFO can be read only once)

    @property
    def overridden(self) -> dict:
        """Parameters whose value differs from the file's default, then the fields set from
        the command line (``--set stance.start_mm=[-1000,0]``)."""
        changed = {k: v for k, v in self.parameters.items() if self.defaults.get(k) != v}
        return changed | self.fields_set


# ---------------------------------------------------------------------------- loading
def task_files() -> list[Path]:
    """The shipped task files, sorted by name."""
    return sorted(data_dir("tasks").glob("*.toml"))


def find_task(name_or_path: str | Path) -> Path:
    """A task file from a path or a shipped task's name (``cut-rectangle``)."""
    if not str(name_or_path).strip():  # Path('') is the current folder
        raise ConfigError("no task given (an empty name)",
                          hint="give a .toml file or a shipped task's name (hubo task list)")
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            mode = path.stat().st_mode
        except OSError as exc:
            why = ("no such task file" if exc.errno == errno.ENOENT
                   else f"cannot read the task file: {exc.strerror or exc}")
            raise ConfigError(why, path=str(path),
                              hint="give a .toml file or a shipped task's name (hubo task list)"
                              ) from None
        if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):  # a FIFO is read once
            what = ("a folder" if stat.S_ISDIR(mode) else
                    "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a socket")
            raise ConfigError(f"{what}, not a task file", path=str(path),
                              hint="give a .toml file or a shipped task's name (hubo task list)")
        return path
    for candidate in task_files():
        if candidate.stem == str(name_or_path):
            return candidate
    names = ", ".join(p.stem for p in task_files())
    raise ConfigError(f"no shipped task called {quoted(str(name_or_path))}",
                      hint=f"shipped tasks: {names}; or give a .toml file")


def load_task(name_or_path: str | Path, overrides: dict | None = None, *,
              sources_on_command_line: bool = False,
              model: RobotModel | None = None) -> TaskSpec:
    """Read, check and resolve a task file (:func:`read_task`, then :func:`parse_task`) for
    the robot ``model`` the task will run on (default: the shipped robot file's).

    Raises:
        ConfigError: the file is missing or malformed (file, line, field and a hint).
    """
    return parse_task(*read_task(name_or_path), overrides,
                      sources_on_command_line=sources_on_command_line, model=model)


def read_task(name_or_path: str | Path) -> tuple[Path, str]:
    """A task file's path and text, read once (a FIFO gives its text only once), never
    waiting on a silent one for more than :data:`~hubo_cli.streams.STREAM_WAIT_S`.

    Args:
        name_or_path: a ``.toml`` file or the name of a shipped task.

    Raises:
        ConfigError: the file is missing, not a file, too large, not text or unreadable.
    """
    path = find_task(name_or_path)
    try:
        fd = open_nonblocking(path)
        try:
            blob = reader_of(fd, path)(MAX_TASK_BYTES + 1)
        finally:
            os.close(fd)
        if len(blob) > MAX_TASK_BYTES:
            raise ConfigError(f"larger than {MAX_TASK_BYTES >> 20} MiB: not a task file",
                              path=str(path), hint="a task file is a page of TOML; see "
                                                   "tasks/README.md")
        text = blob.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file (byte {exc.start} is not UTF-8)", path=str(path),
                          hint="a task file is TOML text; see tasks/README.md") from None
    except OSError as exc:
        raise ConfigError(f"cannot read the task file: {exc.strerror or exc}", path=str(path),
                          hint="check the path and its permissions") from None
    return path, text.removeprefix("\ufeff")  # the byte-order mark some Windows editors write


def parse_task(path: Path, text: str, overrides: dict | None = None, *,
               sources_on_command_line: bool = False,
               model: RobotModel | None = None) -> TaskSpec:
    """Check and resolve a task file's text (read by :func:`read_task` from ``path``, which
    errors name).

    Args:
        path, text: the file and what it held.
        overrides: parameter name -> value (strings from the command line are converted to the
            default's type; ``auto`` stays a string).
        sources_on_command_line: ``--estop-sources`` or ``--no-estop`` chooses the run's stop
            sources, so the file's list may lack some (a task file as run records them so);
            the run keeps the command line's, removing sources from the task's baseline.
        model: the robot the task will run on, whose file bounds the task's (the drill bit's
            diameter, the stop settings); default: the shipped robot file's.

    Raises:
        ConfigError: the text is malformed (file, line, field and a hint).
    """
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ConfigError("not valid TOML: arrays or tables nested too deeply", path=str(path),
                          hint="a task file nests a few levels at most; see tasks/README.md"
                          ) from None
    except tomllib.TOMLDecodeError as exc:  # before ValueError: it is one
        line = None
        message = str(exc)
        if "(at line " in message:
            line = int(message.split("(at line ")[1].split(",")[0].rstrip(")"))
            message = message.split(" (at line ")[0]
        raise ConfigError(f"not valid TOML: {message}", path=str(path), line=line,
                          hint="check the quotes, brackets and '=' on that line") from None
    except ValueError:  # Python reads no integer of more than 4300 digits
        raise ConfigError("not valid TOML: an integer too long to read", path=str(path),
                          hint="a task file's numbers are a few digits long") from None
    return _Loader(path, text, data, overrides or {}, sources_on_command_line, model).task()


FIELD_TABLES = ("stance", "scene", "safety")  # what a dotted ``--set`` name may reach


def parse_override(text: str) -> tuple[str, object]:
    """``name=value`` from ``--set`` (value: number, true/false, a TOML list ``[a, b]``, or
    text)."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise ConfigError(f"--set {quoted(text)} is not NAME=VALUE",
                          hint="e.g. --set speed_mm_s=20 (see hubo task show NAME)")
    return name.strip(), _scalar(value.strip())


def format_override(value: object) -> str:
    """A value as ``--set`` reads it back (lists without spaces, so no quoting is needed)."""
    if isinstance(value, list):
        return "[" + ",".join(format_override(v) for v in value) + "]"
    if isinstance(value, bool):
        return str(value).lower()
    return str(value)


def _scalar(value: str) -> object:
    if value.startswith("["):
        try:
            return tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:  # before ValueError: it is one
            raise ConfigError(f"--set value {quoted(value)} is not a list",
                              hint="write lists as in TOML, e.g. [-1000, 0]") from None
        except RecursionError:
            raise ConfigError(f"--set value {quoted(value)}: lists nested too deeply",
                              hint="a parameter's list nests a level or two") from None
        except ValueError:  # Python reads no integer of more than 4300 digits
            raise ConfigError(f"--set value {quoted(value)}: an integer too long to read",
                              hint="write numbers of a few digits") from None
    lowered = value.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return float(value)
    except ValueError:
        return value


class _Loader:
    """Checks one parsed file field by field, so each error can point at its line."""

    def __init__(self, path: Path, text: str, data: dict, overrides: dict,
                 sources_on_command_line: bool = False, model: RobotModel | None = None) -> None:
        self.path = path
        self._robot = model
        self.sources_on_command_line = sources_on_command_line
        self.text = text
        self.data = data
        self.overrides = {k: v for k, v in overrides.items() if "." not in k}
        self.fields_set = {k: v for k, v in overrides.items() if "." in k}
        self.origin: dict[str, str] = {}  # field -> parameter it came from
        self.tool = "drill"

    # ------------------------------------------------------------------ errors
    def fail(self, field_path: str, message: str, hint: str = "") -> ConfigError:
        parameter = self.origin.get(field_path)
        if parameter is not None:
            source = ("set on the command line"
                      if parameter in self.overrides or parameter in self.fields_set
                      else "the file's default")
            message += f" (from parameter {parameter}, {source})"
        return ConfigError(message, path=str(self.path), line=field_line(self.text, field_path),
                           field=field_path, hint=hint)

    def _at_least(self, t: _Table, name: str, value_mm: float, minimum_mm: float,
                  what: str) -> float:
        """``value_mm``, refused below the physical ``minimum_mm`` (exit 2, the units hint)."""
        if value_mm < minimum_mm:
            raise self.fail(t.key(name), f"{quoted(value_mm)} mm is below {what} "
                            f"({minimum_mm:g} mm)", hint=UNITS_HINT)
        return value_mm

    def _model(self) -> RobotModel:
        """The robot the task will run on: the one given, else the shipped robot file's."""
        from hubo_cli.model import load_model

        return load_model() if self._robot is None else self._robot

    def _bit_mm(self) -> float | None:
        """The drill bit's diameter (mm, the robot file's); None for a task with the hand."""
        if self.tool != "drill":
            return None
        return 2000.0 * self._model().drill.bit_radius_m

    # ------------------------------------------------------------------ parameters
    def _parameters(self) -> tuple[dict, dict]:
        defaults = self.data.get("parameters", {})
        if not isinstance(defaults, dict):
            raise self.fail("parameters", "must be a table of name = default value")
        values = dict(defaults)
        for name, value in self.overrides.items():
            if name not in defaults:
                known = ", ".join(defaults) or "none"
                raise ConfigError(f"the task has no parameter {quoted(name)}", path=str(self.path),
                                  hint=f"its parameters: {known}")
            default = defaults[name]
            if isinstance(value, str):
                value = _scalar(value)
            if isinstance(default, bool) and not isinstance(value, bool):
                raise ConfigError(f"parameter {name} must be true or false, got {quoted(value)}",
                                  path=str(self.path), hint=f"e.g. --set {name}=false")
            values[name] = value
        return defaults, values

    def _substitute(self, value, where: str, params: dict):
        if isinstance(value, str) and value.startswith("$"):
            name = value[1:]
            if name not in params:
                raise self.fail(where, f"refers to an unknown parameter {quoted(value)}",
                                hint=f"declare it under [parameters]; known: "
                                     f"{', '.join(params) or 'none'}")
            self.origin[where] = name
            return params[name]
        if isinstance(value, dict):
            return {k: self._substitute(v, f"{where}.{k}" if where else k, params)
                    for k, v in value.items()}
        if isinstance(value, list):
            return [self._substitute(v, f"{where}[{i}]" if isinstance(v, dict) else where,
                                     params) for i, v in enumerate(value, start=1)]
        return value

    def _set_fields(self, body: dict) -> dict:
        """The file's tables with the dotted ``--set`` names applied (checked later as the
        file's own fields are)."""
        for name, value in self.fields_set.items():
            parts = name.split(".")
            if parts[0] not in FIELD_TABLES or not all(parts):
                raise ConfigError(f"--set {name}: only fields of the {', '.join(FIELD_TABLES)} "
                                  "tables can be set by name", path=str(self.path),
                                  hint="e.g. --set stance.start_mm=[-1000,0]")
            table = body
            for part in parts[:-1]:
                inner = table.setdefault(part, {})
                if not isinstance(inner, dict):
                    raise ConfigError(f"--set {name}: {part} is not a table",
                                      path=str(self.path))
                table = inner
            if isinstance(value, str):
                value = _scalar(value)
            table[parts[-1]] = value
            self.origin[name] = name  # errors in it say it was set on the command line
        return body

    # ------------------------------------------------------------------ the whole file
    def task(self) -> TaskSpec:
        defaults, params = self._parameters()
        body = {k: v for k, v in self.data.items() if k != "parameters"}
        body = self._set_fields(self._substitute(body, "", params))
        if "experiment" not in body:  # an experiment's procedure reads its parameters itself
            used = set(self.origin.values())
            unused = [name for name in self.overrides if name not in used]
            if unused:
                raise ConfigError(f"the task declares parameter {quoted(unused[0])} but never uses "
                                  "it: setting it would change nothing", path=str(self.path),
                                  hint="leave it out (hubo task show NAME lists what each "
                                       "step uses)")
        table = _Table(self, "", body)
        name = table.text("name", default=self.path.stem)
        description = table.text("description", default="")
        experiment = table.text("experiment", default=None)
        if experiment is not None:
            if experiment not in EXPERIMENTS:
                raise self.fail("experiment", f"unknown experiment {quoted(experiment)}",
                                hint=f"use one of {', '.join(EXPERIMENTS)}")
            known = EXPERIMENT_PARAMETERS[experiment]
            for param in params:
                if param not in known:
                    raise ConfigError(f"the {experiment} experiment reads no parameter "
                                      f"{quoted(param)}: setting it would change nothing",
                                      path=str(self.path),
                                      line=field_line(self.text, f"parameters.{param}"),
                                      field=f"parameters.{param}",
                                      hint=f"its parameters: {', '.join(known)}")
            if not isinstance(params.get("estop", True), bool):
                raise ConfigError(f"parameter estop must be true or false, got "
                                  f"{quoted(params['estop'])}", path=str(self.path),
                                  line=field_line(self.text, "parameters.estop"),
                                  field="parameters.estop", hint=f"estop = true (a TOML "
                                  f"boolean); {_NO_ESTOP_HINT}")
            if params.get("estop", True) is not True:  # only the command line turns it off
                where = ("set on the command line" if "estop" in self.overrides
                         else "in the task file")
                raise ConfigError(f"parameter estop = {format_override(params['estop'])} ({where}) "
                                  "would turn the emergency stopper off", path=str(self.path),
                                  line=field_line(self.text, "parameters.estop"),
                                  field="parameters.estop", hint=f"leave it true; {_NO_ESTOP_HINT}")
            table.finish()
            return TaskSpec(name, description, self.path, params, defaults,
                            experiment=experiment, text=self.text)
        stance = self._stance(table.table("stance"))
        scene = self._scene(table.table("scene"))
        safety = self._safety(table.table("safety"))
        steps = self._steps(table.list_of_tables("steps"))
        self._paths_fit(scene, steps)
        table.finish()
        return TaskSpec(name, description, self.path, params, defaults, stance, scene, safety,
                        steps, fields_set=dict(self.fields_set), text=self.text)

    def _paths_fit(self, scene: Scene, steps: tuple[Step, ...]) -> None:
        """Each path's extent fits on the wall (its width, and its height from the floor)."""
        for step in steps:
            if not step.points_m:
                continue
            ys, zs = zip(*step.points_m, strict=True)
            for name, size_m, extent_m, across in (
                    ("width_mm", scene.wall_width_m, max(ys) - min(ys), "across"),
                    ("height_mm", scene.wall_height_m, max(zs) - min(zs), "high")):
                if size_m < extent_m:
                    raise self.fail(f"scene.wall.{name}", f"{size_m * 1000:g} mm is less "
                                    f"than the path of {step.label} ({extent_m * 1000:g} "
                                    f"mm {across})", hint=UNITS_HINT)

    def _stance(self, t: _Table) -> Stance:
        from hubo_cli.urdf import torso_front_m

        distance = t.number_or_auto("wall_distance_mm", positive=True, maximum=LENGTH_MAX_MM)
        if distance is not None:  # a nearer wall passes through the robot's chest
            self._at_least(t, "wall_distance_mm", distance, 1000 * torso_front_m(),
                           "the front of the robot's chest")
        centre = t.point_or_auto("centre_mm")
        arm = t.choice("arm", ("right", "left"), default="right")
        tool = t.choice("tool", ("drill", "hand"), default="drill")
        if tool == "drill" and arm != "right":
            raise self.fail(t.key("tool"), "the drill is mounted on the right hand",
                            hint='use arm = "right" or tool = "hand"')
        tool_mass = t.number("tool_mass_kg", positive=True, maximum=TOOL_MASS_MAX_KG,
                             default=None)
        if tool_mass is not None and tool != "drill":
            raise self.fail(t.key("tool_mass_kg"), "is the drill's mass; the hand holds none",
                            hint='use tool = "drill" or leave tool_mass_kg out')
        self.tool = tool  # the steps' lower bounds depend on it
        start = t.value("start_mm", default=None)
        if start is not None and not (_is_point(start)
                                      and math.hypot(*start) <= START_MAX_MM):
            raise self.fail(t.key("start_mm"), f"must be [x, y] in mm within "
                            f"{START_MAX_MM:g} mm of the working stance, got {quoted(start)}",
                            hint="e.g. start_mm = [-1000, 0] (1 m behind it)")
        t.finish()
        return Stance(None if distance is None else distance / 1000,
                      None if centre is None else (centre[0] / 1000, centre[1] / 1000), arm, tool,
                      None if start is None else (start[0] / 1000, start[1] / 1000),
                      tool_mass)

    def _scene(self, t: _Table) -> Scene:
        wall = t.table("wall")
        cutting = t.table("cutting")
        d = Scene()
        scene = Scene(
            wall_width_m=wall.number("width_mm", positive=True, maximum=WALL_MAX_MM,
                                     default=d.wall_width_m * 1000) / 1000,
            wall_height_m=wall.number("height_mm", positive=True, maximum=WALL_MAX_MM,
                                      default=d.wall_height_m * 1000) / 1000,
            wall_thickness_m=self._at_least(
                wall, "thickness_mm", wall.number("thickness_mm", positive=True,
                                                  maximum=LENGTH_MAX_MM,
                                                  default=d.wall_thickness_m * 1000),
                WALL_THICKNESS_MIN_MM, "the thinnest cardboard") / 1000,
            cutting=CuttingModel(**{
                f.name: cutting.number(f.name, minimum=0.0, positive=f.metadata["positive"],
                                       maximum=f.metadata["maximum"],
                                       default=f.default)
                for f in fields(CuttingModel)}),
            wall_misplaced_m=wall.number("misplaced_mm", minimum=-MISPLACED_MAX_MM,
                                         maximum=MISPLACED_MAX_MM, default=0.0) / 1000)
        wall.finish()
        cutting.finish()
        t.finish()
        return scene

    def _safety(self, t: _Table) -> Safety:
        """The file's stop settings, which may only tighten the robot's (more sources, a
        lower wrist-torque limit): removing a stop is the command line's choice alone
        (:mod:`hubo_cli.control.stop_choice`)."""
        d = Safety()
        sources = t.value("estop_sources", default=list(d.estop_sources))
        if not isinstance(sources, list) or any(s not in ESTOP_SOURCES for s in sources):
            raise self.fail(t.key("estop_sources"), f"must be a list of sources, got "
                            f"{quoted(sources)}",
                            hint=f"choose from {', '.join(ESTOP_SOURCES)}")
        missing = [s for s in TASK_SOURCES if s not in sources]
        if missing and not self.sources_on_command_line:
            kept = ",".join(s for s in ESTOP_SOURCES if s in sources) or "none"
            raise self.fail(t.key("estop_sources"), f"a task may add stop sources but not "
                            f"remove the {stops_words(missing)}",
                            hint=f"to run without the {stops_words(missing)}, say so on "
                                 f"hubo task's command line: --estop-sources {kept} (a "
                                 f"sweep keeps every stop)")
        robot = self._model().safety
        # field, unit, sense bound, its robot file key (the most a task may give), words
        at_most = (("wrist_torque_limit_nm", "N m", WRIST_TORQUE_MAX_NM, "wrist_torque_limit_nm",
                    "limit", "lower it"),
                   ("revert_s", "s", STOP_MAX_S, "estop_revert_s", "T1",
                    "shorten it: a longer one reverts further back"),
                   ("stop_s", "s", STOP_MAX_S, "estop_stop_s", "T2",
                    "shorten it: a longer one is a slower stop"))
        values = []
        for name, unit, maximum, robot_key, what, rule in at_most:
            robot_value = float(robot[robot_key])
            value = float(t.number(name, positive=True, maximum=maximum, default=robot_value))
            if value > robot_value:  # repr: the shortest text that tells two floats apart
                raise self.fail(t.key(name), f"{quoted(value)} {unit} is above the robot file's "
                                f"{what} of {quoted(robot_value)} {unit}: a task may only {rule}",
                                hint=f"give at most {quoted(robot_value)}, or leave it out")
            values.append(value)
        safety = Safety(tuple(s for s in ESTOP_SOURCES if s in sources), *values)
        t.finish()
        return safety

    def _steps(self, tables: list[_Table]) -> tuple[Step, ...]:
        if not tables:
            raise self.fail("steps", "the task has no steps",
                            hint="add [[steps]] tables (kind = move, plunge, follow, ...)")
        steps = []
        for number, t in enumerate(tables, start=1):
            kind = t.choice("kind", STEP_KINDS)
            name = t.text("name", default=kind)
            if number == 1 and kind != "move":
                raise self.fail(t.key("kind"), "the first step must be a move",
                                hint="it brings the tool up to the wall from the start posture")
            steps.append(getattr(self, f"_{kind}")(t, kind, name, number))
            t.finish()
        return tuple(steps)

    @staticmethod
    def _timing(t: _Table) -> tuple[float | None, float | None]:
        speed = t.number("speed_mm_s", minimum=TOOL_SPEED_MIN_MM_S, maximum=TOOL_SPEED_MAX_MM_S,
                         default=None)
        duration = t.number("duration_s", positive=True, maximum=STEP_MAX_S, default=None)
        if (speed is None) == (duration is None):
            raise t.loader.fail(t.key("speed_mm_s"), "give exactly one of speed_mm_s or "
                                                     "duration_s", hint="e.g. speed_mm_s = 20")
        return None if speed is None else speed / 1000, duration

    def _move(self, t: _Table, kind: str, name: str, number: int) -> Step:
        to = t.point("to_mm", default=None)
        depth = t.number("depth_mm", minimum=-LENGTH_MAX_MM, maximum=LENGTH_MAX_MM)
        speed, duration = self._timing(t)
        return Step(kind, name, number, to_m=None if to is None else (to[0] / 1000, to[1] / 1000),
                    depth_m=depth / 1000, speed_m_s=speed, duration_s=duration)

    def _retract(self, t: _Table, kind: str, name: str, number: int) -> Step:
        depth = t.number("depth_mm", minimum=-LENGTH_MAX_MM, maximum=LENGTH_MAX_MM)
        self._within_tool(t, f"step {number} {quoted(name)} (a {kind})", kind, depth)
        return Step(kind, name, number, depth_m=depth / 1000,
                    speed_m_s=t.number("speed_mm_s", minimum=TOOL_SPEED_MIN_MM_S,
                                       maximum=TOOL_SPEED_MAX_MM_S) / 1000)

    def _within_tool(self, t: _Table, label: str, kind: str, depth_mm: float) -> None:
        """Refuse a plunge or retract deeper than the task's tool allows (exit 2), judged
        against the robot file the task runs on.

        The drill's bit cuts through the wall: past ``depth_max_mm`` its body would come
        nearer the wall face than the hand may yield along the bit under a thrust (the robot
        file's ``[impedance] max_offset_m``). The hand cuts nothing: its front
        (:func:`~hubo_cli.tasks.tool.tool_front_m` ahead of the hand point) stops on the face.
        Planned past it, a position-only hand pushes the arm's stiffness into the wall (review
        21's 60 mm plunge latched the wrist-torque stop on contact); a hand pressing with a
        thrust meets the face wherever it is (force tracking carries it up to that same yield
        past its plan), and a plan past the face only spends the yield kept for a wall nearer
        than planned.
        """
        model = self._model()
        yield_mm = 1000.0 * model.impedance_max_offset_m
        if self.tool == "drill":
            drill = model.drill
            face_mm = -1000.0 * drill.body_front_m  # the depth at which the body meets the face
            depth_max_mm = round(face_mm - yield_mm, 6)
            why = (f"the drill's body meets the wall face at {face_mm:g}: the bit's "
                   f"{1000 * drill.bit_out_m:g} mm out of the chuck less the "
                   f"{1000 * drill.bit_tip_m:g} mm past its middle; less the {yield_mm:g} mm the "
                   "hand may yield along the bit under a thrust")
            tool, remedy = "the bit", (", or fit a longer bit (the robot file's "
                                       "[tools.drill] body_front_m)")
        else:
            front_mm = 1000.0 * tool_front_m(self.tool, model)
            depth_max_mm = round(-front_mm, 6)
            why = (f"the hand's front, {front_mm:g} mm ahead of the hand point, meets the wall "
                   "face there; the hand cuts nothing")
            tool, remedy = "the hand", (f"; to press on the wall, give the plunge a thrust_n "
                                        f"(N): the hand presses with it wherever the face is, "
                                        f"up to {yield_mm:g} mm past its plan")
        if depth_mm > depth_max_mm:
            raise self.fail(t.key("depth_mm"), f"{label} to depth_mm = {depth_mm:g} is deeper "
                            f"than {tool} allows: at most depth_mm = {depth_max_mm:g} ({why})",
                            hint=f"{kind} to depth_mm = {depth_max_mm:g} or less{remedy}")

    def _plunge(self, t: _Table, kind: str, name: str, number: int) -> Step:
        return replace(self._retract(t, kind, name, number), thrust_n=self._thrust(t))

    @staticmethod
    def _thrust(t: _Table) -> float:
        return t.number("thrust_n", minimum=0.0, maximum=THRUST_MAX_N, default=0.0)

    def _wait(self, t: _Table, kind: str, name: str, number: int) -> Step:
        return Step(kind, name, number,
                    duration_s=t.number("duration_s", minimum=0.0, maximum=STEP_MAX_S),
                    thrust_n=self._thrust(t))

    def _follow(self, t: _Table, kind: str, name: str, number: int) -> Step:
        path = t.choice("path", ("rectangle", "polyline"))
        speed = t.number("speed_mm_s", minimum=TOOL_SPEED_MIN_MM_S,
                         maximum=TOOL_SPEED_MAX_MM_S) / 1000
        accel = t.number("accel_mm_s2", minimum=TOOL_ACCEL_MIN_MM_S2,
                         maximum=TOOL_ACCEL_MAX_MM_S2, default=None)
        accel = None if accel is None else accel / 1000
        bit_mm = self._bit_mm()
        if path == "polyline":
            points = t.points("points_mm")
            if bit_mm is not None:
                self._at_least(t, "points_mm", sum(math.dist(a, b) for a, b in
                                                   zip(points[:-1], points[1:], strict=True)),
                               bit_mm, "the bit's diameter: the path's length")
            return Step(kind, name, number, points_m=tuple((y / 1000, z / 1000)
                                                           for y, z in points),
                        speed_m_s=speed, accel_m_s2=accel, path=path,
                        thrust_n=self._thrust(t))
        width = t.number("width_mm", positive=True, maximum=LENGTH_MAX_MM)
        height = t.number("height_mm", positive=True, maximum=LENGTH_MAX_MM)
        if bit_mm is not None:
            for key, value in (("width_mm", width), ("height_mm", height)):
                self._at_least(t, key, value, bit_mm, "the bit's diameter: no hole is that "
                               "small")
        width, height = width / 1000, height / 1000
        centre = t.point("centre_mm", default=(0.0, 0.0))
        start = t.choice("start", tuple(CORNERS), default="upper-left")
        direction = t.choice("direction", ("ccw", "cw"), default="ccw")
        points = rectangle_points(width, height, (centre[0] / 1000, centre[1] / 1000), start,
                                  direction)
        shape = {"width_m": width, "height_m": height, "start": start, "direction": direction}
        return Step(kind, name, number, points_m=points, speed_m_s=speed, accel_m_s2=accel,
                    path=path, shape=shape, thrust_n=self._thrust(t))


def rectangle_points(width_m: float, height_m: float, centre_m: tuple[float, float],
                     start: str = "upper-left", direction: str = "ccw"
                     ) -> tuple[tuple[float, float], ...]:
    """The closed corner list (y, z) of a rectangle in the wall plane (m), first corner repeated
    at the end. Directions are as seen from behind the robot (looking at the wall: its left is
    +y): counter-clockwise from the upper-left goes down the left edge first."""
    sy, sz = CORNERS[start]
    hw, hh = width_m / 2, height_m / 2
    # ccw seen from behind the robot: left edge down, bottom to the right, right edge up, ...
    ring = [(1, 1), (1, -1), (-1, -1), (-1, 1)]
    if direction == "cw":
        ring = ring[::-1]
    k = ring.index((sy, sz))
    order = ring[k:] + ring[:k] + [ring[k]]
    return tuple((centre_m[0] + a * hw, centre_m[1] + b * hh) for a, b in order)


class _Table:
    """Typed access to one table; ``finish`` rejects keys nobody asked for (typos)."""

    def __init__(self, loader: _Loader, where: str, data) -> None:
        self.loader = loader
        self.where = where
        if not isinstance(data, dict):
            raise loader.fail(where, "must be a table", hint=f"write it as [{where}]")
        self.data = data
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.where}.{name}" if self.where else name

    def value(self, name: str, default=...):
        self.used.add(name)
        if name not in self.data:
            if default is ...:
                raise self.loader.fail(self.key(name), f"missing field {quoted(name)}",
                                       hint=f"add {name} = ... to [{self.where or 'top level'}]")
            return default
        return self.data[name]

    def table(self, name: str) -> _Table:
        return _Table(self.loader, self.key(name), self.value(name, default={}))

    def list_of_tables(self, name: str) -> list[_Table]:
        items = self.value(name, default=[])
        if not isinstance(items, list):
            raise self.loader.fail(self.key(name), "must be a list of tables",
                                   hint=f"write each entry as [[{name}]]")
        return [_Table(self.loader, f"{self.key(name)}[{i}]", item)
                for i, item in enumerate(items, start=1)]

    def text(self, name: str, default=...) -> str | None:
        value = self.value(name, default)
        if value is not None and not isinstance(value, str):
            raise self.loader.fail(self.key(name), f"must be text, got {quoted(value)}",
                                   hint=f'write it in quotes: {name} = "..."')
        return value

    def choice(self, name: str, options: tuple[str, ...], default=...) -> str:
        value = self.value(name, default)
        if value not in options:
            raise self.loader.fail(self.key(name), f"must be one of {', '.join(options)}; "
                                                   f"got {quoted(value)}",
                                   hint=f'e.g. {name} = "{options[0]}"')
        return value

    def number(self, name: str, *, positive: bool = False, minimum: float | None = None,
               maximum: float | None = None, default=...) -> float | None:
        value = self.value(name, default)
        if value is None and default is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value):
            raise self.loader.fail(self.key(name), f"must be a number, got {quoted(value)}",
                                   hint=f"give a finite number (no quotes): {name} = "
                                        f"{'1.0' if minimum is None else f'{minimum:g}'}")
        if positive and not value > 0:
            raise self.loader.fail(self.key(name), f"must be positive, got {quoted(value)}",
                                   hint="give a number above 0 (sizes, speeds and times are "
                                        "magnitudes; the signs are in positions and depths)")
        if minimum is not None and value < minimum:
            raise self.loader.fail(self.key(name),
                                   f"must be at least {minimum:g}, got {quoted(value)}",
                                   hint=f"give {minimum:g} or more")
        if maximum is not None and value > maximum:
            raise self.loader.fail(self.key(name),
                                   f"must be at most {maximum:g}, got {quoted(value)}",
                                   hint="a larger value makes no physical sense for Hubo")
        return float(value)

    def number_or_auto(self, name: str, *, positive: bool = False,
                       maximum: float | None = None) -> float | None:
        if self.data.get(name, "auto") == "auto":
            self.used.add(name)
            return None
        return self.number(name, positive=positive, maximum=maximum)

    def point(self, name: str, default=...) -> tuple[float, float] | None:
        value = self.value(name, default)
        if value is None and default is None:
            return None
        if not _is_point(value):
            raise self.loader.fail(self.key(name), f"must be [y, z] in mm, got {quoted(value)}")
        if max(abs(value[0]), abs(value[1])) > LENGTH_MAX_MM:
            raise self.loader.fail(self.key(name), f"{quoted(value)} lies more than "
                                   f"{LENGTH_MAX_MM:g} mm out: beyond any arm's reach")
        return float(value[0]), float(value[1])

    def point_or_auto(self, name: str) -> tuple[float, float] | None:
        if self.data.get(name, "auto") == "auto":
            self.used.add(name)
            return None
        return self.point(name)

    def points(self, name: str) -> list[tuple[float, float]]:
        value = self.value(name)
        if not isinstance(value, list) or len(value) < 2 or not all(map(_is_point, value)):
            raise self.loader.fail(self.key(name), "must be a list of at least two [y, z] "
                                                   "points in mm", hint="e.g. [[0, 0], [50, 0]]")
        if any(max(abs(y), abs(z)) > LENGTH_MAX_MM for y, z in value):
            raise self.loader.fail(self.key(name), f"a point lies more than {LENGTH_MAX_MM:g} "
                                   "mm out: beyond any arm's reach")
        return [(float(y), float(z)) for y, z in value]

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            raise self.loader.fail(self.key(unknown[0]), f"unknown field {quoted(unknown[0])}",
                                   hint=f"fields here: {', '.join(sorted(self.used))}")


def _is_point(value) -> bool:
    return (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                    for v in value))
