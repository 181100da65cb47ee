"""``hubo hardware``: the real robot's side tools (a fake hubo-daemon), and the hardware driver's
options shared by ``hubo task`` and ``hubo teleop``."""

from __future__ import annotations

import contextlib
import signal

import click

from hubo_cli.cli.output import err_console, print_json, warn
from hubo_cli.errors import DeviceError, InputError

SINK_CHOICES = ("ach", "file", "fifo")
REF_MODE_CHOICES = ("direct", "filtered")  # the driver's words for hubo-ach's modes 1 and 0


def hardware_options(function):
    """The hardware driver's options (used with ``--driver hardware``)."""
    options = [
        click.option("--dry-run", is_flag=True,
                     help="Hardware driver without a robot: frames to the run folder's "
                          "hubo-ref.bin, state echoed through hubo-daemon's filter."),
        click.option("--sink", type=click.Choice(SINK_CHOICES), default=None,
                     help="Hardware references: ach (hubo-ach's channels through libach, the "
                          "default), file or fifo (in the run folder; implied by --dry-run)."),
        click.option("--ach-ref", default=None, metavar="NAME",
                     help="hubo-ach reference channel (default hubo-ref)."),
        click.option("--ach-state", default=None, metavar="NAME",
                     help="hubo-ach state channel (default hubo-state)."),
        click.option("--ref-mode", type=click.Choice(REF_MODE_CHOICES), default=None,
                     help="hubo-ach reference mode for every joint: direct (mode 1, the "
                          "default, as hubo-motion-rt) or filtered (mode 0, hubo-daemon's "
                          "40-tap filter: 0.2 s of lag). Recorded in the summary."),
        click.option("--echo-sensors", is_flag=True,
                     help="The daemon's sensors are made up (hubo hardware fake-daemon): the "
                          "sensor checks are off and the force stops cannot act (said on "
                          "stderr). Without it a run against the fake daemon is refused: its "
                          "wrist sensors read exactly 0."),
    ]
    for option in reversed(options):
        function = option(function)
    return function


def driver_options(driver: str, armed: bool, dry_run: bool, sink: str | None,
                   ach_ref: str | None, ach_state: str | None,
                   ref_mode: str | None = None, echo_sensors: bool = False,
                   quiet: bool = False) -> dict:
    """The driver's options from the command line; hardware options (``--arm`` among them)
    with another driver, or a dry run on the channels, are refused (exit 2).

    A dry run writes a file that no robot reads, so it needs no ``--arm``; every other sink
    reaches (or may reach) a robot and the driver refuses to start without it. A dry run is
    told on stderr that its force stops and sensor checks cannot act (the echo reads no force;
    not with ``quiet``: ``--json``).
    """
    hardware = {"sink": sink, "ach_ref": ach_ref, "ach_state": ach_state, "ref_mode": ref_mode}
    given = [f"--{k.replace('_', '-')}" for k, v in hardware.items() if v is not None]
    if dry_run:
        given.append("--dry-run")
    if echo_sensors:
        given.append("--echo-sensors")
    if driver != "hardware":
        if armed:  # arms nothing: a script that believes it armed a robot is told
            given.insert(0, "--arm")
        if given:
            raise InputError(f"{', '.join(given)} only apply to the hardware driver",
                             hint="add --driver hardware or leave them out")
        return {}
    if dry_run:
        if sink not in (None, "file"):
            raise InputError(f"--dry-run writes a file; --sink {sink} contradicts it",
                             hint="leave out --sink")
        if ach_ref or ach_state:
            raise InputError("a dry run uses no ach channel",
                             hint="leave out --ach-ref and --ach-state")
        options = {"armed": True, "sink": "file"}
        # the echo is no sensor (Driver.sensors_measured): say what cannot act, never pretend
        if not quiet:
            warn("dry run: the echoed state reads no force and a level, still IMU: the "
                 "wrist-torque and force stops, the force control and the sensor checks cannot "
                 "act")
    else:
        options = {"armed": armed, **{k: v for k, v in hardware.items() if v is not None}}
    if ref_mode is not None:
        options["ref_mode"] = ref_mode
    if echo_sensors and not dry_run:  # (a dry run's echo is said above)
        options["echo_sensors"] = True
        if not quiet:
            warn("--echo-sensors: the daemon's sensors are taken as made up: the wrist-torque "
                 "and force stops, the force control and the sensor checks cannot act")
    return options


@click.group("hardware")
def hardware() -> None:
    """The real Hubo's side: stand-ins for hubo-daemon to run the hardware driver without a
    robot (fake-daemon: ideal motors; sim-daemon: the simulated robot).

    The hardware driver (--driver hardware --arm) talks to hubo-ach's hubo-ref and hubo-state
    channels through libach. See docs/hardware.md (The real Hubo).
    """


def _daemon_options(function):
    """The options both daemons take."""
    options = [
        click.option("--ach-ref", default="hubo-ref", show_default=True, metavar="NAME",
                     help="Reference channel to read."),
        click.option("--ach-state", default="hubo-state", show_default=True, metavar="NAME",
                     help="State channel to publish."),
        click.option("--duration", type=float, default=None, metavar="SECONDS",
                     help="Stop after this long (default: until Ctrl-C)."),
        click.option("--json", "as_json", is_flag=True,
                     help="Print the final statistics as JSON."),
    ]
    for option in reversed(options):
        function = option(function)
    return function


POSTURES = ("home", "standing", "braced", "walking")  # sim-daemon --posture
WALL_AT_S = 4.5  # after the shipped cut's raise (about 4 s), before its plunge (about 9 s)


def _check_duration(duration: float | None) -> None:
    if duration is not None and not 0 < duration <= 7 * 24 * 3600:
        raise InputError(f"--duration {duration:g} s is not a duration",
                         hint="give seconds, more than 0 and at most a week")


def _serve(daemon, what: str, duration: float | None, as_json: bool, extra: dict) -> None:
    """Run ``daemon`` (a :class:`~hubo_cli.drivers.hubo_ach_daemon.HuboDaemon`) in this thread
    until Ctrl-C, SIGTERM, SIGHUP or ``duration``; close it (its channels removed) and report."""
    with daemon:
        created = ", ".join(daemon.created) or "none (they existed)"
        if daemon.replaced:
            created += f" (replacing {', '.join(daemon.replaced)} left over from a dead daemon)"
        err_console.print(f"{what}: reading {daemon.ref_channel}, publishing "
                          f"{daemon.state_channel} at 200 Hz; channels created: {created}. "
                          "Ctrl-C stops.")
        # Ctrl-C, SIGTERM (kill, systemd) and SIGHUP end the loop; the channels are removed
        signals = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
        previous = {sig: signal.signal(sig, lambda *_: daemon.request_stop()) for sig in signals}
        try:
            daemon.run(duration)
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        stats = daemon.stats
        summary = {**stats.summary(), **extra(daemon)}
    if as_json:
        print_json(summary)
    else:
        sizes = ", ".join(f"{n} x {size} B" for size, n in sorted(stats.frame_sizes.items()))
        loop = ("" if summary["loop_ms_median"] is None else
                f"; loop {summary['loop_ms_median']:.2f} ms median, "
                f"{summary['loop_ms_p99']:.2f} ms p99")
        err_console.print(f"{stats.periods} periods, {stats.ref_frames} reference frames "
                          f"({sizes or 'none'}), {stats.missed_ref_frames} missed, "
                          f"{stats.overruns} overruns ({summary['overrun_percent']:.2f} %), "
                          f"{stats.late_periods} late periods{loop}")
        for spec, began in stats.faults.items():
            err_console.print(f"fault {spec}: " + ("not reached" if began is None else
                                                   f"began {began:.3f} s after the first "
                                                   "reference"))
        if stats.states_withheld or stats.states_late:
            err_console.print(f"{stats.states_withheld} states withheld, {stats.states_late} "
                              "published late")
    if stats.error:
        raise DeviceError(f"the {what} stopped: {stats.error}",
                          hint="the writer does not send hubo_ref_t frames")


@hardware.command("fake-daemon")
@_daemon_options
@click.option("--posture", type=click.Choice(["home", "zero"]), default="home", show_default=True,
              help="Where the joints start.")
def fake_daemon(ach_ref: str, ach_state: str, duration: float | None, as_json: bool,
                posture: str) -> None:
    """Stand in for hubo-daemon: read hubo-ref, apply its reference filter, publish hubo-state
    at 200 Hz. Channels that do not exist are created, and removed again at the end;
    channels left over from a daemon that died (kill -9) are replaced and removed too; channels
    another daemon publishes are refused (exit 3).

    Example: hubo hardware fake-daemon   (then, in another terminal:
             hubo task cut-rectangle --driver hardware --arm)
    """
    import numpy as np

    from hubo_cli.drivers.ach import load_libach
    from hubo_cli.drivers.hardware import hubo_ach_vector
    from hubo_cli.drivers.hubo_ach_daemon import FakeHuboDaemon
    from hubo_cli.model import load_model
    from hubo_cli.posture import home_posture

    _check_duration(duration)
    lib = load_libach()
    model = load_model()
    q = home_posture(model) if posture == "home" else np.zeros(len(model.joint_names))
    _serve(FakeHuboDaemon(lib, hubo_ach_vector(model, q), ach_ref, ach_state),
           "fake hubo-daemon", duration, as_json, lambda _: {})


@hardware.command("sim-daemon")
@_daemon_options
@click.option("--perturb", "perturb_seed", type=click.IntRange(min=0), default=None,
              metavar="SEED",
              help="Simulate a robot and world drawn from SEED as hubo sim --perturb does "
                   "(0 = nominal); the draws go into the final statistics (--json).")
@click.option("--fault", "faults", multiple=True, metavar="SPEC",
              help="Play a fault, times in s after the first reference frame, counted in the "
                   "daemon's periods (repeatable): "
                   "missing,at=S[,for=S] (no state); late,at=S,by=S[,for=S] (states S old); "
                   "frozen,joint=NAME,at=S (the joint sticks); hot,joint=NAME,at=S,rate=K/S "
                   "(the motor heats that much faster).")
@click.option("--drill", is_flag=True,
              help="The drill in the right hand (as a drilling task's robot holds it).")
@click.option("--wall", "wall_mm", type=click.FloatRange(min=50.0, max=5000.0), default=None,
              metavar="MM",
              help="A wall (the shipped tasks' cardboard, 2 m x 1.2 m) with its near face MM "
                   "ahead of where the robot started, e.g. a task's planned wall_distance_mm, "
                   "placed --wall-at after the first reference; with --drill the bit cuts it "
                   "as in hubo sim.")
@click.option("--wall-at", "wall_at_s", type=click.FloatRange(min=0.0, max=3600.0),
              default=None, metavar="SECONDS",
              help="When --wall is placed, in s after the first reference (counted as "
                   "--fault's): once a task has "
                   "raised its tool (the shipped cut's raise ends about 4 s after it; the raise "
                   "may sweep through the wall's place), before its plunge reaches the wall "
                   "(about 9 s after it). Default 4.5.")
@click.option("--tool-log", type=click.Path(dir_okay=False, writable=True), default=None,
              metavar="FILE.csv",
              help="Write the right hand's tool's true world position (the drill bit with "
                   "--drill) with each published state's time, at the end: a run's hole as "
                   "the simulator has it (tools/daemon_hole.py compares it with the run).")
@click.option("--truth-log", type=click.Path(dir_okay=False, writable=True), default=None,
              metavar="FILE.csv",
              help="Write the simulator's truth with each published state's time: the torso's "
                   "position and tilt, the soles' places on the floor (tools/daemon_walk.py "
                   "measures a walk's arrival from it).")
@click.option("--posture", type=click.Choice(POSTURES), default="home", show_default=True,
              help="What the robot stands in: home, standing (hubo sim's with --step or "
                   "--no-hip, the CoM over the soles), braced (hubo sim's with the hip "
                   "strategy: standing, crouched) or walking (hubo walk's start, the walking "
                   "limit set's).")
@click.option("--push", "push_spec", default=None, metavar="N,at=S[,dir=D][,for=S]",
              help="Push the torso at its centre of mass with N newtons, S seconds after the "
                   "first reference (counted as --fault's), dir forward (default), backward, "
                   "left or right, for 0.2 s unless for= says: what hubo sim --push does on "
                   "the sim driver.")
def sim_daemon(ach_ref: str, ach_state: str, duration: float | None, as_json: bool,
               perturb_seed: int | None, faults: tuple[str, ...], drill: bool,
               wall_mm: float | None, wall_at_s: float | None, tool_log: str | None,
               truth_log: str | None, posture: str, push_spec: str | None) -> None:
    """Play hubo-daemon with the simulated robot behind it: read hubo-ref, apply references as
    hubo-daemon does (mode 0 through its reference filter, mode 1 directly, per joint), run the
    PyBullet Hubo (the sim driver's world) in real time and publish what it measures on
    hubo-state at 200 Hz: encoders, the body IMU, the four force-torque sensors, and the motors'
    currents and temperatures from the simulated torques (the robot file's [motors]). The robot
    stands in --posture. --fault plays a bus's or a motor's fault on request, --push a push.
    Channels as the fake daemon (created, taken over from a dead daemon, removed at the end;
    another live daemon's refused, exit 3). The loop's overruns and times and the faults played
    are reported at the end (--json: also the hottest motor and the simulator's true tilt).

    \b
    Examples:
      hubo hardware sim-daemon --perturb 3 --drill   (then, in another terminal:
        hubo task cut-rectangle --driver hardware --arm)
      hubo hardware sim-daemon --fault frozen,joint=REB,at=2
      hubo hardware sim-daemon --posture walking --truth-log truth.csv   (then:
        hubo walk --to 1 0 0 --driver hardware --arm)
      hubo hardware sim-daemon --posture standing --push 120,at=2   (then:
        hubo sim --driver hardware --arm --step --duration 6)
    """
    import numpy as np

    from hubo_cli.drivers.ach import load_libach
    from hubo_cli.drivers.hardware import hubo_ach_vector
    from hubo_cli.drivers.hubo_ach_daemon import HuboDaemon
    from hubo_cli.drivers.hubo_ach_faults import parse_fault, parse_push
    from hubo_cli.drivers.hubo_ach_sim_body import TRUTH_COLUMNS, PhysicsBody
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS
    from hubo_cli.model import load_model

    _check_duration(duration)
    if wall_at_s is not None and wall_mm is None:
        raise InputError("--wall-at places a --wall; there is none", hint="add --wall MM")
    wall_at_s = WALL_AT_S if wall_at_s is None else wall_at_s
    model = load_model()
    played = tuple(parse_fault(spec, model.joint_names) for spec in faults)
    push = None if push_spec is None else parse_push(push_spec)
    # checked now, written as the daemon runs (a daemon's log: an existing file is replaced)
    tool_out = _csv_log(tool_log, "--tool-log", ("x_m", "y_m", "z_m"))
    truth_out = _csv_log(truth_log, "--truth-log", TRUTH_COLUMNS)
    lib = load_libach()
    with contextlib.ExitStack() as stack:
        body = PhysicsBody(model, hubo_ach_vector(model, _posture(model, posture)),
                           perturb_seed, track_tool=tool_out and tool_out(stack),
                           track_truth=truth_out and truth_out(stack), drill=drill)
        scheduled = [] if wall_mm is None else [(wall_at_s,
                                                 lambda: body.place_wall(wall_mm / 1000))]
        pushed = {}  # the push's spec -> when it began (None: not reached)
        if push is not None:
            force = push.force_n * np.array(PUSH_DIRECTIONS[push.direction])
            name = f"push {push.describe()}"
            pushed[name] = None

            def push_now() -> None:
                body.push_torso(force, push.for_s)
                pushed[name] = round(daemon.fault_time_s(), 4)
            scheduled.append((push.at_s, push_now))
        # closes the body if it cannot start
        daemon = HuboDaemon(lib, body, ach_ref, ach_state, faults=played,
                            scheduled=tuple(scheduled))
        _serve(daemon, "simulated hubo-daemon", duration, as_json,
               lambda daemon: _sim_extra(model, daemon.body) | {"pushes": pushed})
        if not as_json:
            for spec, began in pushed.items():
                err_console.print(f"{spec}: " + ("not reached" if began is None else
                                                 f"began {began:.3f} s after the first "
                                                 "reference"))



def _posture(model, name: str):
    """The limb joints of a --posture (rad): the walking start, or a standing run's."""
    if name == "walking":
        from hubo_cli.walking.body import walking_posture
        from hubo_cli.walking.params import walking_params

        walking_model = model.with_limits("walking")
        params = walking_params(walking_model)
        return walking_posture(walking_model, params.step_width_m, params.crouch_m)[0]
    from hubo_cli.experiments.standing import posture_of

    return posture_of(model, name)


def _csv_log(path: str | None, option: str, columns: tuple[str, ...]):
    """A daemon's CSV log (``time_s`` and ``columns``), checked now: None without a path, else
    a function of an ExitStack that opens it and returns the row writer (rows as they come, the
    file renamed into place at the end; a full disk stops the daemon, exit 3)."""
    from hubo_cli.outputs import OutputFile

    if path is None:
        return None
    output = OutputFile(path, option=option, force=True)

    def open_in(stack: contextlib.ExitStack):
        # line-buffered: what a killed daemon leaves is whole rows up to its end
        out = stack.enter_context(open(stack.enter_context(output.writing(keep_partial=True)),
                                       "w", encoding="utf-8", buffering=1))
        out.write(",".join(("time_s", *columns)) + "\n")

        def write(t_s: float, values) -> None:
            try:
                out.write(f"{t_s:.6f}," + ",".join(f"{v:.7f}" for v in values) + "\n")
            except OSError as exc:  # a full disk: the daemon stops, its channels removed
                raise DeviceError(f"cannot write {output.path}: {exc.strerror or exc}",
                                  hint=f"free space or leave out {option}") from None
        return write
    return open_in


def _sim_extra(model, body) -> dict:
    """The simulated daemon's own report: the true largest tilt, the perturbation, the hottest
    motor."""
    import numpy as np

    tmp_c = body.motors.tmp_c[body.index]
    hottest = int(np.argmax(tmp_c))
    return {"max_tilt_deg": body.max_tilt_deg, "perturbation": body.sim.perturbation.to_json(),
            "hottest_motor": {"joint": model.joint_names[hottest],
                              "temperature_c": round(float(tmp_c[hottest]), 3)}}
