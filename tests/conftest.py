"""Shared fixtures, the order of the tests and their grouping on the xdist workers."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hubo_cli.model import load_model
from hubo_cli.walking.params import walking_params

WARM_DEADLINE_S = 300  # a fresh checkout's compile takes 40-150 s (under load)

# A shell starting the suite in the background (`make test &`, nohup) hands it SIGINT ignored,
# and every process it starts inherits that: the Ctrl-C tests would then test the shell's
# setting. Python's own handler, as in a terminal (exec gives the children the default).
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def model():
    return load_model()


@pytest.fixture(scope="module")
def walking_model():
    """The as-built model with the walking limit set. Module-scoped, as the walking test
    modules had it: the tests using it form their module's group (see below)."""
    return load_model(limits="walking")


@pytest.fixture(scope="module")
def params(walking_model):
    """The walking parameters (normal gait) of :func:`walking_model` (a module may name its
    own ``params``, as the toe-heel tests do)."""
    return walking_params(walking_model)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def _shared_module_fixture(item) -> bool:
    """Whether the test uses a module-scoped fixture (one expensive run its module shares)."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    return any(defs and defs[-1].scope == "module"
               for name in item.fixturenames
               if (defs := info.name2fixturedefs.get(name)))


def _group_on_one_worker(item, name: str) -> None:
    """Suffix the test's id with its group as pytest-xdist's ``--dist loadgroup`` does: the
    scheduler hands out a group as one unit, so a module-scoped fixture is built once, on one
    worker. pytest-xdist sets a ``_nodeid`` attribute, which pytest from 9.1 on no longer reads
    (its node id is structured): there the id is set here."""
    try:
        from _pytest.nodeid import NodeId
    except ImportError:  # pytest < 9.1: pytest-xdist's own hook applies the mark
        return
    if hasattr(item, "_id") and "@" not in item.nodeid:
        item._id = NodeId.parse(f"{item.nodeid}@{name}")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Long simulation tests (``@pytest.mark.slow``) first: pytest-xdist hands the tests out in
    this order, so the longest start at once and the short ones fill the workers' gaps at the
    end instead of one long test running alone. (With ``--dist loadgroup`` pytest-xdist 3.8
    first sorts its units by their number of tests, ``--loadscope-reorder`` being the default:
    the groups go out first, the most tests first, then the single tests in this order.)

    Tests that share a module-scoped fixture form one group (``xdist_group``, named after
    their module unless the module names one): a run they share happens once, not once per
    worker and again whenever another module's test ran in between."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
    _check_physical_files_name_the_mark(items)
    grouping = getattr(config.option, "loadgroup", False)  # set on pytest-xdist's workers
    for item in items:
        mark = item.get_closest_marker("xdist_group")
        if mark is None and _shared_module_fixture(item):
            group = pytest.mark.xdist_group(item.module.__name__)
            item.add_marker(group)
            mark = group.mark
        if grouping and mark is not None:
            _group_on_one_worker(item, str(mark.args[0] if mark.args
                                           else mark.kwargs.get("name", "default")))


def _check_physical_files_name_the_mark(items) -> None:
    """``make test-portable`` collects only the test files whose text names ``physical``
    (the Makefile's PHYSICAL_TESTS): a test marked so from elsewhere would silently leave the
    portable run. Refused here instead, in every run that collects it."""
    unnamed = {str(item.path) for item in items if item.get_closest_marker("physical")
               and "physical" not in item.path.read_text().lower()}
    if unnamed:
        raise pytest.UsageError(f"{', '.join(sorted(unnamed))}: tests marked physical in a "
                                "file that does not name the mark (make test-portable would "
                                "not collect them): mark them in the file itself")


def pytest_configure(config):
    """Before pytest-xdist starts two or more workers to run tests: fill numba's cache with
    ``tests/warm_kernels.py``'s two workloads, run at once (its docstring says why). In a fresh
    checkout this compiles each kernel once instead of once per worker; with a warm cache it
    costs the workloads' few seconds. A workload that fails costs only time (the workers then
    compile what they need, and the tests report any fault); it is said in one warning line.
    ``.ci/run`` fills both CPU paths' caches at once first (``make warm``) and says so with
    ``HUBO_KERNELS_WARM=1``: then the workloads are not run again."""
    option = config.option
    if (hasattr(config, "workerinput") or (getattr(option, "numprocesses", 0) or 0) < 2
            or option.help or option.collectonly or option.showfixtures
            or os.environ.get("HUBO_KERNELS_WARM") == "1"):
        return
    script = Path(__file__).with_name("warm_kernels.py")
    warming = {part: subprocess.Popen([sys.executable, str(script), part],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
               for part in ("arms", "legs")}
    deadline = time.monotonic() + WARM_DEADLINE_S
    try:
        for part, process in warming.items():
            try:
                _, err = process.communicate(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                config.issue_config_time_warning(pytest.PytestWarning(
                    f"warm_kernels.py {part}: not done in {WARM_DEADLINE_S} s"), stacklevel=2)
                continue
            if process.returncode:
                last = (err.decode(errors="replace").strip().splitlines() or ["?"])[-1]
                config.issue_config_time_warning(pytest.PytestWarning(
                    f"warm_kernels.py {part} failed: {last}"), stacklevel=2)
    finally:
        for process in warming.values():
            if process.poll() is None:
                process.kill()
                process.wait()
