"""``hubo task``: list, show and run scripted tasks (``tasks/*.toml``), one shortcut per task."""

from __future__ import annotations

import click
from rich.console import Group
from rich.markup import escape
from rich.progress_bar import ProgressBar
from rich.table import Table

from hubo_cli.cli.hardware import driver_options, hardware_options
from hubo_cli.cli.options import (
    active_stops,
    balance_option,
    live_server,
    perturb_option,
    robot_run_options,
)
from hubo_cli.cli.output import (
    busy,
    console,
    err_console,
    print_json,
    print_run_folder,
    report_interrupt_stop,
    warn,
)
from hubo_cli.control.operator import KEYS_HELP
from hubo_cli.control.stop_choice import SOFT_SOURCES, TASK_SOURCES, check_walk_stops
from hubo_cli.drivers.registry import DRIVER_NAMES
from hubo_cli.errors import EXIT_INTERRUPTED, EXIT_NOT_COMPLETED, InputError, SafetyError
from hubo_cli.runs import shown_name


class TaskGroup(click.Group):
    """``hubo task``: its own commands, then one generic shortcut per other shipped task."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        from hubo_cli.tasks.spec import task_files

        return sorted(set(super().list_commands(ctx)) | {p.stem for p in task_files()})

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        command = super().get_command(ctx, name)
        if command is not None:
            return command
        from hubo_cli.tasks.spec import task_files

        if any(p.stem == name for p in task_files()):
            from hubo_cli.cli.main import with_exit_codes

            return with_exit_codes(_shortcut(name))
        return None


@click.group("task", cls=TaskGroup)
def task() -> None:
    """Scripted tasks on the robot (simulated by default).

    Each task is a TOML file: the stance, the tool, the scene, safety settings and its steps.
    Before anything moves every pose of every step is checked against the kinematics; an
    unreachable task is refused. Runs write runs/<time>-task-<name>/.

    Examples: hubo task list
              hubo task cut-rectangle --speed 20
              hubo task run my-task.toml --set width_mm=120
    """


# ---------------------------------------------------------------------------- options
def run_options(function):
    """The options every way of running a task shares."""
    options = [
        click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
                     help="Override a task parameter (see hubo task show NAME)."),
        click.option("--driver", type=click.Choice(DRIVER_NAMES), default=DRIVER_NAMES[0],
                     show_default=True, help="Robot back end."),
        click.option("--arm", "armed", is_flag=True,
                     help="Arm the hardware driver (required by it)."),
        robot_run_options("task-<name>"),
        click.option("--video", is_flag=True,
                     help="After the run, render video.mp4 from its log (needs hubo-cli[viz])."),
        perturb_option,
        balance_option,
    ]
    function = hardware_options(function)  # listed after the others
    for option in reversed(options):
        function = option(function)
    return function


OPTION_OF = {"width_mm": "--width", "height_mm": "--height", "speed_mm_s": "--speed",
             "wall_distance_mm": "--wall-distance", "direction": "--direction",
             "interpolator": "--interpolator"}


def _overrides(sets: tuple[str, ...], named: dict | None = None) -> dict:
    """Parameter overrides from ``--set`` and the named options; both for one name is refused."""
    from hubo_cli.tasks.spec import parse_override

    values: dict = {}
    for text in sets:
        name, value = parse_override(text)
        if name in values and values[name] != value:
            raise InputError(f"--set {name} is given twice with different values",
                             hint="give each parameter once")
        values[name] = value
    for name, value in (named or {}).items():
        if value is None:
            continue
        if name in values:
            raise InputError(f"{OPTION_OF.get(name, name)} and --set {name}=... both set "
                             f"{name}", hint="give it once")
        values[name] = value
    return values


# ---------------------------------------------------------------------------- list / show
@task.command("list")
@click.option("--json", "as_json", is_flag=True, help="Print the list as JSON.")
def list_tasks(as_json: bool) -> None:
    """The shipped tasks, each with its one-line description."""
    from hubo_cli.tasks.spec import load_task, task_files

    tasks = [load_task(p) for p in task_files()]
    if as_json:
        print_json({"tasks": [{"name": t.name, "description": t.description,
                               "file": str(t.path)} for t in tasks]})
        return
    table = Table(box=None, show_header=False, pad_edge=False)
    for t in tasks:
        table.add_row(f"[bold]{t.name}[/]", t.description)
    console.print(table)


@task.command("show")
@click.argument("name")
@click.option("--json", "as_json", is_flag=True, help="Print the task as JSON.")
def show(name: str, as_json: bool) -> None:
    """A task's parameters, stance, scene, safety settings and steps.

    NAME is a shipped task's name or a .toml file.
    """
    from hubo_cli.tasks.spec import load_task

    spec = load_task(name)
    if as_json:
        print_json({"name": spec.name, "description": spec.description, "file": spec.path,
                    "parameters": spec.parameters, "experiment": spec.experiment,
                    "steps": [{"kind": s.kind, "name": s.name, "description": s.describe()}
                              for s in spec.steps]})
        return
    console.print(f"[bold]{escape(shown_name(spec.name))}[/] — {escape(spec.description)}")
    console.print(f"file        {spec.path}", soft_wrap=True)
    params = ", ".join(f"{k} = {v!r}" for k, v in spec.parameters.items()) or "none"
    console.print(f"parameters  {params}  [dim](--set NAME=VALUE)[/]")
    if spec.experiment:
        console.print(f"experiment  {spec.experiment} (a built-in procedure)")
        return
    st, sc, sa = spec.stance, spec.scene, spec.safety
    distance = "auto" if st.wall_distance_m is None else f"{st.wall_distance_m * 1000:g} mm"
    console.print(f"stance      wall {distance}, {st.arm} arm with the {st.tool}")
    console.print(f"scene       wall {sc.wall_width_m * 1000:g} x {sc.wall_height_m * 1000:g} x "
                  f"{sc.wall_thickness_m * 1000:g} mm; cutting {sc.cutting.coulomb_n:g} N + "
                  f"{sc.cutting.viscous_n_s_per_m:g} N s/m, thrust {sc.cutting.thrust_n:g} N + "
                  f"{sc.cutting.thrust_n_s_per_m:g} N s/m, spindle "
                  f"{sc.cutting.spindle_torque_nm:g} N m"
                  + (f"; depth guide {sc.cutting.guide_depth_m * 1000:g} mm behind the bit's "
                     "middle" if sc.cutting.guide_depth_m else "")
                  + (f"; the wall {sc.wall_misplaced_m * 1000:+g} mm off the plan"
                     if sc.wall_misplaced_m else ""))
    console.print(f"safety      e-stop on {', '.join(sa.estop_sources)}; wrist torque limit "
                  f"{sa.wrist_torque_limit_nm:g} N m; revert {sa.revert_s:g} s, "
                  f"stop {sa.stop_s:g} s")
    for s in spec.steps:
        console.print(f"  {s.number}. [bold]{s.name}[/]: {s.describe()}")


# ---------------------------------------------------------------------------- running
@task.command("run")
@click.argument("file")
@run_options
def run(file: str, **options) -> None:
    """Run a task file (or a shipped task by name).

    Example: hubo task run tasks/cut-rectangle.toml --set speed_mm_s=20
    """
    _run(file, _overrides(options.pop("sets")), **options)


@task.command("cut-rectangle")
@click.option("--width", type=float, default=None, metavar="MM",
              help="Hole width (default 150, the paper's).")
@click.option("--height", type=float, default=None, metavar="MM",
              help="Hole height (default 100).")
@click.option("--speed", type=float, default=None, metavar="MM/S",
              help="Cutting speed along the edges (default 10).")
@click.option("--wall-distance", default=None, metavar="MM|auto",
              help="Neck to wall (default auto: from the workspace map).")
@run_options
def cut_rectangle(width, height, speed, wall_distance, **options) -> None:
    """Drill a rectangular hole out of a cardboard wall (paper V, Fig. 5).

    Counter-clockwise from the upper-left corner, as seen from behind the robot. Writes the
    run folder with log.csv, summary.json, path.png (Fig. 5), wrist_torque.png, snapshot.png.

    Example: hubo task cut-rectangle --width 120 --speed 20
    """
    named = {"width_mm": width, "height_mm": height, "speed_mm_s": speed,
             "wall_distance_mm": wall_distance}
    _run("cut-rectangle", _overrides(options.pop("sets"), named), **options)


@task.command("push-wall")
@click.option("--direction", type=click.Choice(["forward", "left"]), default=None,
              help="forward: both hands 0.25 m into a wall in 4 s; left: the left hand 0.25 m "
                   "into a block on its left in 2 s (default forward).")
@click.option("--interpolator", type=click.Choice(["otg", "hoff-arbib"]), default=None,
              help="Trajectory generator: ruckig or Hoff-Arbib (eq. 1) (default otg).")
@run_options
def push_wall(direction, interpolator, **options) -> None:
    """The emergency-stop experiment (multi-layer controllers paper, IV-C): push a wall.

    With the emergency stopper the capture-point flag reverts the push and the robot stays
    up; with --no-estop it tips over. Writes log.csv, summary.json and cp_error.png.

    Example: hubo task push-wall --direction left --no-estop
    """
    named = {"direction": direction, "interpolator": interpolator}
    _run("push-wall", _overrides(options.pop("sets"), named), **options)


def _shortcut(name: str) -> click.Command:
    @click.command(name, help=f"Run the shipped task '{name}' (see hubo task show {name}).")
    @run_options
    def command(**options) -> None:
        _run(name, _overrides(options.pop("sets")), **options)

    return command


def _run(name: str, overrides: dict, *, driver: str, armed: bool, no_estop: bool,
         estop_sources: str | None, accept_reduced_safety: bool, gui: bool,
         out: str | None, as_json: bool, perturb_seed: int | None, balance: str = "default",
         video: bool = False, live: bool = False, live_host: str | None = None,
         live_port: int | None = None, **hardware) -> None:
    from hubo_cli.cli.replay import add_run_video, check_video_support
    from hubo_cli.runs import reserved_run_dir
    from hubo_cli.tasks.runner import run_experiment
    from hubo_cli.tasks.spec import load_task

    if video:
        check_video_support()
    options = driver_options(driver, armed, **hardware, quiet=as_json)
    spec = load_task(name, overrides,
                     sources_on_command_line=no_estop or estop_sources is not None)
    ctx = click.get_current_context()
    if spec.experiment:
        if driver != "sim":
            raise InputError(f"the {shown_name(spec.name)} experiment runs on the simulated "
                             "robot only",
                             hint="leave out --driver")
        if estop_sources is not None:
            raise InputError(f"the {shown_name(spec.name)} experiment's stopper listens to "
                             "the operator "
                             "and the capture point; --estop-sources does not apply",
                             hint="to run it without the stopper: --no-estop")
        # its procedure names its own run folder (direction, e-stop) and checks --out first
        with live_server(live, live_host, live_port, quiet=as_json) as server:
            done = run_experiment(spec, out=out, gui=gui, estop=not no_estop,
                                  perturb_seed=perturb_seed, balance=balance, live=server)
        if video:
            add_run_video(done.run_dir, done.summary, quiet=as_json)
        printer = _print_push_wall if spec.experiment == "push-wall" else _print_manipulation
        _finish(ctx, done, as_json, lambda: printer(done.summary, done.run_dir))
        return
    # the baseline: what a file lacks is removed by the command line (and so confirmed)
    requested = tuple(s for s in SOFT_SOURCES
                      if s in TASK_SOURCES or s in spec.safety.estop_sources)
    stops = active_stops(requested, driver, no_estop=no_estop,
                         estop_sources=estop_sources,
                         accept_reduced_safety=accept_reduced_safety, quiet=as_json)
    if spec.stance.start_m is not None:
        from hubo_cli.experiments.walk import check_walk_driver

        check_walk_driver(driver)  # review 23: as hubo walk does (the ideal driver has no floor)
        check_walk_stops(stops, "a task that walks to its stance first")
    with (reserved_run_dir(f"task-{spec.name}", out) as run_dir,
          live_server(live, live_host, live_port, quiet=as_json) as server):
        _run_in(ctx, spec, run_dir, driver=driver, options=options, stops=stops,
                gui=gui, as_json=as_json, video=video, perturb_seed=perturb_seed,
                balance=balance, live=server)


def _run_in(ctx: click.Context, spec, run_dir, *, driver: str, options: dict, stops,
            gui: bool, as_json: bool, video: bool, perturb_seed: int | None,
            balance: str, live=None) -> None:
    from hubo_cli.cli.keys import operator_keys
    from hubo_cli.cli.live_view import LiveView
    from hubo_cli.cli.safety_view import SafetyPanel, read_safety
    from hubo_cli.tasks.runner import check_task, run_task

    with busy(f"{shown_name(spec.name)}: pre-flight (laying out and solving every period; "
              "a first run "
              "also maps the arm's workspace, a few seconds)", quiet=as_json):
        plan = check_task(spec)
    if not plan.preflight.ok:
        _refuse(ctx, plan, as_json)
    if not as_json:
        for line in plan.preflight.warnings:  # a move or plunge the joints lag behind
            warn(line)
    state: dict = {}

    def on_start(target, loop) -> None:
        if as_json:
            return
        keys = state["keys"]
        loop.watch_status()
        panel = SafetyPanel(lambda: read_safety(loop, world=loop.driver.world,
                                                robot_flags=target.robot_flags),
                            bell=err_console.bell,
                            release_key="r" if keys else None)
        state["view"] = LiveView(lambda: _view(target, panel, keys is not None),
                                 lambda: _progress_line(target, panel), urgent=panel.alarm,
                                 header=f"keys: {KEYS_HELP}" if keys else None,
                                 transient=True)
        state["view"].start()

    try:
        with operator_keys() as keys:
            state["keys"] = keys
            done = run_task(plan, driver=driver, out=run_dir, gui=gui, stops=stops,
                            on_start=on_start, perturb_seed=perturb_seed,
                            driver_options=options, balance=balance, operator=keys,
                            live=live)
    finally:
        if "view" in state:
            state["view"].stop()
    if video:
        from hubo_cli.cli.replay import add_run_video

        add_run_video(done.run_dir, done.summary, quiet=as_json)
    _finish(ctx, done, as_json, lambda: _print_cut(done.summary, done.run_dir))


def _finish(ctx: click.Context, done, as_json: bool, printer) -> None:
    loop = done.loop
    failure = loop.failure(done.run_dir)
    if as_json:  # the summary, also when the run ended in a device or log failure
        print_json({"run_dir": str(done.run_dir), **done.summary}
                   | ({} if failure is None else {"failure": str(failure),
                                                  "exit_code": failure.exit_code}))
    if failure is not None:
        raise failure
    if not as_json:
        printer()
    report_interrupt_stop(done.summary)
    report_path_miss(done.summary)
    if loop.ended == "interrupted":
        ctx.exit(EXIT_INTERRUPTED)
    if done.summary.get("completed") is False:
        ctx.exit(EXIT_NOT_COMPLETED)


def report_path_miss(summary: dict) -> None:
    """One line on stderr when the outcome check failed the cut: the measured tool point's
    miss (the drill's bit, the hand), the limit and what to check (the run exits 1, not
    completed)."""
    from hubo_cli.tasks.tool import tool_point

    outcome = summary.get("path_outcome")
    if (not outcome or summary["estop"] or summary["ended"] != "done"
            or summary.get("finished_by_operator")):
        return  # (a run stopped otherwise says why already)
    point = tool_point(summary["tool"])
    if outcome["missed"]:
        err_console.print(f"[red]not completed:[/] the measured {point} missed its path by "
                          f"{outcome['path_rms_mm']:.1f} mm RMS while cutting (limit "
                          f"{outcome['limit_mm']:g} mm): check that the joints follow "
                          f"(log.csv's tracking-error flag), the tool's mounting and what "
                          f"pushed the {point}", soft_wrap=True)
    if outcome.get("missed_wall"):
        fix = ("check that the drill's depth guide rests on the face (scene.cutting."
               "guide_depth_m): with none, the thrust drives the bit through the wall"
               if outcome["force_control"] else "check where the wall is against the task's "
               "wall_distance_mm, or cut under force control (a plunge with thrust_n and the "
               "drill's depth guide finds the face)")
        err_console.print(f"[red]not completed:[/] the {point}'s flutes were in the wall "
                          f"{outcome['in_wall_fraction']:.0%} of the cut (at least "
                          f"{outcome['in_wall_min']:.0%} cuts a hole): {fix}", soft_wrap=True)


def _refuse(ctx: click.Context, plan, as_json: bool) -> None:
    from hubo_cli.tasks.runner import preflight_refusal

    worst = plan.preflight.worst_per_step()
    if as_json:
        print_json({"task": plan.spec.name, "parameters": plan.spec.parameters,
                    "refused": True, "completed": False,
                    "stance": plan.placement.to_json(),
                    "misses": [{"step": m.step.name, "number": m.step.number,
                                "kind": m.step.kind, "t_s": m.t_s,
                                "point_mm": m.point_W_m * 1000,
                                "miss_mm": None if m.miss_m is None else m.miss_m * 1000,
                                "legs_too_slow": m.legs_lag} for m in worst],
                    "lagging": [{"step": c.step.name, "number": c.step.number,
                                 "speed_mm_s": c.step.speed_m_s * 1000,
                                 "lag_rms_mm": c.rms_m * 1000, "lag_max_mm": c.max_m * 1000,
                                 "possible_mm_s": c.possible_m_s * 1000}
                                for c in plan.preflight.lagging]})
        ctx.exit(SafetyError.exit_code)
    if worst:
        err_console.print("pre-flight: these steps leave the robot's reach (the farthest pose "
                          "of each)")
    for miss in worst:
        err_console.print(f"  {miss.message()}")
    raise preflight_refusal(plan)


PHASE_WORDS = {"raise": "raising the tool", "run": "running", "settle": "settling",
               "stopped": "[bold red]EMERGENCY STOP: reverted and holding[/]"}


def _progress_line(target, panel) -> str:
    """One plain line of progress (piped output): step, progress, error, safety state."""
    from hubo_cli.tasks.tool import tool_point

    plan = target.plan
    step = plan.spec.steps[min(target.step, len(plan.spec.steps) - 1)]
    phase = "EMERGENCY STOP" if target.phase == "stopped" else target.phase
    return (f"{shown_name(plan.spec.name)}: {phase}, step {step.number}/{len(plan.spec.steps)} "
            f"'{shown_name(step.name)}' {target.step_fraction(target.step):.0%}, "
            f"{tool_point(plan.spec.stance.tool)} error "
            f"{target.error_m * 1000:.1f} mm, wrist {target.torque_nm:.2f} N m | "
            f"{panel.words()}")


def _view(target, panel, keys: bool = False) -> Group:
    """The live view: one progress bar per step, the safety state, error and wrist torque;
    the operator's keys when there are (a terminal)."""
    from hubo_cli.tasks.tool import tool_point

    plan = target.plan
    safety = panel()
    status = PHASE_WORDS[target.phase]
    table = Table(title=f"hubo task {escape(shown_name(plan.spec.name))} — {status}"
                  + (f"   (keys: {KEYS_HELP})" if keys else ""), title_justify="left",
                  box=None, pad_edge=False)
    table.add_column("step")
    table.add_column("progress", width=32)
    table.add_column("")
    current = target.step
    for index, step in enumerate(plan.spec.steps):
        fraction = target.step_fraction(index)
        marker = "[bold]>[/] " if index == current and target.phase != "settle" else "  "
        table.add_row(f"{marker}{step.number}. {escape(shown_name(step.name))}",
                      ProgressBar(total=1.0, completed=fraction, width=30),
                      f"{fraction:4.0%}")
    limit = plan.spec.safety.wrist_torque_limit_nm
    colour = "red" if target.torque_nm > limit else "green"
    table.caption = (f"{tool_point(plan.spec.stance.tool)} error "
                     f"{target.error_m * 1000:5.1f} mm   wrist torque "
                     f"[{colour}]{target.torque_nm:.2f}[/] / {limit:g} N m")
    return Group(safety, table)  # the safety state first: never the part a short screen cuts


def _print_cut(summary: dict, run_dir) -> None:
    from hubo_cli.cli.safety_view import balance_summary_line
    from hubo_cli.tasks.tool import tool_point

    point = tool_point(summary["tool"])
    stance = summary["stance"]
    check = summary.get("path_outcome") or {}
    missed = ("its path" if check.get("missed") else "the wall" if check.get("missed_wall")
              else None)
    why = ("emergency stop" if summary["estop"] else "finished by the operator: q"
           if summary.get("finished_by_operator") else f"the {point} missed {missed}"
           if missed and summary["ended"] == "done" else summary["ended"])
    outcome = "completed" if summary["completed"] else f"[red]did not complete[/] ({why})"
    console.print(f"{escape(shown_name(summary['task']))} {outcome} after "
                  f"{summary['duration_s']:.1f} s "
                  f"({summary['driver']})")
    console.print(f"  stance      wall {stance['wall_distance_mm']:.0f} mm"
                  f"{' (auto)' if stance['auto'] else ''}, work centre y "
                  f"{stance['centre_mm'][0]:+.0f} z {stance['centre_mm'][1]:+.0f} mm")
    if summary["rms_error_mm"] is not None:
        hole = summary.get("hole_rms_error_mm")
        console.print(f"  {point + ' error':<12}{summary['rms_error_mm']:.1f} mm rms, "
                      f"{summary['max_error_mm']:.1f} mm max while cutting (paper: "
                      f"{summary['paper_rms_error_mm']:g} mm)"
                      + (f"; hole in the wall {hole:.1f} mm rms"
                         if hole is not None and not check.get("missed_wall") else ""))
    torque = summary["wrist_torque_nm"]
    parts = [f"{edge} {torque[edge]['mean']:.2f} mean / {torque[edge]['max']:.2f} max"
             for edge in ("horizontal", "vertical") if torque[edge]["samples"]]
    if parts:
        console.print(f"  wrist       {', '.join(parts)} N m while cutting (limit "
                      f"{torque['limit']:g}; paper 0.14 / 0.23 and 0.15 / 0.35)")
    thrust = summary.get("thrust_n") or {}
    if thrust.get("force_control") and thrust.get("samples"):
        console.print(f"  thrust      {thrust['mean']:.1f} N mean, {thrust['min']:.1f} to "
                      f"{thrust['max']:.1f} N while cutting (reference "
                      f"{thrust['reference_mean']:.1f} N; {thrust['share_within_band']:.1%} "
                      f"within +-{thrust['band']:g} N)")
    stop = summary["estop"]
    if stop is None:
        console.print("  e-stop      none")
    else:
        console.print(f"  e-stop      {_stop_words(stop, summary['tool'])}", soft_wrap=True)
    console.print(f"  velocity    {summary['max_joint_velocity_ratio']:.0%} of the limit at most")
    console.print(f"  balance     {balance_summary_line(summary)}", soft_wrap=True)
    print_run_folder(run_dir, summary["files"], width=12, indent="  ")


def _stop_words(stop: dict, tool: str) -> str:
    """The e-stop line of the text summary: what latched it, what the stopper did, and the
    wrist torque and the travel of the ``tool``'s point (the drill's bit, the hand) after the
    latch apart from those before it."""
    from hubo_cli.tasks.tool import tool_point, travel_keys

    point, (along, into, _) = tool_point(tool), travel_keys(tool)
    before = stop["wrist_torque_nm"]
    where = f"step '{stop['step']}'" if stop["step"] is not None else "the approach"
    words = (f"[red]{', '.join(stop['sources'])}[/] at {stop['t_s']:.2f} s in {where}"
             + (f" (wrist {before:.2f} N m)" if before is not None else "") + ": ")
    if stop.get("finished_step"):
        words += "finished the walk's step into a double-support stance"
    elif stop["reverted_to_t_s"] is not None:
        words += f"reverted to the command of {stop['reverted_to_t_s']:.2f} s"
    elif stop["retreat_mm"] is not None:
        words += f"braked and backed the {point} {stop['retreat_mm']:.0f} mm out of the wall"
    else:
        words += "braked"
    if stop["held"]:
        held = stop["held_after_s"]
        words += " and held" + (f" {held:.2f} s after the latch" if held is not None else "")
    after = stop["wrist_torque_after_nm"]
    if after is not None:
        words += f"; after the latch: wrist {after:.2f} N m max"
        if stop[along] is not None:
            words += (f", {point} {stop[along]:.1f} mm along the wall, "
                      f"{stop[into]:.1f} mm into it")
    return words


def _print_push_wall(summary: dict, run_dir) -> None:
    flag = summary["t_emergency_s"]
    cp_flag = summary["t_cp_flag_s"]
    outcome = "FELL" if summary["fell"] else "tipped" if summary["tipped"] else "stayed up"
    console.print(f"push              {summary['direction']}, {summary['push_m']:g} m in "
                  f"{summary['push_s']:g} s")
    console.print(f"emergency stop    {summary['estop']}"
                  + (f" (revert {summary['revert_s']:g} s, stop {summary['stop_s']:g} s)"
                     if summary["estop"] == "on" else ""))
    console.print("capture-point flag "
                  + (f"at {cp_flag:.3f} s" if cp_flag is not None else "never raised"))
    console.print("emergency         "
                  + (f"at {flag:.3f} s ({', '.join(summary['emergency_sources'])})"
                     if flag is not None else "none"))
    console.print(f"robot             {outcome}: max tilt {summary['max_tilt_deg']:.1f} deg, "
                  f"sole lift {summary['max_sole_lift_mm']:.0f} mm")
    console.print(f"max CP error      {summary['max_cp_error_mm']:.1f} mm along "
                  f"{summary['cp_error_axis']}")
    console.print(f"ended             {summary['ended']} after {summary['duration_s']:.2f} s")
    print_run_folder(run_dir, summary["files"])


def _print_manipulation(summary: dict, run_dir) -> None:
    outcome = "FELL" if summary["fell"] else "tipped" if summary["tipped"] else "stayed up"
    if summary["overloaded"]:
        outcome += ", arm OVERLOADED"
    if summary["wrist_overloaded"]:
        outcome += ", wrist OVERLOADED"
    flag = summary["t_emergency_s"]
    what = "valve" if summary["experiment"] == "turn-valve" else "door"
    console.print(f"experiment        {summary['experiment']} ({escape(summary['case'])})")
    console.print(f"emergency stop    {summary['estop']}"
                  + (f", at {flag:.3f} s ({', '.join(summary['emergency_sources'])})"
                     if flag is not None else ", never raised" if summary["estop"] == "on"
                     else ""))
    console.print(f"{what:<18}{summary['object_angle_deg']:.1f} deg at the end (planned "
                  f"{summary['planned_deg']:g})"
                  + (f", gripped at {summary['grasped_at_s']:.2f} s"
                     if summary.get("grasped_at_s") is not None else
                     ", never gripped" if what == "valve" else ""))
    console.print(f"robot             {outcome}: max tilt {summary['max_tilt_deg']:.1f} deg, "
                  f"sole lift {summary['max_sole_lift_mm']:.0f} mm")
    if summary["min_com_inside_mm"] is not None and summary["end_tilt_deg"] is not None:
        console.print(f"centre of mass    {summary['min_com_inside_mm']:.0f} mm inside the soles "
                      f"at the least; tilt {summary['end_tilt_deg']:.1f} deg at the end")
    console.print(f"max CP error      {summary['max_cp_error_mm']:.1f} mm")
    limit = summary["wrist_limit_nm"]
    console.print(f"wrist sensor      {summary['max_axial_force_n']:.0f} N along the forearm, "
                  f"{summary['max_wrist_moment_nm']:.1f} N m bending at most"
                  + (f", beyond the wrist's {limit:g} N m for "
                     f"{summary['wrist_over_limit_s']:.2f} s" if limit is not None else ""))
    console.print(f"arm motors        up to "
                  f"{summary['max_arm_torque_ratio'] * 100:.0f} % of their limit")
    console.print(f"ended             {summary['ended']} after {summary['duration_s']:.2f} s")
    print_run_folder(run_dir, summary["files"])
