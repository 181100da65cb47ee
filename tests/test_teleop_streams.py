"""A property test over generated operator streams (:mod:`hubo_cli.input.operator_stream`):
streams no one tuned the teleoperation on, replayed through ``hubo teleop`` on the ideal driver.

It asserts what holds today, with a margin over what was measured: no command beyond a joint
limit, none not finite, no jump (a joint step beyond its speed limit in one period), and the
largest excursion within 1.5x the worst measured over the bench's streams. It does not assert
the issue's accuracy targets (position RMS <= 10 mm, orientation RMS <= 3 deg over the time the
goal is reachable, excursion <= 15 mm): they are not met today (``make bench BENCH=teleop``
prints the distribution). Few short streams here; the bench replays more.
"""

import numpy as np
import pytest

from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.teleop.stream_runs import replay_generated

# the seeds are drawn, not picked (a new draw is a new test of the same properties)
SEEDS = np.random.default_rng(3434).integers(0, 2**31, 2).tolist()
# The largest excursion, worst over the bench's streams (make bench BENCH=teleop: 20 streams
# <= 0.25 m/s and 8 <= 0.6 m/s, 20 s each, seeds 3400-3419, ideal driver; the same figures on
# two runs): over the whole run (where the goal is out of reach it includes how far beyond
# reach the goal is) 416 / 287 mm (median 93-106 / 128-148 mm); over the reachable time 226 /
# 147 mm (median 70-80 / 110 mm). The bounds are 1.5x those.
EXCURSION_BOUND_MM = {0.25: 1.5 * 416, 0.6: 1.5 * 287}
REACHABLE_EXCURSION_BOUND_MM = {0.25: 1.5 * 226, 0.6: 1.5 * 147}


@pytest.mark.parametrize("max_speed, seed", [(0.25, SEEDS[0]), (0.6, SEEDS[1])])
def test_generated_streams_never_exceed_limits_jump_or_swing_beyond_todays_bound(max_speed,
                                                                                 seed):
    run = replay_generated(seed, StreamSettings(duration_s=8.0, max_speed_m_s=max_speed))
    assert run.ended == "done", run
    assert run.finite
    assert run.limit_excess_rad <= 1e-9
    assert run.max_step_ratio <= 1.0 + 1e-6
    for arm, figures in run.hands.items():
        assert figures["max_excursion_mm"] <= EXCURSION_BOUND_MM[max_speed], (arm, figures)
        assert (figures["reachable_max_excursion_mm"] or 0.0) <= REACHABLE_EXCURSION_BOUND_MM[
            max_speed], (arm, figures)
        assert figures["branch_changes"] == 0, (arm, figures)
