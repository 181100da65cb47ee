"""The pipeline's compiled per-period passes give what the numpy code they replaced gives: the
trajectory generator's target (NaN hold, clamp, flags), the stoppers' NaN hold, the loop's
finiteness check and the limiter's clamp bits."""

from __future__ import annotations

import numpy as np

from hubo_cli.control.limiter import (
    CLAMP_POSITION,
    CLAMP_RATE,
    CLAMP_TRACKING,
    SoftErrorLimiter,
)
from hubo_cli.control.module import Cycle
from hubo_cli.control.otg import TargetInput
from hubo_cli.dataflow import Store
from hubo_cli.model import load_model
from hubo_cli.motion.limits import JointLimits, all_finite, hold_nan
from hubo_cli.state import RobotState


def _reference_take(q_rad, held_rad, limits):
    """The target's update as numpy wrote it: (new target or None, flags)."""
    fresh = np.isfinite(q_rad)
    every = bool(fresh.all())
    if not (every or fresh.any()):
        return None, set()
    wanted = np.asarray(q_rad, dtype=float) if every else np.where(fresh, q_rad, held_rad)
    clipped = limits.clip(wanted)
    flags = set()
    if (np.abs(clipped - wanted) > 1e-9).any():
        flags.add("joint-limit")
    if not every:
        flags.add("holding")
    return clipped, flags


def _inputs(limits, rng, count=300):
    """Targets inside, at and beyond the limits, with some, all or no NaN entries."""
    n = limits.size
    for k in range(count):
        q = rng.uniform(limits.lower_rad - 0.3, limits.upper_rad + 0.3)
        if k % 5 == 1:
            q[rng.random(n) < 0.3] = np.nan
        elif k % 5 == 2:
            q[:] = np.nan
        elif k % 5 == 3:
            q = np.clip(q, limits.lower_rad, limits.upper_rad)
            q = np.where(rng.random(n) < 0.3, limits.lower_rad, q)
            q = np.where(rng.random(n) < 0.3, limits.upper_rad + 5e-10, q)  # rounding at a limit
        elif k % 5 == 4:
            q = rng.uniform(limits.lower_rad, limits.upper_rad)
        yield q


def test_the_generators_compiled_target_matches_numpy():
    model = load_model()
    limits = JointLimits.from_model(model)
    rng = np.random.default_rng(11)
    target = TargetInput(limits, stale_timeout_s=0.02)
    target.reset(rng.uniform(limits.lower_rad, limits.upper_rad))
    seen = set()
    for k, q in enumerate(_inputs(limits, rng)):
        held = target.target.copy()
        expected, expected_flags = _reference_take(q, held, limits)
        cycle = Cycle(k * 0.005, 0.005)
        target.take(q, cycle)
        if expected is None:
            assert np.array_equal(target.target, held)
        else:
            assert np.array_equal(target.target, expected)  # bit for bit: the same comparisons
            assert cycle.flags == expected_flags
            seen |= expected_flags
    assert seen == {"joint-limit", "holding"}  # both flags were exercised


def test_the_generators_compiled_target_still_goes_stale():
    limits = JointLimits.from_model(load_model())
    target = TargetInput(limits, stale_timeout_s=0.02)
    target.reset(np.zeros(limits.size))
    nan = np.full(limits.size, np.nan)
    stale = []
    for k in range(10):
        cycle = Cycle(k * 0.005, 0.005)
        stale.append(target.take(nan, cycle))
    assert stale[:5] == [False] * 5 and all(stale[5:])
    assert "stale-input" in cycle.estop_requests


def test_nan_hold_and_finiteness_match_numpy():
    rng = np.random.default_rng(5)
    for k in range(200):
        q = rng.normal(size=24)
        bad = rng.random(24) < (0.0 if k % 3 == 0 else 0.2)
        q[bad] = rng.choice([np.nan, np.inf, -np.inf], size=int(bad.sum()))
        held = rng.normal(size=24)
        out = np.empty(24)
        hold_nan(q, held, out)
        assert np.array_equal(out, np.where(np.isfinite(q), q, held))
        assert all_finite(q) == bool(np.isfinite(q).all())


def test_the_limiters_clamp_bits_are_its_mask():
    """The limiter's flags come from the or of its per-joint clamp bits, which the compiled
    step returns: they equal the flags its mask gives, period by period."""
    model = load_model()
    dt = model.control_period_s
    limiter = SoftErrorLimiter(model, dt)
    limiter.checks.measured = lambda *args: None  # random measurements no robot gives: the
    # following checks (tests/test_following.py) would end it as a jump at once
    n = len(model.joint_names)
    rng = np.random.default_rng(2)
    q0 = np.clip(np.zeros(n), limiter.limits.lower_rad, limiter.limits.upper_rad)
    limiter.reset(q0, RobotState(0.0, q0, np.zeros(n)), Store())
    names = {CLAMP_POSITION: "joint-limit", CLAMP_RATE: "slowing",
             CLAMP_TRACKING: "tracking-error"}
    seen = set()
    for k in range(400):
        want = q0 + (0.0 if k % 4 == 0 else rng.normal(scale=0.05 * (k % 7), size=n))
        if k % 9 == 0:
            want[rng.random(n) < 0.2] = np.nan
        measured = q0 + rng.normal(scale=0.1, size=n)
        cycle = Cycle(k * dt, dt)
        limiter.update(want, RobotState(k * dt, measured, np.zeros(n)), cycle)
        mask = limiter._mask
        expected = {name for bit, name in names.items() if (mask & bit).any()}
        assert cycle.flags == expected
        assert cycle.info["limiter_clamped_count"] == float(np.count_nonzero(mask))
        seen |= expected
    assert seen == set(names.values())


COMPILE_CHECK = """
import json
import numpy as np
from hubo_cli.control import limiter, otg
from hubo_cli.motion import limits
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.drivers.registry import make_driver
from hubo_cli.model import load_model

kernels = (otg.take_target, limits.hold_nan, limits.all_finite, limiter.limit_step)
model = load_model()
driver = make_driver("ideal", model)
driver.start()
q0 = driver.read().q_rad.copy()
loop = ControlLoop(driver, build_pipeline(model), lambda t, s: (q0 + 0.05 * np.sin(t), {}))
built = [len(k.signatures) for k in kernels]
loop.run(0.2)
print(json.dumps({"built": built, "after": [len(k.signatures) for k in kernels]}))
"""


def test_the_compiled_passes_compile_when_the_pipeline_is_built():
    """Building the modules and the loop compiles every pass above with a run's argument
    types, so no control period compiles one (seconds on a fresh install)."""
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", COMPILE_CHECK], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert all(n == 1 for n in counts["built"]), counts
    assert counts["after"] == counts["built"], counts
