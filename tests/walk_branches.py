"""Walks that are the same command until their first disturbance, walked once up to there.

``hubo walk --to 1 0 0`` pushed at 1.89 s and the same walk pushed at 8.16 s are one walk for
their first 1.89 s. :func:`branched_walks` walks each such group once: a trunk process runs
the walk (:func:`hubo_cli.experiments.walk.walk`, nothing disturbing it) and, in the period
a branch's first disturbance is due, forks; the child takes the branch's disturbances as its
pending ones and walks on from the trunk's whole in-process state (the simulator, the walk
target, the estimators, the pipeline's modules, the loop's store), while the trunk waits for
it and walks on to the next branch. Each child writes its own run folder and its
:class:`~hubo_cli.experiments.walk.WalkResult`; the trunk ends after the last branch.

A continued walk is the fresh walk's: every period before the branch ran the same code on the
same inputs (a disturbance waiting in the pending list is read by nothing until its time), and
the run folder is the fresh run's, the log's records before the branch copied from the
trunk's (docs/history/performance-latest-round.md, round 19: the logs and summaries compared
with fresh runs', both CPU paths).

The trunk runs in a fresh Python process (this file as a script), not in a fork of the
pytest worker: a process that has run numba's OpenMP kernels (every run's balance report does)
cannot run them again in a forked child. The trunk runs none before its last fork (a child
that needed one would end at once, and its branch would say so)."""

from __future__ import annotations

import dataclasses
import os
import pickle
import shutil
import subprocess
import sys
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path

NOT_DUE_S = 1e9  # the trunk's own pending disturbance: never due (a walk ends long before)


def branched_walks(goal: tuple[float, float, float],
                   branches: Mapping[str, Sequence], out: Path,
                   walk_kwargs: Mapping[str, object] | None = None) -> dict[str, object]:
    """``walk(load_model(), goal, out=out / name, disturbances=branches[name], **walk_kwargs)``
    for each branch, the walks sharing their common first seconds. Returns name -> its
    WalkResult, or the error it ended with (an exception to raise)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    spec = out / "branches.pickle"
    spec.write_bytes(pickle.dumps((goal, dict(branches), dict(walk_kwargs or {}), out)))
    done = subprocess.run([sys.executable, __file__, str(spec)], capture_output=True,
                          text=True)
    shutil.rmtree(out / "trunk", ignore_errors=True)  # (the trunk's scratch folder)
    results = {}
    for name in branches:
        path = out / f"{name}.result"
        if path.exists():
            results[name] = pickle.loads(path.read_bytes())
        else:
            results[name] = RuntimeError(
                f"branch {name} gave no result (trunk exit {done.returncode}): "
                f"{done.stderr[-3000:]}")
    return results


def _trunk(spec_path: Path) -> None:
    """The trunk process: walk, forking a child at each branch (see the module docstring)."""
    goal, branches, walk_kwargs, out = pickle.loads(spec_path.read_bytes())
    from hubo_cli.control import loop as loop_module
    from hubo_cli.control.log import PeriodLog
    from hubo_cli.experiments import walk as walking
    from hubo_cli.model import load_model

    logs: list[PeriodLog] = []

    class KeptLog(PeriodLog):
        """The loop's log, kept at hand so that a child can continue it in its own files."""

        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            logs.append(self)

    todo = sorted(branches, key=lambda name: min(d.at_s for d in branches[name]))
    trunk_dir = out / "trunk"
    branch: list[str] = []  # the branch this process walks (empty: the trunk)

    class Branching(walking.Disturbed):
        def __call__(self, t_s, state):
            while not branch and todo and t_s >= min(
                    d.at_s for d in branches[todo[0]]) - 1e-9:
                name = todo.pop(0)
                pid = os.fork()
                if pid == 0:
                    branch.append(name)
                    try:
                        _continue_in_own_folder(logs[0], trunk_dir)
                    except BaseException as err:  # noqa: BLE001 (the branch says it)
                        _save(out / f"{name}.result", RuntimeError(
                            "".join(traceback.format_exception(err))))
                        os._exit(1)
                    self.pending = sorted(branches[name], key=lambda d: d.at_s)
                    break
                _, status = os.waitpid(pid, 0)
                if status and not (out / f"{name}.result").exists():
                    _save(out / f"{name}.result", RuntimeError(
                        f"branch {name}: its process ended with status {status}"))
            if not branch and not todo:
                os._exit(0)  # the trunk's part is done (its folder is scratch)
            return super().__call__(t_s, state)

    _warm_the_end_of_a_run()
    loop_module.PeriodLog = KeptLog
    walking.Disturbed = Branching
    try:
        result = walking.walk(load_model(), goal, out=trunk_dir,
                              disturbances=[walking.Disturbance(NOT_DUE_S, stop=True)],
                              **walk_kwargs)
    except BaseException as err:  # noqa: BLE001 (said in the branch's result)
        result = RuntimeError("".join(traceback.format_exception(err)))
    if not branch:  # the trunk's walk ended before these branches' first disturbances
        for name in todo:
            _save(out / f"{name}.result", RuntimeError(
                f"branch {name}: the walk ended before its first disturbance: {result}"))
        os._exit(1)
    name = branch[0]
    os.rename(trunk_dir, out / name)
    if not isinstance(result, BaseException):
        result = dataclasses.replace(result, run_dir=out / name)
    os.rename(trunk_dir.with_name("trunk.held"), trunk_dir)  # back for the trunk
    _save(out / f"{name}.result", result)
    os._exit(0)


def _warm_the_end_of_a_run() -> None:
    """Import what a run imports once its loop ends (the log's Parquet copy, the snapshot,
    the footprint plot) and draw one small figure, here in the trunk: each child would
    otherwise do it again (about 1.5 s of CPU each)."""
    import io

    import matplotlib.pyplot as plt
    import pyarrow.ipc  # noqa: F401

    import hubo_cli.drivers.snapshot  # noqa: F401
    import hubo_cli.plots.walk  # noqa: F401
    import hubo_cli.viz.camera  # noqa: F401
    import hubo_cli.viz.legend  # noqa: F401

    figure, axes = plt.subplots()
    axes.plot([0.0, 1.0], [0.0, 1.0], label="x")
    axes.legend()
    axes.set_title("warm")
    figure.savefig(io.BytesIO(), format="png")
    plt.close(figure)


def _continue_in_own_folder(log, trunk_dir: Path) -> None:
    """In a child just forked: the trunk's run folder moves aside (``trunk.held``, its files
    still open in the trunk), a copy of it takes its place, and the loop's log writes on in
    that copy's files (the trunk's stay as they were at the fork, for its later branches)."""
    import fcntl
    import io
    import mmap

    handles = sorted(name for name, value in vars(log).items()
                     if isinstance(value, (io.IOBase, mmap.mmap)) or name.endswith("_fd"))
    if handles != ["_flags_fd", "_map", "_rows_file"]:  # (a change to PeriodLog: follow it)
        raise RuntimeError(f"the log holds {handles} open; this helper continues "
                           "_flags_fd, _map and _rows_file alone")
    held = trunk_dir.with_name("trunk.held")
    os.rename(trunk_dir, held)
    shutil.copytree(held, trunk_dir)
    log._map.close()
    log._rows_file.close()
    os.close(log._flags_fd)
    log._rows_file = open(log.rows_path, "r+b")  # noqa: SIM115 (kept open, as the log's)
    fcntl.flock(log._rows_file, fcntl.LOCK_EX)
    log._map = mmap.mmap(log._rows_file.fileno(), 0)
    log._flags_fd = os.open(log.flags_path, os.O_WRONLY)
    os.lseek(log._flags_fd, 0, os.SEEK_END)


def _save(path: Path, value) -> None:
    partial = path.with_suffix(".partial")
    partial.write_bytes(pickle.dumps(value))
    os.rename(partial, path)


if __name__ == "__main__":
    _trunk(Path(sys.argv[1]))
