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

import csv
import itertools
import json
import math
import os
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from hubo_cli.errors import HuboError, InputError

SIM_COMMAND = "sim"
SIM_PARAMETERS = {"duration": 5.0, "push": 0.0}
TABLE_NAME = "sweep.csv"
PLOT_NAME = "sweep.png"


@dataclass(frozen=True)
class Job:
    """One simulation of a sweep.

    Attributes:
        command: ``sim`` or a task name or file.
        seed: the perturbation seed (0: the nominal robot).
        parameters: (name, value) pairs, the task's ``--set`` (or ``sim``'s duration/push).
        balance: the balancer, ``default``, ``paper`` or ``off`` (``--balance``).
    """

    command: str
    seed: int
    parameters: tuple[tuple[str, object], ...] = ()
    balance: str = "default"

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
        completed: the task completed (``sim``: the robot did not fall); False when refused.
        estop: the sources of the first emergency stop (``+``-joined), "" when none.
        hole_rms_mm: the hole's RMS error in the wall plane (tasks that cut), else None.
        min_support_margin_mm: the smallest distance of the capture point inside the support
            polygon of the soles on the ground over the run (negative: it left the polygon;
            the e-stop fires below the monitor's 30 mm), None without the monitor.
        max_tilt_deg: the largest true torso tilt from upright (deg).
        wall_clock_s: how long the job took where it ran (s).
        ended: how the control loop ended (or ``refused``, ``error``).
        error: the error message, "" when none.
        run_dir: the job's run folder.
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

    def outcome(self) -> dict:
        """Everything but the wall-clock and the folder: equal for equal jobs anywhere."""
        row = asdict(self)
        del row["wall_clock_s"], row["run_dir"]
        return row


def parse_seeds(text: str) -> list[int]:
    """``A-B`` (inclusive), ``A`` or ``A,B,C`` -> seeds.

    Raises:
        InputError: not that form, negative, or B < A.
    """
    seeds: list[int] = []
    for part in text.split(","):
        match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", part)
        if not match:
            raise InputError(f"--seeds {text!r} is not A-B, A or A,B,C (integers >= 0)",
                             hint="e.g. --seeds 1-20")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise InputError(f"--seeds {part.strip()!r}: the range ends before it starts",
                             hint="e.g. --seeds 1-20")
        seeds += range(first, last + 1)
    return list(dict.fromkeys(seeds))


def parse_sets(sets: Sequence[str]) -> dict[str, list[object]]:
    """``NAME=V1,V2,...`` (each ``--set``) -> name -> values (numbers, true/false or text).

    Raises:
        InputError: not NAME=VALUES.
    """
    from hubo_cli.tasks.spec import parse_override

    values: dict[str, list[object]] = {}
    for text in sets:
        name, sep, listed = text.partition("=")
        if not sep or not name.strip() or not listed.strip():
            raise InputError(f"--set {text!r} is not NAME=V1,V2,...",
                             hint="e.g. --set speed_mm_s=10,20,40")
        values[name.strip()] = [parse_override(f"{name}={v}")[1] for v in listed.split(",")]
    return values


def make_jobs(command: str, seeds: Sequence[int], sets: dict[str, list[object]],
              balance: str = "default") -> list[Job]:
    """Every combination of seeds and parameter values, seeds outermost, with the balancer
    ``balance``."""
    names = list(sets)
    return [Job(command, seed, tuple(zip(names, combo, strict=True)), balance)
            for seed in seeds for combo in itertools.product(*(sets[n] for n in names))]


def check_jobs(jobs: Sequence[Job]) -> None:
    """Refuse a sweep whose command or parameters are unknown before anything runs.

    Raises:
        HuboError: an unknown task, a bad task file or parameter (ConfigError), an unknown
            ``sim`` parameter (InputError).
    """
    from hubo_cli.tasks.spec import load_task

    for job in {(j.command, tuple(n for n, _ in j.parameters)): j for j in jobs}.values():
        if job.command == SIM_COMMAND:
            unknown = [n for n, _ in job.parameters if n not in SIM_PARAMETERS]
            if unknown:
                raise InputError(f"sim has no parameter {', '.join(unknown)}",
                                 hint=f"use {', '.join(SIM_PARAMETERS)}")
        else:
            load_task(job.command, dict(job.parameters))


def run_job(job: Job, out_dir: str | Path) -> Row:
    """Run one simulation (in whatever process calls it) into ``out_dir/<job name>``."""
    t0 = time.perf_counter()
    run_dir = Path(out_dir) / job.name
    try:
        row = _run_sim(job, run_dir) if job.command == SIM_COMMAND else _run_task(job, run_dir)
    except HuboError as exc:
        row = Row(job.command, job.seed, dict(job.parameters), completed=False, ended="error",
                  error=str(exc))
    row.completed = row.completed and row.ended != "interrupted"  # Ctrl-C or SIGTERM
    row.wall_clock_s = time.perf_counter() - t0
    row.run_dir = str(run_dir)
    return row


def _first_stop(summary: dict) -> str:
    stops = [e for e in summary.get("estop_events", []) if e["kind"] == "stop"]
    return "+".join(stops[0]["sources"]) if stops else ""


def _run_sim(job: Job, run_dir: Path) -> Row:
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
               max_tilt_deg=summary["max_torso_tilt_deg"], ended=summary["ended"])


def _run_task(job: Job, run_dir: Path) -> Row:
    from hubo_cli.tasks.runner import check_task, run_experiment, run_task
    from hubo_cli.tasks.spec import load_task

    spec = load_task(job.command, dict(job.parameters))
    if spec.experiment:
        done = run_experiment(spec, out=run_dir, perturb_seed=job.seed, balance=job.balance)
    else:
        plan = check_task(spec)
        if not plan.preflight.ok:
            return Row(job.command, job.seed, dict(job.parameters), completed=False,
                       ended="refused", error=plan.preflight.worst_per_step()[0].message())
        done = run_task(plan, out=run_dir, perturb_seed=job.seed, balance=job.balance)
    summary = done.summary
    completed = summary.get("completed")
    if completed is None:  # an experiment: it completed unless the robot fell or tipped
        completed = not (summary.get("fell") or summary.get("tipped"))
    return Row(job.command, job.seed, dict(job.parameters), completed=bool(completed),
               estop=_first_stop(summary), hole_rms_mm=summary.get("hole_rms_error_mm"),
               min_support_margin_mm=summary.get("min_support_margin_mm"),
               max_tilt_deg=summary["max_torso_tilt_deg"], ended=summary["ended"])


def _read_summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


@dataclass
class SweepResult:
    """A finished (or interrupted) sweep: its rows in job order, where it ran, how long."""

    rows: list[Row]
    jobs: int
    where: str
    wall_clock_s: float
    interrupted: bool = False
    out_dir: Path | None = None


def run_sweep(jobs: Sequence[Job], out_dir: str | Path, *, workers: int | None = None,
              scheduler: str | None = None,
              on_row: Callable[[Row, int, int], None] | None = None) -> SweepResult:
    """Run every job and write the table and the plot into ``out_dir``.

    Args:
        jobs: from :func:`make_jobs`.
        out_dir: the sweep folder (``sweep.csv``, ``sweep.png`` and one run folder per job).
        workers: 0 = one after the other in this process; None = a LocalCluster with one
            worker process per core; n = a LocalCluster of n worker processes.
        scheduler: the address of an existing Dask scheduler (``workers`` is then ignored).
        on_row: called with each finished row, the number done and the total (progress).

    A KeyboardInterrupt cancels the jobs still running; the finished rows are kept and
    written (``interrupted`` is then True).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    n_workers = workers or os.cpu_count() or 1
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

    try:
        if scheduler is None and workers == 0:
            for index, job in enumerate(jobs):
                row = run_job(job, out_dir)
                finished(index, row)
                if row.ended == "interrupted":  # the run took the Ctrl-C (SIGTERM): stop here
                    raise KeyboardInterrupt
        else:
            _run_on_dask(jobs, out_dir, n_workers, scheduler, finished)
    except KeyboardInterrupt:
        interrupted = True
    rows = [done[i] for i in sorted(done)]
    result = SweepResult(rows, len(jobs), where, time.perf_counter() - t0, interrupted, out_dir)
    write_table(rows, out_dir / TABLE_NAME)
    if rows:
        plot_sweep(rows, out_dir / PLOT_NAME)
    return result


def _run_on_dask(jobs, out_dir: Path, n_workers: int, scheduler: str | None,
                 finished: Callable[[int, Row], None]) -> None:
    from dask import config
    from distributed import Client, LocalCluster, as_completed

    with config.set({"distributed.worker.daemon": False,
                     "distributed.admin.system-monitor.gil.enabled": False}):
        if scheduler is not None:
            cluster = None
            client = Client(scheduler, timeout="10s")
        else:
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None,
                                   silence_logs=50)
            client = Client(cluster)
        futures = {}
        try:
            for index, job in enumerate(jobs):
                future = client.submit(run_job, job, str(out_dir.resolve()), pure=False,
                                       key=f"hubo-sweep-{index}-{job.name}")
                futures[future] = index
            for future in as_completed(futures):
                index = futures[future]
                if future.status == "error":
                    exc = future.exception()
                    job = jobs[index]
                    row = Row(job.command, job.seed, dict(job.parameters), completed=False,
                              ended="error", error=f"{type(exc).__name__}: {exc}")
                else:
                    row = future.result()
                finished(index, row)
        finally:
            client.cancel(list(futures))
            client.close()
            if cluster is not None:
                cluster.close()


COLUMNS = ("command", "seed", "completed", "estop", "hole_rms_mm", "min_support_margin_mm",
           "max_tilt_deg", "wall_clock_s", "ended", "error", "run_dir")


def parameter_names(rows: Sequence[Row]) -> list[str]:
    """The swept parameters' names, in the order they first appear."""
    return list(dict.fromkeys(name for row in rows for name in row.parameters))


def write_table(rows: Sequence[Row], path: str | Path) -> Path:
    """The sweep table as CSV: command, seed, one column per parameter, then the outcome."""
    names = parameter_names(rows)
    header = ["command", "seed", *names, *COLUMNS[2:]]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for row in rows:
            values = asdict(row)
            writer.writerow([row.command, row.seed, *(row.parameters.get(n, "") for n in names),
                             *(_cell(values[c]) for c in COLUMNS[2:])])
    return Path(path)


def _cell(value) -> object:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return value


def plot_sweep(rows: Sequence[Row], path: str | Path) -> Path:
    """Outcome against the parameters: one panel per swept parameter (or the seed), the hole's
    RMS error (tasks that cut) or the largest torso tilt, completed runs as dots and the others
    as red crosses."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in parameter_names(rows)
             if len({str(r.parameters.get(n)) for r in rows}) > 1] or ["seed"]
    holes = any(r.hole_rms_mm is not None for r in rows)
    metric, label = (("hole_rms_mm", "hole RMS error (mm)") if holes
                     else ("max_tilt_deg", "largest torso tilt (deg)"))
    fig, axes = plt.subplots(1, len(names), figsize=(4.5 * len(names), 3.6), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        for ok, style in ((True, dict(marker="o", color="tab:green", label="completed")),
                          (False, dict(marker="x", color="tab:red", label="not completed"))):
            points = [(r.seed if name == "seed" else r.parameters.get(name),
                       getattr(r, metric)) for r in rows if r.completed == ok]
            points = [(x, np.nan if y is None else y) for x, y in points]
            if points:
                xs, ys = zip(*points, strict=True)
                ax.scatter([str(x) for x in xs] if not _numeric(xs) else xs, ys,
                           linestyle="none", **style)
        ax.set_xlabel(name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0][0].legend(loc="best", fontsize=8)
    fig.suptitle(f"hubo sweep {rows[0].command}: {len(rows)} runs, "
                 f"{sum(r.completed for r in rows)} completed")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _numeric(values) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
