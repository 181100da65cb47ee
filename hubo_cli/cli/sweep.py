"""``hubo sweep``: many perturbed simulations of one command, on a Dask cluster."""

from __future__ import annotations

import click

from hubo_cli.cli.options import balance_option
from hubo_cli.cli.output import console, err_console, print_json
from hubo_cli.errors import InputError
from hubo_cli.sweep import CONFIRM_JOBS


@click.command("sweep")
@click.argument("command", metavar="TASK_OR_COMMAND")
@click.option("--seeds", default="1-10", show_default=True, metavar="A-B",
              help="Perturbation seeds (A-B inclusive, or A,B,C; 0 = the nominal robot).")
@click.option("--set", "sets", multiple=True, metavar="NAME=V1,V2,...",
              help="A parameter and the values to sweep (a task's, or sim's duration/push).")
@click.option("--workers", type=click.IntRange(min=0), default=None,
              help="Worker processes of the local Dask cluster (default: one per core; "
                   "0 = one job after the other in this process).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on an existing Dask cluster, e.g. tcp://host:8786.")
@click.option("--dashboard", is_flag=True,
              help="Serve Dask's dashboard (needs the bokeh extra) and print its link; "
                   "with --scheduler, print the scheduler's.")
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="Sweep folder (default runs/<time>-sweep-<command>).")
@click.option("--yes", is_flag=True,
              help=f"Run a sweep of more than {CONFIRM_JOBS:,} simulations without asking.")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON.")
@balance_option
def sweep(command: str, seeds: str, sets: tuple[str, ...], workers: int | None,
          scheduler: str | None, dashboard: bool, out: str | None, yes: bool, as_json: bool,
          balance: str) -> None:
    """Run TASK_OR_COMMAND (a task, or sim) once per seed and combination of --set values,
    each on its own perturbed robot, and tabulate the outcomes.

    Writes sweep.csv, sweep.png and one run folder per simulation. Every value, the scheduler's
    address and the sweep's size (more than 10,000 runs: --yes) are checked before anything
    runs. Ctrl-C cancels the simulations still running and keeps the finished rows, as does a
    lost scheduler. The workers must run this client's versions of Dask, hubo-cli (its source
    files too) and its numerics (checked before any run) and see --out at the same path. Each
    row has the exit code its run alone gives. Exit code 0 when every run completed, the rows'
    code when they all have the same (4: every run refused in pre-flight), 1 otherwise, 2 for
    a bad value or mismatched worker versions, 3 when the scheduler cannot be reached or is
    lost, 130 when interrupted.

    Examples: hubo sweep cut-slot --seeds 1-20
              hubo sweep cut-rectangle --seeds 1-5 --set speed_mm_s=10,20
              hubo sweep sim --seeds 1-50 --set push=0,30 --scheduler tcp://host:8786
    """
    import sys

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from hubo_cli.runs import make_run_dir
    from hubo_cli.sweep import (
        check_dashboard,
        check_jobs,
        check_scheduler,
        check_size,
        check_workers,
        job_count,
        make_jobs,
        parse_seeds,
        parse_sets,
        run_sweep,
        sweep_exit_code,
    )

    seed_list, values = parse_seeds(seeds), parse_sets(sets)
    n_jobs = job_count(len(seed_list), values)
    if not yes and n_jobs > CONFIRM_JOBS and sys.stdin.isatty() and err_console.is_terminal:
        yes = click.confirm(f"run {n_jobs:,} simulations?", err=True)
    check_size(n_jobs, yes)
    check_workers(workers)
    if dashboard and scheduler is None:
        if workers == 0:
            raise InputError("--dashboard needs a Dask cluster; --workers 0 runs in this "
                             "process", hint="leave out --workers 0")
        check_dashboard()
    jobs = make_jobs(command, seed_list, values, balance)
    check_jobs(jobs)
    if scheduler is not None:
        scheduler = check_scheduler(scheduler)
    out_dir = make_run_dir(f"sweep-{command.replace('/', '_')}", out)
    show = err_console.is_terminal and not err_console.is_dumb_terminal and not as_json
    progress = Progress("[progress.description]{task.description}", BarColumn(),
                        MofNCompleteColumn(), TimeElapsedColumn(), console=err_console,
                        disable=not show, transient=True)

    def on_row(row, done: int, total: int) -> None:
        failed[0] += not row.completed
        progress.update(bar, completed=done,
                        description=f"sweep {command} ({failed[0]} not completed)")

    def on_dashboard(link: str | None) -> None:
        err_console.print(f"Dask dashboard: {link}" if link else
                          f"the Dask scheduler at {scheduler} reports no dashboard",
                          highlight=False, soft_wrap=True)

    failed = [0]
    with progress:
        bar = progress.add_task(f"sweep {command}", total=len(jobs))
        result = run_sweep(jobs, out_dir, workers=workers, scheduler=scheduler, on_row=on_row,
                           on_dashboard=on_dashboard if dashboard else None)
    if as_json:
        print_json({"out": str(out_dir), "where": result.where, "jobs": result.jobs,
                    "wall_clock_s": result.wall_clock_s, "interrupted": result.interrupted,
                    "cut_short": [str(p) for p in result.cut_short],
                    "rows": [row.outcome() | {"wall_clock_s": row.wall_clock_s,
                                              "run_dir": row.run_dir} for row in result.rows]})
    else:
        _print_table(result, command)
    if result.cut_short:
        err_console.print(f"cut short by the interrupt, without summary or row (their logs "
                          f"finished): {', '.join(p.name for p in result.cut_short)}",
                          highlight=False, soft_wrap=True)
    ctx = click.get_current_context()
    if result.interrupted:
        ctx.exit(130)
    ctx.exit(sweep_exit_code(result.rows))


def _print_table(result, command: str) -> None:
    """The rows as a table, or as one plain line each on a terminal too narrow for it; then
    each error once, with its exit code and how many runs it ended."""
    from collections import Counter

    from rich.table import Table
    from rich.text import Text

    from hubo_cli.cli.live_view import MIN_COLUMNS
    from hubo_cli.sweep import parameter_names

    names = parameter_names(result.rows)
    columns = ("seed", *names, "completed", "e-stop", "hole RMS mm", "min support mm",
               "max tilt deg", "wall s")

    def number(value, digits: int = 1) -> str:
        return "" if value is None else f"{value:.{digits}f}"

    rows = [(str(row.seed), *(str(row.parameters.get(n, "")) for n in names),
             "yes" if row.completed else "no",
             row.estop or (row.ended if row.ended in ("refused", "error") else ""),
             number(row.hole_rms_mm), number(row.min_support_margin_mm),
             number(row.max_tilt_deg, 2), number(row.wall_clock_s)) for row in result.rows]
    if console.width < MIN_COLUMNS:
        for cells in rows:
            console.print(", ".join(f"{c} {v}" for c, v in zip(columns, cells, strict=True)
                                    if v), markup=False)
    else:
        table = Table(title=f"hubo sweep {command}", title_justify="left")
        for column in columns:
            table.add_column(column, justify="right")
        for cells in rows:
            table.add_row(*map(Text, cells),  # Text: a value's brackets are not markup
                          style=None if cells[len(names) + 1] == "yes" else "red")
        console.print(table)
    for (ended, code, error), count in Counter(
            (row.ended, row.exit_code, row.error) for row in result.rows if row.error).items():
        console.print(f"{ended} (exit {code}), {count} run{'s' * (count > 1)}: {error}",
                      markup=False, highlight=False, soft_wrap=True)
    done = sum(row.completed for row in result.rows)
    state = " (interrupted: the finished rows are kept)" if result.interrupted else ""
    console.print(f"{done} of {len(result.rows)} runs completed ({result.jobs} planned) on "
                  f"{result.where} in {result.wall_clock_s:.1f} s{state}")
    console.print(f"table and plot in {result.out_dir} (sweep.csv, sweep.png)", soft_wrap=True)
