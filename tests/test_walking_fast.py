"""The fast gait on the simulated robot (``hubo walk --to 2.0 0 0 --gait fast``, issue 37)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hubo_cli.model import load_model


@pytest.mark.physical
@pytest.mark.slow
def test_the_fast_gait_walks_two_metres_without_a_fall_or_a_stop(tmp_path):
    """The nominal robot walks 2 m in the fast gait without a fall, a stop or a moved landing,
    its commands within the walking set's 2.6 rad/s. Measured: on AVX-512 12 steps at 0.209
    m/s, 11.4 mm / 0.71 deg off the goal; on the portable path the estimate ended the 12 steps
    8 mm or more off, a correction took 2 more (0.152 m/s) and the truth ended 14.3 mm / 0.78 deg
    off (the soles' twist, which the estimate does not see). Bound 25 mm: 1.7x the larger. The
    speed is the plan's unless a correction walks: 0.209 m/s for the 12 steps
    (tests/test_walking_pattern.py)."""
    from hubo_cli.experiments.walk import walk

    result = walk(load_model(), (2.0, 0.0, 0.0), out=tmp_path / "run", gait="fast")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stopped_s is None and result.shifts == 0
    assert summary["max_joint_velocity_ratio"] <= 1.0 + 1e-9
    assert result.steps in (12, 14)  # 14: a correction's two steps
    assert result.average_speed_m_s >= (0.2 if result.steps == 12 else 0.15)
    assert result.final_error_mm < 25.0


@pytest.mark.physical
@pytest.mark.slow
def test_the_fast_gait_walks_on_after_the_capture_point_moved_a_landing(tmp_path):
    """The fast 2 m walk pushed from the front (50 N, 0.2 s) at 3.0 s: the capture point moves
    a landing twice; the walk goes on to its end without a fall or a stop. (Until round 23
    robot 5's capture-point monitor had stopped the walk at 8.99 s before the monitor's planned
    support lay on the estimated floor.) Until round 31 the unpushed perturbed robot 40 moved
    two landings; with the tracker's synchronisation swings gone it moves none, and no seed of
    1-40 moves one on both code paths (docs/history/walking.md, round 31). A moved landing is a
    threshold event: pushed at 2.95 s both paths move two as well; at 3.05 s, or with 45 or
    55 N, none. Measured: the capture point came within 59.1 mm (AVX-512) and 49.4 mm
    (portable path) of the planned support's shrunk edge, never outside; bound 33 mm = the
    closer / 1.5."""
    from hubo_cli.control.log import load_log
    from hubo_cli.experiments.walk import Disturbance, walk

    result = walk(load_model(), (2.0, 0.0, 0.0), out=tmp_path / "run", gait="fast",
                  disturbances=[Disturbance(3.0, 50.0, (-1.0, 0.0, 0.0))])
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stopped_s is None and result.shifts >= 1
    assert summary["estop_events"] == []
    log = load_log(result.run_dir)
    walking = np.isfinite(np.asarray(log["walk.step"], dtype=float))
    assert np.asarray(log["cp_outside_m"], dtype=float)[walking].max() < -0.033


@pytest.mark.physical
@pytest.mark.slow
def test_the_fast_gaits_own_capture_point_lag_abandons_no_swing(tmp_path):
    """Perturbed robot 11 in the fast gait: its capture point lags the pattern's by more than
    20 mm from behind mid-swing without a push (its slips). A swing abandoned for it (put down
    where the foot is, as after a front push: WalkTarget._abandoned, while the walk still
    walked) fell at 6.455 s (AVX-512); abandoned only once the walk is stopping, the walk does
    not fall: on main the capture-point monitor stopped it at 7.925 s (AVX-512) / 8.78 s
    (portable) and it stood (docs/history/walking.md, round 9 addendum); with round 13's slip
    turn the monitor stops it on AVX-512 (8.945 s) and on the portable path the walk goes on to
    its goal, 25 mm off after a correction (round 13). Either end is this test's: no fall,
    a stop that stands or the walk's end."""
    from hubo_cli.experiments.walk import walk

    result = walk(load_model(), (2.0, 0.0, 0.0), out=tmp_path / "run", gait="fast",
                  perturb_seed=11)
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False
    assert result.stood is True if result.stopped_s is not None else result.ended == "done"
    # measured max tilt 9.5 deg (AVX-512, stopped) and 7.2 (portable, walked on); a fall: 30;
    # bound 20 deg = 2.1x the larger
    assert summary["max_torso_tilt_deg"] < 20.0
