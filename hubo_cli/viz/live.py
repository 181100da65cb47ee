"""A run served live to Foxglove over foxglove-sdk's WebSocket server (``--live``).

The server binds when :class:`LiveServer` is made (before the robot moves: a port in use is an
InputError) and serves the topics of the MCAP export (:mod:`hubo_cli.viz.foxglove_messages`),
so the shipped layout shows a live run as it shows a recorded one. The URDF goes out on
``/robot_description`` (to every client that subscribes) and through the asset handler
(``package://hubo2plus/<file>.urdf`` and its ``file://`` path).

The control loop only copies: every period it notes the e-stop and status changes (for
``/events``) and every :attr:`LiveServer.every` periods (:data:`JOINT_RATE_HZ` of loop time) the
latest state; a background thread builds and sends the messages, at most
:data:`JOINT_RATE_HZ` a second of wall time (the joints, ``/tf``, ``/metrics``, ``/safety``)
and :data:`SCENE_RATE_HZ` (``/scene``: walls, hole as cut, goal and tool paths), and only while
a client listens. Times are UTC: the run's start plus the loop time.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.log import status_codes
from hubo_cli.control.status import Status
from hubo_cli.errors import InputError
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel, load_model
from hubo_cli.state import RobotState
from hubo_cli.viz import foxglove_messages as msg
from hubo_cli.viz.deps import require
from hubo_cli.viz.scene import (
    ARM_SUFFIX,
    SERIES,
    estop_event,
    hand_to_tool,
    hole_on_face,
    leg_limbs,
    series_values,
    status_event,
    torso_on_floor,
    working_arm,
)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
JOINT_RATE_HZ = 40.0  # joints, transforms, metrics, safety: smooth for an eye
SCENE_RATE_HZ = 2.0  # walls, hole and paths: they change slowly
MAX_PATH_POINTS = 20_000  # the goal and tool paths keep their latest points (8 min at 40 Hz)
PACKAGE = "package://hubo2plus/"


@dataclass
class _Snapshot:
    """What the loop copied of one period."""

    t_s: float
    q_rad: np.ndarray
    dq_rad_s: np.ndarray
    T_world_torso: np.ndarray | None
    imu_quat_wxyz: np.ndarray
    status: int
    flags: tuple[str, ...]
    extras: dict


class _Run:
    """One run's model-dependent helpers and the paths drawn so far (publisher thread)."""

    def __init__(self, model: RobotModel, tools: Mapping[str, str], world) -> None:
        self.model = model
        self.world = world
        self.names = list(model.joint_names)
        self.frames = msg.JointFrames(model)
        self.legs = leg_limbs(model)
        self.drill = tools.get("right-arm") == "drill"
        self.arm: str | None = None  # the working arm, from the first snapshot
        self.start_ns = time.time_ns()
        self.last_ns: int | None = None  # the latest snapshot's time (UTC ns)
        self.robot_world_m: np.ndarray | None = None  # the torso at the first snapshot
        self.goal_offset_m: np.ndarray | None = None
        self.goal_path: collections.deque = collections.deque(maxlen=MAX_PATH_POINTS)
        self.tool_path: collections.deque = collections.deque(maxlen=MAX_PATH_POINTS)
        self.tools = dict(tools)
        self._limb: tuple[Limb, slice, np.ndarray] | None = None

    def choose_arm(self, extras: dict) -> str:
        """The arm whose tool the paths follow (:func:`~hubo_cli.viz.scene.working_arm`),
        chosen at the first snapshot."""
        if self.arm is None:
            self.arm = working_arm(self.tools, extras)
        return self.arm

    def tool_world_m(self, T_world_torso: np.ndarray, q_rad: np.ndarray) -> np.ndarray:
        """The working arm's tool point in the world (m)."""
        if self._limb is None:
            tool = self.tools.get(self.arm, "hand")
            self._limb = (Limb(self.model, self.arm, "hand"), self.model.limb_slice(self.arm),
                          hand_to_tool(self.model, tool if tool == "drill" else "hand"))
        limb, index, T_hand_tool = self._limb
        return (T_world_torso @ limb.fk(q_rad[index]) @ T_hand_tool)[:3, 3]


class LiveServer:
    """The Foxglove WebSocket server of ``--live``; a :class:`~hubo_cli.session.RunObserver`.

    Args:
        host: the address to bind (the default, the loopback, serves this machine only).
        port: the TCP port (0: any free one; :attr:`port` says which).
        rate_hz: joint states a second of loop time at most.

    Raises:
        InputError: the port is in use or the host cannot be bound.
        MissingOptionalDependency: foxglove-sdk is not installed.
    """

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 rate_hz: float = JOINT_RATE_HZ) -> None:
        foxglove = require("foxglove", "the live view (--live)")
        import foxglove.messages as fm

        if not 0 <= port <= 65535:
            raise InputError(f"--live-port {port} is not a TCP port",
                             hint="give 1 to 65535, or 0 for any free port")
        self._fm = fm
        self.rate_hz = rate_hz
        self._context = foxglove.Context()
        self._channels = msg.open_channels(foxglove, self._context)
        self._assets: dict[str, Path] = {}
        self._serve_urdfs(load_model().urdf_path().parent)
        self._describe = describe = threading.Event()

        class Listener(foxglove.ServerListener):
            """Asks for the URDF again when a client subscribes to ``/robot_description``."""

            def on_subscribe(self, client, channel) -> None:
                if channel.topic == msg.TOPICS[0]:
                    describe.set()

        try:
            self._server = foxglove.start_server(
                name="hubo-cli", host=host, port=port, context=self._context,
                asset_handler=self._asset, server_listener=Listener())
        except RuntimeError as err:
            reason = str(err).removeprefix("FoxgloveError: ")
            hint = ("another program (another --live run?) holds that port: choose another "
                    "with --live-port, or 0 for any free one" if "in use" in reason else
                    f"give an address of this machine with --live-host (default {DEFAULT_HOST})")
            raise InputError(f"--live cannot serve on {host}:{port}: {reason}",
                             hint=hint) from None
        self.host = host
        self.port = self._server.port
        self.labels = status_codes()
        self.every = 1
        self.error = ""  # why publishing stopped, if it did
        self._run: _Run | None = None
        self._urdf = ""
        self._latest: _Snapshot | None = None
        self._events: collections.deque = collections.deque()
        self._k = 0
        self._estop = False
        self._status = -1
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """Where Foxglove connects (Open connection, Foxglove WebSocket)."""
        host = "localhost" if self.host == DEFAULT_HOST else self.host
        return f"ws://{f'[{host}]' if ':' in host else host}:{self.port}"

    # --------------------------------------------------------------- the run (loop thread)
    def run_started(self, model: RobotModel, tools: Mapping[str, str], world) -> None:
        """Serve a new run (its URDF and scene) until :meth:`run_ended`."""
        self.run_ended()
        run = _Run(model, tools, world)
        urdf = model.urdf_path(run.drill)
        self._serve_urdfs(urdf.parent)
        self._urdf = urdf.read_text(encoding="utf-8")
        self.every = max(1, round(1.0 / (self.rate_hz * model.control_period_s)))
        self._k, self._estop, self._status, self._latest = 0, False, -1, None
        self._events.clear()
        self._run = run
        self._stop.clear()
        self._describe.set()
        self._thread = threading.Thread(target=self._publish_loop, args=(run,),
                                        name="hubo-live", daemon=True)
        self._thread.start()

    def period(self, t_s: float, status: Status, flags: set[str], state: RobotState,
               extras: dict | None) -> None:
        """Note the period (:class:`~hubo_cli.control.loop.PeriodObserver`): its e-stop and
        status changes always, its state every :attr:`every` periods."""
        estop = "estop" in flags
        if estop != self._estop:
            self._estop = estop
            self._events.append((t_s, *estop_event(estop)))
        if status != self._status:
            self._status = int(status)
            self._events.append((t_s, *status_event(int(status), self.labels)))
        k, self._k = self._k, self._k + 1
        if k % self.every:
            return
        T = None if state.truth is None else state.truth.T_world_torso  # a viewer: truth
        self._latest = _Snapshot(t_s, state.q_rad.copy(), state.dq_rad_s.copy(),
                                 None if T is None else T.copy(), state.imu_quat_wxyz.copy(),
                                 int(status), tuple(flags), dict(extras or {}))
        self._wake.set()

    def run_ended(self) -> None:
        """Publish what is left of the run and stop its thread."""
        if self._thread is None:
            return
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=5.0)
        self._thread = None

    def close(self) -> None:
        """End the run's publishing and stop the server (idempotent)."""
        self.run_ended()
        self._server.stop()

    # --------------------------------------------------------------- publisher thread
    def _serve_urdfs(self, folder: Path) -> None:
        """Serve the robot's URDFs (``package://hubo2plus/<name>`` and their ``file://``
        paths); nothing else is served."""
        urdfs = sorted(folder.glob("*.urdf"))
        self._assets = {PACKAGE + p.name: p for p in urdfs} | {p.resolve().as_uri(): p
                                                             for p in urdfs}

    def _asset(self, uri: str) -> bytes | None:
        path = self._assets.get(uri)
        return None if path is None else path.read_bytes()

    def _publish_loop(self, run: _Run) -> None:
        wall_period = 1.0 / self.rate_hz
        next_scene = 0.0
        while True:
            stopping = self._stop.is_set()
            if not stopping:
                self._wake.wait(timeout=0.5)
                self._wake.clear()
            started = time.monotonic()
            try:
                next_scene = self._publish(run, started, next_scene, stopping)
            except Exception as err:  # noqa: BLE001 (a viewer never stops the robot)
                self.error = f"{type(err).__name__}: {err}"
                return
            if stopping:
                return
            self._stop.wait(max(0.0, started + wall_period - time.monotonic()))

    def _publish(self, run: _Run, now: float, next_scene: float, final: bool) -> float:
        fm, channels = self._fm, self._channels
        if self._describe.is_set():
            self._describe.clear()
            channels.description.log({"data": self._urdf}, log_time=run.start_ns)
        while self._events:
            t_s, level, text = self._events.popleft()
            ns = run.start_ns + round(t_s * 1e9)
            channels.events.log(msg.log_message(fm, level, text, msg.stamp(fm, ns)),
                                log_time=ns)
        snap, self._latest = self._latest, None
        T_world_torso = None
        if snap is not None:  # the paths grow whether or not anyone listens
            T_world_torso = self._torso(run, snap)
            self._extend_paths(run, snap, T_world_torso)
        if not any(c.has_sinks() for c in (channels.states, channels.tf, channels.scene,
                                           channels.metrics, channels.safety)):
            return next_scene  # no one listens: no messages
        if snap is not None:
            self._publish_state(run, snap, T_world_torso)
        if run.last_ns is None or (now < next_scene and not final):
            return next_scene
        scene = run.world.scene() if run.world is not None else {}
        walls = scene.get("walls", [])
        hole = hole_on_face(np.asarray(scene.get("hole_world_m", []), dtype=float),
                            walls, run.robot_world_m)
        channels.scene.log(msg.scene_update(fm, walls, np.array(run.goal_path).reshape(-1, 3),
                                            np.array(run.tool_path).reshape(-1, 3), hole,
                                            msg.stamp(fm, run.last_ns)), log_time=run.last_ns)
        return now + 1.0 / SCENE_RATE_HZ

    def _publish_state(self, run: _Run, snap: _Snapshot, T_world_torso: np.ndarray) -> None:
        """The joints, transforms, metrics and safety of a snapshot."""
        fm, channels = self._fm, self._channels
        ns = run.last_ns = run.start_ns + round(snap.t_s * 1e9)
        ts = msg.stamp(fm, ns)
        channels.states.log(msg.joint_states(fm, run.names, snap.q_rad.tolist(),
                                             snap.dq_rad_s.tolist(), ts), log_time=ns)
        channels.tf.log(msg.frame_transforms(fm, run.frames.columns_at(T_world_torso,
                                                                     snap.q_rad), 0, ts),
                        log_time=ns)
        extras = snap.extras
        series = series_values(lambda name: snap.status if name == "status_code"
                               else extras.get(name), run.choose_arm(extras), T_world_torso)
        channels.metrics.log(msg.metrics_message(
            [float(series.get(name, math.nan)) for name in SERIES], self.labels), log_time=ns)
        channels.safety.log(msg.safety_message(snap.flags), log_time=ns)

    @staticmethod
    def _torso(run: _Run, snap: _Snapshot) -> np.ndarray:
        """The torso's world pose: the simulator's, else the IMU's orientation over the
        lower sole standing on the floor (as a replay estimates it)."""
        T = snap.T_world_torso
        if T is not None and np.all(np.isfinite(T)):
            T_world_torso = T
        else:
            T_world_torso = np.eye(4)
            T_world_torso[:3, :3] = quat_wxyz_to_matrix(snap.imu_quat_wxyz)
            T_world_torso[:3, 3] = torso_on_floor(run.legs, T_world_torso[:3, :3], snap.q_rad)
        if run.robot_world_m is None:
            run.robot_world_m = T_world_torso[:3, 3].copy()
        return T_world_torso

    @staticmethod
    def _extend_paths(run: _Run, snap: _Snapshot, T_world_torso: np.ndarray) -> None:
        """Add the measured tool point and the goal (carried from the task's frame into the
        world by the offset of the first snapshot with both: as a replay places it)."""
        suffix = ARM_SUFFIX[run.choose_arm(snap.extras)]
        tool = run.tool_world_m(T_world_torso, snap.q_rad)
        run.tool_path.append(tool)
        for ending in (suffix, ""):
            goal = np.array([snap.extras.get(f"goal_{a}_m{ending}", math.nan) for a in "xyz"])
            actual = np.array([snap.extras.get(f"actual_{a}_m{ending}", math.nan)
                               for a in "xyz"])
            if np.all(np.isfinite(goal)):
                break
        if run.goal_offset_m is None and np.all(np.isfinite(np.r_[goal, actual])):
            run.goal_offset_m = tool - actual
        if run.goal_offset_m is not None and np.all(np.isfinite(goal)):
            run.goal_path.append(goal + run.goal_offset_m)
