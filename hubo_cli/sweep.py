"""Many perturbed simulations at once: every combination of seeds and parameter values.

A sweep is a list of :class:`Job` (one command, one perturbation seed, one value per swept
parameter). Each job is an independent simulation with its own run folder; :func:`run_job`
runs one and returns its :class:`Row`. :func:`run_sweep` runs them all, in this process one
after the other (``workers=0``), on a Dask ``LocalCluster`` of worker processes on the loopback
interface (the default, one worker per core), or on an existing Dask cluster (``scheduler``,
e.g. ``tcp://host:8786``; the workers need hubo-cli installed). A job's result depends only on
the job, so the rows are the same whichever way they ran (except the wall-clock).

Commands: ``sim`` (the standing experiment; parameters ``duration`` in s, default 5, and
``push`` in N) or any task (``cut-rectangle``, ``cut-slot``, ``push-wall`` or a ``.toml`` file;
parameters are the task's, as ``--set``).
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import logging
import math
import os
import re
import socket
import textwrap
import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import CancelledError
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from hubo_cli.errors import (
    EXIT_INTERRUPTED,
    EXIT_NOT_COMPLETED,
    DeviceError,
    HuboError,
    InputError,
    SafetyError,
    quoted,
)
from hubo_cli.interrupts import stopping
from hubo_cli.outputs import replacing

SIM_COMMAND = "sim"
SIM_PARAMETERS = {"duration": 5.0, "push": 0.0}
TABLE_NAME = "sweep.csv"
PLOT_NAME = "sweep.png"
CONFIRM_JOBS = 10_000  # a sweep of more simulations than this needs an explicit yes
MAX_JOBS = 1_000_000  # never more in one sweep (the job list alone would fill the memory)
MAX_SEED_DIGITS = 18
CONNECT_TIMEOUT_S = 10.0
WORKERS_PER_CORE = 4
SCHEDULER_EXAMPLE = "tcp://host:8786"
# --dashboard: the local cluster's dashboard, on the loopback interface only (another machine
# reaches it through an ssh tunnel); Dask moves it to a free port when 8787 is taken
DASHBOARD_ADDRESS = "127.0.0.1:8787"
# what must match between this client and every worker: Dask's own wire (its required
# packages and the interpreter) and what decides a row (hubo-cli and the numerics under it)
DASK_PACKAGES = ("python", "dask", "distributed", "msgpack", "cloudpickle", "tornado", "toolz")
ROW_PACKAGES = ("hubo-cli", "numpy", "scipy", "pybullet", "pin", "ruckig", "numba")
# and hubo-cli's own source files (two checkouts of one version may differ): their fingerprint
# (hubo_cli.resources.source_fingerprint), compared as if it were one more package
SOURCES = "hubo-cli sources"
# the versions equal, the files differ: reinstalling the same files would not help
SOURCES_HINT = ("the versions match but the files differ: compare the checkouts' hubo_cli/*.py "
                "and robots/ *.toml, *.urdf (git status: an edit or a stray file there counts)")


@dataclass(frozen=True)
class Job:
    """One simulation of a sweep.

    Attributes:
        command: ``sim`` or a task name or file.
        seed: the perturbation seed (0: the nominal robot).
        parameters: (name, value) pairs, the task's ``--set`` (or ``sim``'s duration/push).
        balance: the balancer, ``default``, ``paper`` or ``off`` (``--balance``).
        task: a task's file and text, read once by :func:`make_jobs` (a FIFO gives its text
            once; a Dask worker need not see the file); None for ``sim``.
    """

    command: str
    seed: int
    parameters: tuple[tuple[str, object], ...] = ()
    balance: str = "default"
    task: tuple[str, str] | None = field(default=None, repr=False, compare=False)

    def spec(self):
        """The job's task, resolved with its parameters from the text read once.

        Raises:
            ConfigError: a bad parameter value or task text.
        """
        from hubo_cli.tasks.spec import parse_task, read_task

        path, text = self.task or read_task(self.command)
        return parse_task(Path(path), text, dict(self.parameters))

    @property
    def name(self) -> str:
        """A folder name for the job's run: command, seed, parameter values (and the balancer
        when not the default)."""
        parts = [Path(self.command).stem, f"seed{self.seed}"]
        parts += [f"{k}={v}" for k, v in self.parameters]
        if self.balance != "default":
            parts.append(f"balance={self.balance}")
        return re.sub(r"[^A-Za-z0-9_.=+-]", "_", "-".join(parts))


@dataclass
class Row:
    """What one simulation showed (the sweep table's columns).

    Attributes:
        completed: the task completed (``sim``: the robot did not fall); False when refused
            or when the run stopped on an error (then :attr:`error` and :attr:`exit_code`
            are that error's, as the run alone exits with it).
        estop: the sources of the first emergency stop (``+``-joined), "" when none.
        hole_rms_mm: the hole's RMS error in the wall plane (tasks that cut), else None.
        min_support_margin_mm: the smallest distance of the capture point inside the support
            polygon of the soles on the ground over the run (negative: it left the polygon;
            the e-stop fires below the monitor's 30 mm), None without the monitor.
        max_tilt_deg: the largest true torso tilt from upright (deg).
        wall_clock_s: how long the job took where it ran (s).
        ended: how the control loop ended (or ``refused``: refused for safety before
            anything moved; ``error``: another error, :attr:`exit_code` says which).
        error: the error message, "" when none: what ``hubo task run`` (``hubo sim``) says.
        run_dir: the job's run folder, "" when it wrote none (refused before any run; a
            folder an earlier sweep left in a reused ``--out`` is not named).
        exit_code: the run's outcome as the README's exit codes say it (for a task, what
            ``hubo task run`` exits with): 0 completed, 1 not completed (or another error),
            2 bad input or configuration, 3 device trouble, 4 refused for safety (nothing
            moved), 5 no IK solution, 130 interrupted.
    """

    command: str
    seed: int
    parameters: dict
    completed: bool
    estop: str = ""
    hole_rms_mm: float | None = None
    min_support_margin_mm: float | None = None
    max_tilt_deg: float | None = None
    wall_clock_s: float = 0.0
    ended: str = ""
    error: str = ""
    run_dir: str = ""
    exit_code: int = 0

    def outcome(self) -> dict:
        """Everything but the wall-clock and the folder: equal for equal jobs anywhere."""
        row = asdict(self)
        del row["wall_clock_s"], row["run_dir"]
        return row


def parse_seeds(text: str) -> list[int]:
    """``A-B`` (inclusive), ``A`` or ``A,B,C`` -> seeds (at most :data:`MAX_JOBS`).

    Raises:
        InputError: not that form, negative, B < A, or more than MAX_JOBS seeds.
    """
    ranges: list[range] = []
    for part in text.split(","):
        match = re.fullmatch(rf"\s*(\d{{1,{MAX_SEED_DIGITS}}})\s*"
                             rf"(?:-\s*(\d{{1,{MAX_SEED_DIGITS}}})\s*)?", part)
        if not match:
            raise InputError(f"--seeds {quoted(text)} is not A-B, A or A,B,C (integers >= 0 of at "
                             f"most {MAX_SEED_DIGITS} digits)", hint="e.g. --seeds 1-20")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise InputError(f"--seeds {quoted(part.strip())}: the range ends before it starts",
                             hint="e.g. --seeds 1-20")
        ranges.append(range(first, last + 1))
    count = sum(len(r) for r in ranges)  # before listing them: 1-100000000 is refused at once
    if count > MAX_JOBS:
        raise InputError(f"--seeds {quoted(text)} makes {count:,} runs; a sweep runs at most "
                         f"{MAX_JOBS:,}", hint="split the seeds into several sweeps")
    return list(dict.fromkeys(itertools.chain.from_iterable(ranges)))


def parse_sets(sets: Sequence[str]) -> dict[str, list[object]]:
    """``NAME=V1,V2,...`` (each ``--set``) -> name -> values (numbers, true/false, TOML lists
    such as ``[a,b]`` or text).

    Raises:
        InputError: not NAME=VALUES, an empty value, or a name given twice (review 22: the
            last ``--set`` of a name replaced the first without a word; ``hubo task`` refuses
            it too).
    """
    from hubo_cli.tasks.spec import parse_override

    values: dict[str, list[object]] = {}
    for text in sets:
        name, sep, listed = text.partition("=")
        items = _split_values(listed)
        if not sep or not name.strip() or not all(item.strip() for item in items):
            raise InputError(f"--set {quoted(text)} is not NAME=V1,V2,... (no empty value)",
                             hint="e.g. --set speed_mm_s=10,20,40")
        if name.strip() in values:
            raise InputError(f"--set {name.strip()} is given twice",
                             hint=f"give all its values in one: --set {name.strip()}=V1,V2,...")
        values[name.strip()] = [parse_override(f"{name}={v}")[1] for v in items]
    return values


def _split_values(listed: str) -> list[str]:
    """``10,20`` -> ``['10', '20']``; commas inside ``[...]`` belong to a list value."""
    items, depth, start = [], 0, 0
    for i, char in enumerate(listed):
        depth += (char == "[") - (char == "]")
        if char == "," and depth == 0:
            items.append(listed[start:i])
            start = i + 1
    return [*items, listed[start:]]


def job_count(n_seeds: int, sets: dict[str, list[object]]) -> int:
    """How many simulations :func:`make_jobs` would make (without making them)."""
    return n_seeds * math.prod(len(v) for v in sets.values())


def check_size(n_jobs: int, confirmed: bool) -> None:
    """A sweep of more than :data:`CONFIRM_JOBS` simulations runs only when ``confirmed``, and
    never more than :data:`MAX_JOBS`.

    Raises:
        InputError: too many, or not confirmed.
    """
    if n_jobs > MAX_JOBS:
        raise InputError(f"the sweep makes {n_jobs:,} runs; a sweep runs at most {MAX_JOBS:,}",
                         hint="split it into several sweeps (fewer --seeds or --set values)")
    if n_jobs > CONFIRM_JOBS and not confirmed:
        raise InputError(f"the sweep makes {n_jobs:,} runs (more than {CONFIRM_JOBS:,}) and "
                         f"was not confirmed", hint="add --yes to run them all")


def check_workers(workers: int | None) -> None:
    """At most :data:`WORKERS_PER_CORE` local worker processes per core (each holds a
    simulator; more only compete for the cores and the memory).

    Raises:
        InputError: more.
    """
    most = WORKERS_PER_CORE * (os.cpu_count() or 1)
    if workers is not None and workers > most:
        raise InputError(f"--workers {workers}: at most {most} on this machine "
                         f"({WORKERS_PER_CORE} per core)",
                         hint="leave out --workers (one per core), or use --scheduler")


def check_scheduler(address: str) -> str:
    """A Dask scheduler address, ``tcp://HOST:PORT`` or ``HOST:PORT``, that answers; returns
    it as ``tcp://HOST:PORT``. Checked before anything runs.

    Raises:
        InputError: not that form (another scheme, no host, a port that is not 1-65535).
        DeviceError: nothing accepts a connection there, or what does is not a Dask
            scheduler (no Dask handshake within :data:`CONNECT_TIMEOUT_S`).
    """
    match = re.fullmatch(r"(?:tcp://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9][A-Za-z0-9.-]*):(\d{1,5})",
                         address)
    port = int(match.group(2)) if match else 0
    if not 0 < port < 65536:
        raise InputError(f"--scheduler {quoted(address)} is not a Dask scheduler address "
                         f"(tcp://HOST:PORT, port 1-65535)", hint=f"e.g. {SCHEDULER_EXAMPLE}")
    host = match.group(1).strip("[]")
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        raise DeviceError(f"cannot reach the Dask scheduler at {address}: "
                          f"{exc.strerror or exc}",
                          hint="start it (dask scheduler) or check the address") from None
    address = f"tcp://{match.group(1)}:{port}"
    if not _answers_as_dask(address):
        raise DeviceError(f"the service at {address} does not answer as a Dask scheduler "
                          f"within {CONNECT_TIMEOUT_S:g} s",
                          hint="check the address (a Dask scheduler listens on 8786 by "
                               "default)")
    return address


def check_dashboard() -> None:
    """Dask's dashboard can be served: bokeh is installed (the ``bokeh`` extra).

    Raises:
        InputError: it is not.
    """
    import importlib.util

    if importlib.util.find_spec("bokeh") is None:
        raise InputError("--dashboard: Dask's dashboard needs bokeh, which is not installed",
                         hint="pip install 'hubo-cli[bokeh]' (make installs it)")


def version_mismatches(versions: dict) -> list[str]:
    """What differs between this client and the cluster, from Dask's ``get_versions``.

    Every worker must have the client's :data:`DASK_PACKAGES` and :data:`ROW_PACKAGES`, and
    then its :data:`SOURCES` (the fingerprint of hubo-cli's files, added to each ``packages``
    by :func:`_check_versions`); the scheduler the client's :data:`DASK_PACKAGES` (it runs no
    job). Python is compared by its minor version (3.11). Returns one text per difference,
    e.g. ``"worker tcp://10.0.0.2:40111 has hubo-cli 0.0.9 (this client 0.1.0)"``; empty when
    everything matches.
    """

    def version(packages: dict, name: str) -> str | None:
        found = packages.get(name)
        if name == "python" and isinstance(found, str):  # 3.11.7.final.0: the minor version
            return ".".join(found.split(".")[:2])  # decides the bytecode cloudpickle ships
        return found

    client = (versions.get("client") or {}).get("packages") or {}

    def differences(who: str, info, names) -> list[str]:
        packages = (info or {}).get("packages") if isinstance(info, dict) else None
        if not isinstance(packages, dict):
            return [f"{who} did not report its versions"]
        absent = "not reported" if names == (SOURCES,) else "not installed"
        return [f"{who} has {name} {version(packages, name) or absent} "
                f"(this client {version(client, name) or absent})"
                for name in names if version(packages, name) != version(client, name)]

    found = differences("the scheduler", versions.get("scheduler"), DASK_PACKAGES)
    for address, info in sorted((versions.get("workers") or {}).items()):
        found += differences(f"worker {address}", info, DASK_PACKAGES + ROW_PACKAGES)
    if not found:  # the sources last: a worker of another version has other sources too
        for address, info in sorted((versions.get("workers") or {}).items()):
            found += differences(f"worker {address}", info, (SOURCES,))
    return found


def _check_versions(client) -> None:
    """Raise InputError when the cluster's versions differ from this client's."""
    from hubo_cli.resources import source_fingerprint

    try:
        versions = client.get_versions(packages=list(ROW_PACKAGES))
        # a worker whose hubo-cli has no fingerprint (an older one) returns the error: a
        # difference like any other
        sources = client.run(source_fingerprint, on_error="return")
    except (OSError, TimeoutError):  # Dask's CommClosedError is one
        raise DeviceError("lost the connection to the Dask scheduler while asking the "
                          "workers' versions", hint="check the scheduler and try again") from None
    client_packages = (versions.get("client") or {}).get("packages")
    if isinstance(client_packages, dict):
        client_packages[SOURCES] = source_fingerprint()
    for address, info in (versions.get("workers") or {}).items():
        packages = info.get("packages") if isinstance(info, dict) else None
        if isinstance(packages, dict):
            fingerprint = sources.get(address)
            packages[SOURCES] = fingerprint if isinstance(fingerprint, str) else None
    found = version_mismatches(versions)
    if found:
        more = f" (and {len(found) - 1} more difference{'s' * (len(found) > 2)})" \
            if len(found) > 1 else ""
        sources_only = all(f" {SOURCES} " in difference for difference in found)
        raise InputError(f"the Dask cluster does not run this client's versions: "
                         f"{found[0]}{more}; nothing ran",
                         hint=SOURCES_HINT if sources_only else
                         "install hubo-cli on every worker from the same checkout and lock: "
                         "pip install -c requirements.lock -e .")


def _answers_as_dask(address: str) -> bool:
    """Dask's own handshake with ``address`` completes within :data:`CONNECT_TIMEOUT_S`."""
    import asyncio

    from distributed.comm import connect

    async def handshake() -> None:
        comm = await connect(address, timeout=CONNECT_TIMEOUT_S)
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(handshake(), CONNECT_TIMEOUT_S))
    except Exception:  # noqa: BLE001 (a service that is not Dask can make it fail any way)
        return False
    return True


def make_jobs(command: str, seeds: Sequence[int], sets: dict[str, list[object]],
              balance: str = "default") -> list[Job]:
    """Every combination of seeds and parameter values, seeds outermost, with the balancer
    ``balance``; a task's file is read here, once, and each job carries its text.

    Raises:
        ConfigError: the task file is missing, not a file or unreadable.
    """
    from hubo_cli.tasks.spec import read_task

    task = None
    if command != SIM_COMMAND:
        path, text = read_task(command)
        task = (str(path), text)
    names = list(sets)
    return [Job(command, seed, tuple(zip(names, combo, strict=True)), balance, task)
            for seed in seeds for combo in itertools.product(*(sets[n] for n in names))]


def check_jobs(jobs: Sequence[Job]) -> None:
    """Refuse a sweep whose command or any parameter value is unknown or out of range before
    anything runs (every distinct combination of values is checked).

    Raises:
        HuboError: an unknown task, a bad task file or parameter value (ConfigError), an
            unknown ``sim`` parameter or a bad value of one (InputError).
    """
    from hubo_cli.experiments.standing import check_standing_args
    from hubo_cli.model import load_model

    combinations = {(j.command, repr(j.parameters)): j for j in jobs}
    for job in combinations.values():
        command, parameters = job.command, job.parameters
        if command != SIM_COMMAND:
            _check_task(job.spec())
            continue
        unknown = [n for n, _ in parameters if n not in SIM_PARAMETERS]
        if unknown:
            raise InputError(f"sim has no parameter {', '.join(unknown)}",
                             hint=f"use {', '.join(SIM_PARAMETERS)}")
        for name, value in parameters:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"--set {name}={value}: sim's {name} must be a number",
                                 hint="e.g. --set push=0,30")
        params = SIM_PARAMETERS | dict(parameters)
        try:
            check_standing_args(float(params["duration"]), float(params["push"]),
                                load_model())  # the robot _run_sim stands
        except InputError as exc:
            example = "duration=5" if exc.message.startswith("duration") else "push=0,30"
            raise InputError(f"--set: sim's {exc}", hint=f"e.g. --set {example}") from None


def _check_task(spec) -> None:
    """What ``hubo task run`` refuses of a task before its pre-flight, checked without one:
    an experiment's parameters, a task's length (ConfigError, InputError: exit 2)."""
    if spec.experiment:
        from hubo_cli.tasks.runner import check_experiment

        check_experiment(spec)
    else:
        from hubo_cli.tasks.plan import check_duration

        check_duration(spec)


def run_job(job: Job, out_dir: str | Path, task: tuple[str, str] | None = None) -> Row:
    """Run one simulation (in whatever process calls it) into ``out_dir/<job name>``;
    ``task``, if given, is the job's task file and text (sent apart from the job)."""
    if task is not None:
        job = replace(job, task=task)
    t0 = time.perf_counter()
    run_dir = Path(out_dir) / job.name
    before = _folder_state(run_dir)  # a reused --out may hold an earlier sweep's folder
    try:
        row, failure = (_run_sim if job.command == SIM_COMMAND else _run_task)(job, run_dir)
        if failure is not None:  # the loop stopped on an error: what the run alone exits with
            row = error_row(job, failure, measured=row)
    except HuboError as exc:
        row = error_row(job, exc)
        # refused before its run wrote anything: an earlier sweep's folder is not this job's
        if _folder_state(run_dir) == before:
            run_dir = None
    row.completed = row.completed and row.ended != "interrupted"  # Ctrl-C or SIGTERM
    if row.ended == "interrupted":
        row.exit_code = EXIT_INTERRUPTED
    elif not row.completed and row.exit_code == 0:
        row.exit_code = EXIT_NOT_COMPLETED
    row.wall_clock_s = time.perf_counter() - t0
    # a run refused before it wrote anything leaves no folder (as hubo task run): none named
    row.run_dir = str(run_dir) if run_dir is not None and run_dir.is_dir() else ""
    return row


def _folder_state(folder: Path) -> dict[str, tuple[int, int]]:
    """Each file's name -> (modification time in ns, size) directly in ``folder`` (its run
    marker left out: taking the folder rewrites it), {} when there is no such folder: what a
    job wrote there shows as a difference."""
    from hubo_cli.runs import MARKER

    try:
        entries = list(os.scandir(folder))
    except OSError:
        return {}
    state = {}
    for entry in entries:
        if entry.name != MARKER:
            with contextlib.suppress(OSError):
                info = entry.stat(follow_symlinks=False)
                state[entry.name] = (info.st_mtime_ns, info.st_size)
    return state


def error_row(job: Job, exc: BaseException, measured: Row | None = None) -> Row:
    """The row of a job that ended with ``exc``: ``refused`` for a safety refusal (nothing
    moved), else ``error``; the message and exit code are what the run alone gives. With
    ``measured``, the row of a run whose loop stopped on ``exc`` (its
    :meth:`~hubo_cli.control.loop.LoopResult.failure`, e.g. the robot's state lost): its
    measurements and ``ended`` kept, not completed, with that message and exit code."""
    code = exc.exit_code if isinstance(exc, HuboError) else EXIT_NOT_COMPLETED
    message = str(exc) if isinstance(exc, HuboError) else f"{type(exc).__name__}: {exc}"
    if measured is not None:
        return replace(measured, completed=False, error=message, exit_code=code)
    return Row(job.command, job.seed, dict(job.parameters), completed=False,
               ended="refused" if isinstance(exc, SafetyError) else "error", error=message,
               exit_code=code)


def sweep_exit_code(rows: Sequence[Row]) -> int:
    """The sweep's exit code from its rows: theirs when they all agree (every run completed:
    0; every run refused for safety: 4), else 1 (some run did not complete)."""
    codes = {row.exit_code for row in rows}
    return codes.pop() if len(codes) == 1 else EXIT_NOT_COMPLETED


def _first_stop(summary: dict) -> str:
    stops = [e for e in summary.get("estop_events", []) if e["kind"] == "stop"]
    return "+".join(stops[0]["sources"]) if stops else ""


def _run_sim(job: Job, run_dir: Path) -> tuple[Row, HuboError | None]:
    from hubo_cli.control.pipeline import SafetyProfile
    from hubo_cli.experiments.standing import stand
    from hubo_cli.model import load_model

    params = SIM_PARAMETERS | dict(job.parameters)
    profile = SafetyProfile().with_balance(job.balance)
    result = stand(load_model(), float(params["duration"]), float(params["push"]),
                   profile.balance, out=run_dir, perturb_seed=job.seed,
                   balance_mode=profile.balance_mode)
    summary = _read_summary(run_dir)
    return Row(job.command, job.seed, dict(job.parameters), completed=not result.fell,
               estop=_first_stop(summary),
               min_support_margin_mm=summary["min_support_margin_mm"],
               max_tilt_deg=summary["max_torso_tilt_deg"], ended=summary["ended"]), \
        result.failure


def _run_task(job: Job, run_dir: Path) -> tuple[Row, HuboError | None]:
    from hubo_cli.tasks.runner import check_task, run_experiment, run_task

    spec = job.spec()
    if spec.experiment:
        done = run_experiment(spec, out=run_dir, perturb_seed=job.seed, balance=job.balance)
    else:  # a plan that fails pre-flight is refused (SafetyError) as by hubo task run
        done = run_task(check_task(spec), out=run_dir, perturb_seed=job.seed,
                        balance=job.balance)
    summary = done.summary
    completed = summary.get("completed")
    if completed is None:  # an experiment: it completed unless the robot fell or tipped
        completed = not (summary.get("fell") or summary.get("tipped"))
    return Row(job.command, job.seed, dict(job.parameters), completed=bool(completed),
               estop=_first_stop(summary), hole_rms_mm=summary.get("hole_rms_error_mm"),
               min_support_margin_mm=summary.get("min_support_margin_mm"),
               max_tilt_deg=summary["max_torso_tilt_deg"], ended=summary["ended"]), \
        done.loop.failure(done.run_dir)


def _read_summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))


@dataclass
class SweepResult:
    """A finished (or interrupted) sweep: its rows in job order, where it ran, how long."""

    rows: list[Row]
    jobs: int
    where: str
    wall_clock_s: float
    interrupted: bool = False
    out_dir: Path | None = None
    cut_short: list[Path] = field(default_factory=list)


def run_sweep(jobs: Sequence[Job], out_dir: str | Path, *, workers: int | None = None,
              scheduler: str | None = None,
              on_row: Callable[[Row, int, int], None] | None = None,
              on_dashboard: Callable[[str | None], None] | None = None) -> SweepResult:
    """Run every job and write the table and the plot into ``out_dir``.

    Args:
        jobs: from :func:`make_jobs`.
        out_dir: the sweep folder (``sweep.csv``, ``sweep.png`` and one run folder per job).
        workers: 0 = one after the other in this process; None = a LocalCluster with one
            worker process per core; n = a LocalCluster of n worker processes.
        scheduler: the address of an existing Dask scheduler (``workers`` is then ignored).
        on_row: called with each finished row, the number done and the total (progress).
        on_dashboard: given, the local cluster serves Dask's dashboard (needs bokeh, see
            :func:`check_dashboard`) and this is called with its link once the cluster is up;
            with ``scheduler``, with the scheduler's link, or None when it serves none.
            Without it the local cluster opens no dashboard.

    Before any job runs, the cluster's versions are checked against this process's
    (:func:`version_mismatches`): a difference raises InputError.

    A KeyboardInterrupt cancels the jobs still running; the finished rows are kept and
    written (``interrupted`` is then True). A run the interrupt cut short in a killed local
    worker has its log finished as ``hubo export`` would (:func:`recover_runs`; listed in
    ``cut_short``); it has no summary and no row.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n_workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    if scheduler is not None:
        where = f"the Dask cluster at {scheduler}"
    elif workers == 0:
        where = "this process, one job after the other"
    else:
        where = f"a local Dask cluster of {n_workers} worker process{'es' * (n_workers > 1)}"
    t0 = time.perf_counter()
    done: dict[int, Row] = {}
    interrupted = False

    def finished(index: int, row: Row) -> None:
        done[index] = row
        if on_row is not None:
            on_row(row, len(done), len(jobs))

    lost: DeviceError | None = None
    try:
        if scheduler is None and workers == 0:
            for index, job in enumerate(jobs):
                row = run_job(job, out_dir)
                finished(index, row)
                if row.ended == "interrupted":  # the run took the Ctrl-C (SIGTERM): stop here
                    raise KeyboardInterrupt
        else:
            _run_on_dask(jobs, out_dir, n_workers, scheduler, finished, on_dashboard)
    except KeyboardInterrupt:
        interrupted = True
    except DeviceError as exc:
        lost = exc
    rows = [done[i] for i in sorted(done)]
    write_table(rows, out_dir / TABLE_NAME)  # first: a second Ctrl-C in the logs' recovery
    if rows:                                 # below leaves the table written (and the cut
        plot_sweep(rows, out_dir / PLOT_NAME)  # logs recoverable by hubo export)
    cut = recover_runs(out_dir, [job for i, job in enumerate(jobs) if i not in done])
    result = SweepResult(rows, len(jobs), where, time.perf_counter() - t0, interrupted, out_dir,
                         cut)
    if lost is not None and not rows:
        raise lost
    if lost is not None:
        raise DeviceError(f"{lost} after {len(rows)} of {len(jobs)} runs; the finished rows "
                          f"are in {out_dir / TABLE_NAME}", hint=lost.hint) from None
    return result


def recover_runs(out_dir: Path, unfinished: Sequence[Job]) -> list[Path]:
    """Finish the logs of the unfinished jobs' runs that a killed worker left with only their
    records (``log.rows``), as ``hubo export`` would; returns those run folders. A run still
    being written (a remote worker that goes on) is left to finish itself."""
    from hubo_cli.control.log import ROWS_NAME, recover_log

    recovered = []
    for job in unfinished:
        run_dir = out_dir / job.name
        if (run_dir / ROWS_NAME).exists():
            with contextlib.suppress(InputError, OSError):  # still running, or unreadable
                if recover_log(run_dir):
                    recovered.append(run_dir)
    return recovered


def _run_on_dask(jobs, out_dir: Path, n_workers: int, scheduler: str | None,
                 finished: Callable[[int, Row], None],
                 on_dashboard: Callable[[str | None], None] | None) -> None:
    """Submit every job and hand back each row as it finishes.

    Raises:
        DeviceError: the connection to the scheduler was lost (the rows handed back so far
            are all there is).
    """
    import distributed  # noqa: F401  (its loggers exist from here on)
    from dask import config

    # a lost scheduler is reported once, by us, not as pages of Dask's tracebacks
    quiet = {name: logging.getLogger(name) for name in list(logging.root.manager.loggerDict)
             if name.split(".")[0] == "distributed"}
    levels = {name: logger.level for name, logger in quiet.items()}
    for logger in quiet.values():
        logger.setLevel(logging.CRITICAL + 1)
    try:
        with config.set({"distributed.worker.daemon": False,
                         "distributed.admin.system-monitor.gil.enabled": False}):
            _submit_all(jobs, out_dir, n_workers, scheduler, finished, on_dashboard)
    finally:
        for name, logger in quiet.items():
            logger.setLevel(levels[name])


def _submit_all(jobs, out_dir: Path, n_workers: int, scheduler: str | None,
                finished: Callable[[int, Row], None],
                on_dashboard: Callable[[str | None], None] | None) -> None:
    from distributed import Client, LocalCluster, as_completed
    from distributed.versions import VersionMismatchWarning

    cluster = None
    try:
        if scheduler is not None:
            with warnings.catch_warnings():  # Dask's table of them; _check_versions says it
                warnings.simplefilter("ignore", VersionMismatchWarning)
                client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        else:
            # without on_dashboard no dashboard: the scheduler's own HTTP routes on a free
            # loopback port (it would take 8787 by default)
            http = DASHBOARD_ADDRESS if on_dashboard else "127.0.0.1:0"
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   host="127.0.0.1",
                                   dashboard_address=http if on_dashboard else None,
                                   scheduler_kwargs={"dashboard_address": http},
                                   silence_logs=logging.CRITICAL)
            client = Client(cluster)
    except Exception as exc:  # noqa: BLE001 (nothing has run; garbage from a service that
        # is not a Dask scheduler can make Dask fail in any way, even a MemoryError)
        if cluster is not None:
            cluster.close()
        where = (f"connect to a Dask scheduler at {scheduler}" if scheduler
                 else "start a local Dask cluster")
        why = exc if isinstance(exc, OSError | TimeoutError) else "it did not answer as one"
        raise DeviceError(f"cannot {where}: {why}",
                          hint="check the address and that it is a Dask scheduler"
                          if scheduler else "run with --workers 0 (one job after the other)"
                          ) from None
    futures = {}
    interrupted = False
    try:
        _check_versions(client)
        if on_dashboard is not None:
            on_dashboard(_dashboard_link(client))
        texts = {}  # a task's text sent to the cluster once, not with every job, as a task
        for index, job in enumerate(jobs):  # (not scattered: a lost worker's copy is redone)
            if job.task is not None and id(job.task) not in texts:
                texts[id(job.task)] = client.submit(_same, job.task, pure=False,
                                                    key=f"hubo-sweep-task-{index}")
            future = client.submit(run_job, replace(job, task=None), str(out_dir.resolve()),
                                   texts.get(id(job.task)), pure=False,
                                   key=f"hubo-sweep-{index}-{job.name}")
            futures[future] = index
        for future in as_completed(futures):
            index = futures[future]
            try:
                if future.status == "cancelled":  # only a lost scheduler cancels them here
                    raise ConnectionError("cancelled")
                if future.status == "error":
                    row = error_row(jobs[index], future.exception())
                else:
                    row = future.result()
            except (OSError, CancelledError, TimeoutError):  # Dask's CommClosedError is one
                raise DeviceError(f"lost the connection to the Dask scheduler "
                                  f"{scheduler or '(local)'}",
                                  hint="restart the scheduler and sweep the missing seeds "
                                       "again") from None
            finished(index, row)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM
        interrupted = True
        raise
    finally:
        with stopping() if interrupted else contextlib.nullcontext():
            if interrupted and cluster is not None:
                _kill_local_workers()
            # after a lost scheduler, cancelling and closing may fail too: nothing to report
            with contextlib.suppress(Exception):
                client.cancel(list(futures))
                client.close()
            if cluster is not None:
                cluster.close()


def _same(value):
    """``value`` itself: a task's text as a Dask task of its own (see :func:`_submit_all`)."""
    return value


def _kill_local_workers() -> None:
    """End the local cluster's worker processes at once (an interrupted sweep): a worker in
    the middle of a simulation does not stop for the cluster's graceful close, which took
    about 5 s; its run is cut short either way (its ``log.rows`` can be recovered)."""
    import psutil

    def is_worker(process) -> bool:  # not multiprocessing's resource tracker: it cleans up
        with contextlib.suppress(psutil.Error):
            return not any("resource_tracker" in part for part in process.cmdline())
        return False

    workers = [p for p in psutil.Process().children(recursive=True) if is_worker(p)]
    for worker in workers:
        with contextlib.suppress(psutil.Error):
            worker.kill()
    psutil.wait_procs(workers, timeout=1.0)


def _dashboard_link(client) -> str | None:
    """The dashboard's address, or None when the scheduler serves none."""
    try:
        return client.dashboard_link
    except (KeyError, TypeError):  # no "dashboard" among the scheduler's services
        return None


COLUMNS = ("command", "seed", "completed", "estop", "hole_rms_mm", "min_support_margin_mm",
           "max_tilt_deg", "wall_clock_s", "ended", "error", "exit_code", "run_dir")


def parameter_names(rows: Sequence[Row]) -> list[str]:
    """The swept parameters' names, in the order they first appear."""
    return list(dict.fromkeys(name for row in rows for name in row.parameters))


def write_table(rows: Sequence[Row], path: str | Path) -> Path:
    """The sweep table as CSV: command, seed, one column per parameter, then the outcome;
    written beside ``path`` and renamed over it (whole or not at all)."""
    names = parameter_names(rows)
    header = ["command", "seed", *names, *COLUMNS[2:]]
    try:
        with replacing(path) as temporary, \
                open(temporary, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(header)
            for row in rows:
                values = asdict(row)
                writer.writerow([row.command, row.seed,
                                 *(row.parameters.get(n, "") for n in names),
                                 *(_cell(values[c]) for c in COLUMNS[2:])])
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}",
                         hint="free disk space or choose a writable path") from None
    return Path(path)


def _cell(value) -> object:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return value


METRIC_NOTES = {
    "hole_rms_mm": ("hole RMS error (mm)", "the hole's distance from the commanded path in the "
                                            "wall plane, RMS; lower is better"),
    "max_tilt_deg": ("largest torso tilt (deg)", "the torso's largest tilt from upright; lower "
                                                 "is steadier"),
}


def plot_sweep(rows: Sequence[Row], path: str | Path) -> Path:
    """Outcome against the parameters (:func:`sweep_figure`) as a PNG."""
    from hubo_cli.plots import save_figure

    fig = sweep_figure(rows)
    return save_figure(fig, path, dpi=110)


def sweep_figure(rows: Sequence[Row]):
    """Outcome against the parameters: one panel per swept parameter (or the seed), the hole's
    RMS error (tasks that cut) or the largest torso tilt, completed runs as dots and the others
    as red crosses (those without a value on the panel's floor, with their e-stop's sources in
    the legend); a note says what the value means. The figure is left open."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in parameter_names(rows)
             if len({str(r.parameters.get(n)) for r in rows}) > 1] or ["seed"]
    holes = any(r.hole_rms_mm is not None for r in rows)
    metric = "hole_rms_mm" if holes else "max_tilt_deg"
    label, note = METRIC_NOTES[metric]
    stops = sorted({r.estop for r in rows if not r.completed and r.estop})
    failed = "not completed" + (f" (e-stop: {', '.join(stops)})" if stops else "")
    fig, axes = plt.subplots(1, len(names), figsize=(max(7.5, 4.5 * len(names)), 5.0),
                             squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        for ok, style in ((True, dict(marker="o", color="tab:green", label="completed")),
                          (False, dict(marker="x", color="tab:red", label=failed))):
            points = [(r.seed if name == "seed" else r.parameters.get(name),
                       getattr(r, metric)) for r in rows if r.completed == ok]
            known = [(x, y) for x, y in points if y is not None]
            unknown = [x for x, y in points if y is None]
            xs_all = [x for x, _ in points]
            as_x = (lambda xs: xs) if _numeric(xs_all) else (lambda xs: [str(x) for x in xs])
            if known:
                xs, ys = zip(*known, strict=True)
                ax.scatter(as_x(xs), ys, linestyle="none", **style)
            if unknown:  # no value (refused, or stopped before any): on the panel's floor
                ax.scatter(as_x(unknown), [0.0] * len(unknown), marker=style["marker"],
                           color=style["color"], transform=ax.get_xaxis_transform(),
                           clip_on=False, label=f"{style['label']}, no value (on the floor)")
        ax.set_xlabel(name if name == "seed" else f"{name} (--set)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=1, fontsize=8, frameon=False)
    fig.suptitle(f"hubo sweep {rows[0].command}: {len(rows)} runs, "
                 f"{sum(r.completed for r in rows)} completed; one mark per run\n"
                 + textwrap.fill(f"{label}: {note}", 90), fontsize=10)
    fig.tight_layout(rect=(0, 0.04 + 0.035 * len(labels), 1, 1))
    return fig


def _numeric(values) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
