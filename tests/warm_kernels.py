"""Fill numba's cache before the suite's workers start (``tests/conftest.py``).

The project's compiled kernels (``@njit(cache=True)``) compile on their first call and are
cached on disk. In a fresh checkout every kernel compiles once per CPU path, and pytest-xdist's
workers start on tests that need the same kernels at the same moment, so each compiles them
again. Two short workloads, run at once in two processes before the workers start, compile the
arms' kernels (teleoperation and a task's plan) and the legs' (standing, stepping and walking
on the simulator, the estimators) once; the workers then load them. With a warm cache a
workload only runs (a few seconds).

    python tests/warm_kernels.py arms|legs [arms|legs]

Given both, one process runs them one after the other: the legs' kernels are nearly all among
the arms' (a cold cache: 35 s of CPU for the legs alone, 8 s after the arms), which
``make warm`` uses to fill both CPU paths' caches at once, one process each.
"""

import sys


def arms() -> None:
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.model import load_model
    from hubo_cli.tasks.runner import check_task
    from hubo_cli.tasks.spec import load_task
    from hubo_cli.teleop.stream_runs import replay_generated

    replay_generated(1, StreamSettings(duration_s=1.0))
    replay_generated(1, StreamSettings(duration_s=1.0), mode="drill")
    check_task(load_task("cut-rectangle"), load_model())


def legs() -> None:
    import tempfile

    from hubo_cli.experiments.standing import stand
    from hubo_cli.experiments.walk import walk
    from hubo_cli.model import load_model

    with tempfile.TemporaryDirectory(prefix="hubo-warm-") as tmp:
        stand(load_model(), 0.5, out=f"{tmp}/stand")
        walk(load_model(), (0.05, 0.0, 0.0), out=f"{tmp}/walk", corrections=0)


if __name__ == "__main__":
    for part in sys.argv[1:]:
        {"arms": arms, "legs": legs}[part]()
