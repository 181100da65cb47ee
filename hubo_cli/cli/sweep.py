"""``hubo sweep``: many perturbed simulations of one command, on a Dask cluster."""

from __future__ import annotations

import click

from hubo_cli.cli.options import balance_option
from hubo_cli.cli.output import console, err_console, interactive, print_json


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
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="Sweep folder (default runs/<time>-sweep-<command>).")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON.")
@balance_option
def sweep(command: str, seeds: str, sets: tuple[str, ...], workers: int | None,
          scheduler: str | None, out: str | None, as_json: bool, balance: str) -> None:
    """Run TASK_OR_COMMAND (a task, or sim) once per seed and combination of --set values,
    each on its own perturbed robot, and tabulate the outcomes.

    Writes sweep.csv, sweep.png and one run folder per simulation. Ctrl-C cancels the
    simulations still running and keeps the finished rows. Exit code 0 when every run
    completed, 1 otherwise, 130 when interrupted.

    Examples: hubo sweep cut-slot --seeds 1-20
              hubo sweep cut-rectangle --seeds 1-5 --set speed_mm_s=10,20
              hubo sweep sim --seeds 1-50 --set push=0,30 --scheduler tcp://host:8786
    """
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from hubo_cli.runs import make_run_dir
    from hubo_cli.sweep import check_jobs, make_jobs, parse_seeds, parse_sets, run_sweep

    jobs = make_jobs(command, parse_seeds(seeds), parse_sets(sets), balance)
    check_jobs(jobs)
    out_dir = make_run_dir(f"sweep-{command.replace('/', '_')}", out)
    progress = Progress("[progress.description]{task.description}", BarColumn(),
                        MofNCompleteColumn(), TimeElapsedColumn(), console=err_console,
                        disable=not interactive() or as_json, transient=True)
    with progress:
        bar = progress.add_task(f"sweep {command}", total=len(jobs))
        result = run_sweep(jobs, out_dir, workers=workers, scheduler=scheduler,
                           on_row=lambda row, done, total: progress.update(bar, completed=done))
    if as_json:
        print_json({"out": str(out_dir), "where": result.where, "jobs": result.jobs,
                    "wall_clock_s": result.wall_clock_s, "interrupted": result.interrupted,
                    "rows": [row.outcome() | {"wall_clock_s": row.wall_clock_s,
                                              "run_dir": row.run_dir} for row in result.rows]})
    else:
        _print_table(result, command)
    ctx = click.get_current_context()
    if result.interrupted:
        ctx.exit(130)
    if not all(row.completed for row in result.rows):
        ctx.exit(1)


def _print_table(result, command: str) -> None:
    from rich.table import Table

    from hubo_cli.sweep import parameter_names

    names = parameter_names(result.rows)
    table = Table(title=f"hubo sweep {command}", title_justify="left")
    for column in ("seed", *names, "completed", "e-stop", "hole RMS mm", "min support mm",
                   "max tilt deg", "wall s"):
        table.add_column(column, justify="right")

    def number(value, digits: int = 1) -> str:
        return "" if value is None else f"{value:.{digits}f}"

    for row in result.rows:
        table.add_row(str(row.seed), *(str(row.parameters.get(n, "")) for n in names),
                      "yes" if row.completed else "[red]no[/]",
                      row.estop or ("refused" if row.ended == "refused" else ""),
                      number(row.hole_rms_mm), number(row.min_support_margin_mm),
                      number(row.max_tilt_deg, 2), number(row.wall_clock_s))
    console.print(table)
    done = sum(row.completed for row in result.rows)
    state = " (interrupted: the finished rows are kept)" if result.interrupted else ""
    console.print(f"{done} of {len(result.rows)} runs completed ({result.jobs} planned) on "
                  f"{result.where} in {result.wall_clock_s:.1f} s{state}")
    console.print(f"table and plot in {result.out_dir} (sweep.csv, sweep.png)", soft_wrap=True)
