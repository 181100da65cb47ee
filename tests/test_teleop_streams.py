"""A property test over generated operator streams (:mod:`hubo_cli.input.operator_stream`):
streams no one tuned the teleoperation on, replayed through ``hubo teleop`` on the ideal driver.

It asserts what holds today, with a margin over what was measured: no command beyond a joint
limit, none not finite, no jump (a joint step beyond its speed limit in one period), and the
largest excursion within 1.5x the worst measured over the bench's streams. It does not assert
the issue's accuracy targets (position RMS <= 10 mm, orientation RMS <= 3 deg over the time the
goal is reachable, excursion <= 15 mm): they are not met today (``make bench BENCH=teleop``
prints the distribution). Few short streams through the whole session here; the bench replays
more. Many shorter ones go through the teleop target and the trajectory generator alone
(``stream_runs.follow_generated``): the issue's swing target (excursion <= 15 mm up to
0.6 m/s) is asserted, its accuracy targets at 0.25 m/s are a strict expected failure.
"""

import numpy as np
import pytest

from hubo_cli.estimation.build import build_estimator
from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.teleop.stream_runs import GENERATED_SETS, meets_targets, replay_generated

# the seeds are drawn, not picked (a new draw is a new test of the same properties)
SEEDS = np.random.default_rng(3434).integers(0, 2**31, 2).tolist()
# The largest excursion, worst over the bench's streams (make bench BENCH=teleop: 20 streams
# <= 0.25 m/s and 8 <= 0.6 m/s, 20 s each, seeds 3400-3419, ideal driver; the same figures on
# two runs; measured when the generator turned the hands at up to 90 deg/s, before its
# 40 deg/s cap): over the whole run (where the goal is out of reach it includes how far beyond
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


def test_the_devices_clutch_holds_the_hand_and_recentres_without_a_jump(model):
    """The operator moves 5 cm forward, holds the clutch while going 10 cm back, releases it
    and moves 5 cm forward again: the goal goes 5 cm forward, holds, then 5 cm further, with
    no step; the robot's hand ends 10 cm forward while the operator's is back where it began.
    Then the hand is silent for 0.4 s (lost; the replay re-centres it by itself). Each
    re-centre starts the hand's reach lead anew: a goal position pushed into its history while
    the hand is held is gone in the period it is re-centred."""
    from hubo_cli.drivers.registry import make_driver
    from hubo_cli.geometry import min_jerk
    from hubo_cli.input.device import HandPose, RecordedInput
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.mapping import HandMapper
    from hubo_cli.teleop.phases import PHASES
    from hubo_cli.teleop.session import TeleopSettings, approach_paths, prepare
    from hubo_cli.teleop.target import TeleopTarget

    def x_m(t):  # the operator's hand along x: +5 cm, back 10 cm (clutched), +5 cm
        return 0.05 * (min_jerk(t - 1.0) - 2 * min_jerk(t - 2.5) + min_jerk(t - 4.0))

    t = np.arange(0.0, 6.0, 1 / 120)
    poses = []
    for ti in t[(t < 5.2) | (t >= 5.6)]:   # silent from 5.2 s to 5.6 s
        T = np.eye(4)
        T[:3, 3] = [0.3 + x_m(ti), -0.2, -0.1]
        poses.append(HandPose("right", T, float(ti), engaged=not 2.4 <= ti < 3.6))
    settings = TeleopSettings(generate_seed=0, station_arm={1: "right-arm"})
    _, body, mapping, scene = prepare(settings, model)
    driver = make_driver("ideal", model)
    with driver, RecordedInput(poses, {"kind": "test"}) as device:
        driver.start(home_posture(model))
        target = TeleopTarget(model, device, HandMapper(mapping), body,
                              approach_paths(body, ["right-arm"], scene), home_posture(model))
        state, t_s, goals, phases = driver.read(), 0.0, [], []
        estimator = build_estimator(model, period_s=driver.period_s)  # as the loop runs it
        target.store = estimator.reset(state)
        hand, lead, far_m = target.hands["right-arm"], target.leads["right-arm"], np.ones(3)
        recentred = {}  # why the hand was held -> whether far_m was gone once re-centred
        while target.phase != "settle" and t_s < 30.0:
            held = [k for k in ("clutched", "lost") if getattr(hand, k)]
            q, info = target(t_s, state)
            if held and not (hand.clutched or hand.lost):
                recentred[held[0]] = not any(np.array_equal(p, far_m) for p in lead._p)
            if target.phase == "operate" and (hand.clutched or hand.lost):
                lead.push(t_s, far_m)
            phases.append((target.phase, info["phase_code"]))
            driver.send(q)
            state = driver.step()
            estimator.update(state)
            if target.phase == "operate" and target.mapper.is_calibrated("right"):
                goals.append((t_s - target.t_operate_s, target.goals["right-arm"][:3, 3].copy()))
            t_s += model.control_period_s
    times = np.array([g[0] for g in goals])
    x = np.array([g[1][0] for g in goals]) - goals[0][1][0]
    assert target.phase == "settle"
    # the phases in order, each period's log code its own (the balance report reads them)
    assert list(dict.fromkeys(phases)) == [(name, PHASES.index(name)) for name in PHASES]
    clutched = (times >= 2.45) & (times < 3.6)
    assert np.ptp(x[clutched]) < 1e-12  # held while the clutch is down
    assert x[clutched][0] == pytest.approx(0.05, abs=2e-3)
    assert x[-1] == pytest.approx(0.10, abs=2e-3)  # 5 + 5 cm: the clutched return not followed
    # no step: at most the operator's own motion in a period (0.05 m min-jerk in 1 s peaks at
    # 0.094 m/s, 0.8 mm per 1/120 s)
    assert np.max(np.abs(np.diff(x))) < 1e-3
    assert recentred == {"clutched": True, "lost": True}


# Many short streams no one tuned on (drawn, not picked), followed by the teleop target and the
# trajectory generator alone (stream_runs.follow_generated: about 0.7 s of CPU each): 50 at the
# accuracy test's hand speed, 10 at the swing test's.
MANY_SETS = GENERATED_SETS
MANY_S = 1.5
# The worst over each set (ideal driver, the generator's turns at most 40 deg/s, the arms'
# tracker meeting the goal's prediction with the joints traded where one cannot follow,
# teleop/trade.py, free mode's orientation filter at 0.65 s while the arm follows its goal
# freely, kinematics/arm_reach.py; the same to 5e-12 on both code paths, AVX-512 / portable;
# with the 1 s filter throughout 28.5 / 46.3 mm and 9.7 / 14.7 mm): reachable position RMS
# 29.1 mm (0.25 m/s) and 44.7 mm (0.6 m/s), largest excursion 9.3 and 14.6 mm. The bounds are
# 1.5x those. (The medians per hand at 0.25 m/s: 2.6 mm RMS, 2.19 deg; about 25 s of CPU for
# the 60.)
MANY_BOUNDS = {0.25: {"reachable_position_rms_mm": 1.5 * 29.1, "max_excursion_mm": 1.5 * 9.3},
               0.6: {"reachable_position_rms_mm": 1.5 * 44.7, "max_excursion_mm": 1.5 * 14.6}}


@pytest.fixture(scope="module")
def many_streams():
    from hubo_cli.teleop.stream_runs import follow_generated

    return {speed: [follow_generated(seed, StreamSettings(duration_s=MANY_S,
                                                          max_speed_m_s=speed))
                    for seed in seeds] for speed, seeds in MANY_SETS.items()}


def test_many_generated_streams_keep_the_limits_and_the_goals_path(many_streams):
    """Every stream: no command beyond a joint limit, none not finite, no jump, no branch
    change; the largest excursion and the position RMS over the reachable time within 1.5x the
    worst measured (see MANY_BOUNDS)."""
    for speed, runs in many_streams.items():
        for run in runs:
            assert run.ended == "done", run
            assert run.finite and run.limit_excess_rad <= 1e-9, run
            assert run.max_step_ratio <= 1.0 + 1e-6, run
            for arm, figures in run.hands.items():
                assert figures["branch_changes"] == 0, (arm, run)
                for key, bound in MANY_BOUNDS[speed].items():
                    assert (figures[key] or 0.0) <= bound, (key, arm, run)


@pytest.mark.xfail(strict=True, reason="issue 34's accuracy targets are not met (30 of 50 "
                   "streams miss, 17 on orientation alone; worst 29.1 mm, 6.6 deg RMS; "
                   "docs/history/teleop.md, 'Following generated streams', 'What the limits "
                   "allow on generated streams', 'Where the error on generated streams comes "
                   "from', rounds 7 to 9; round 16: a causal controller reaches them on 80 "
                   "of the 100 hands, the run on 65)")
def test_many_generated_streams_meet_issue_34s_accuracy_targets(many_streams):
    """Issue 34: at hand speeds up to 0.25 m/s, over the time the goal is reachable, position
    RMS <= 10 mm and orientation RMS <= 3 deg per hand per stream, excursion <= 15 mm."""
    for run in many_streams[0.25]:
        assert all(meets_targets(figures) for figures in run.hands.values()), run


# What the run meets of issue 34's targets on the 50 streams at 0.25 m/s (docs/history/teleop.md,
# "Round 16: a causal floor on generated streams"): 85 hands within 10 mm, 73 within 3 deg, 65
# meeting all three targets, 20 streams whose both hands do; reachable position RMS median
# 2.58 mm, orientation 2.19 deg (the same to 5e-12 on both code paths, AVX-512 / portable).
# With the 1 s orientation filter throughout (round 9's law) 85 / 68 / 61 hands, 16 streams,
# 2.49 mm / 2.35 deg. The bounds leave three hands, three streams and about 15 % of a median.
HELD_HANDS = {"position": 82, "orientation": 70, "all": 62}
HELD_STREAMS = 17
HELD_MEDIANS = {"reachable_position_rms_mm": 3.0, "reachable_orientation_rms_deg": 2.5}
# Not marked physical: the streams' figures are the same to 5e-12 on both code paths, and on the
# portable run this test alone would follow the 60 streams again (19 s of the CI run, round 16).


def test_many_generated_streams_keep_what_they_meet_of_issue_34s_targets(many_streams):
    """What the run meets of issue 34's accuracy targets, held (the issue's own figure, every
    hand, is the strict expected failure above): the hands within 10 mm, within 3 deg and
    within all three targets, the streams whose both hands are, and the median errors, each
    with a margin over what was measured (see HELD_HANDS)."""
    runs = many_streams[0.25]
    hands = [figures for run in runs for figures in run.hands.values()]
    position = np.array([f["reachable_position_rms_mm"] or 0.0 for f in hands])
    orientation = np.array([f["reachable_orientation_rms_deg"] or 0.0 for f in hands])
    held = {"position": int(np.sum(position <= 10.0)),
            "orientation": int(np.sum(orientation <= 3.0)),
            "all": sum(meets_targets(f) for f in hands)}
    assert all(held[key] >= bound for key, bound in HELD_HANDS.items()), held
    streams = sum(all(meets_targets(f) for f in run.hands.values()) for run in runs)
    assert streams >= HELD_STREAMS, streams
    medians = {"reachable_position_rms_mm": np.median(position),
               "reachable_orientation_rms_deg": np.median(orientation)}
    assert all(medians[key] <= bound for key, bound in HELD_MEDIANS.items()), medians


def test_fast_generated_streams_lag_along_the_goals_path(many_streams):
    """Issue 34: up to 0.6 m/s (beyond what the joints' speed limits can follow) the hand lags
    along the goal's path and never swings off it: excursion <= 15 mm. Measured worst 14.6 mm
    over the 20 hands (the same to 5e-12 mm on the portable code path: no spread; 14.7 mm with
    the 1 s orientation filter throughout, 15.6 mm with 0.6 s where the arm follows freely
    instead of 0.65 s, kinematics/arm_reach.py; 13.6 mm before
    the arms' joints were traded, teleop/trade.py, 12.9 mm before the arms' tracker met the
    goal's prediction, teleop/lead.tracking_target); 28.6 mm when the generator
    turned the hands at up to 90 deg/s, beyond what the arm joints' speed limit follows
    (hubo_cli/input/operator_stream.py)."""
    for run in many_streams[0.6]:
        assert all(figures["max_excursion_mm"] <= 15.0 for figures in run.hands.values()), run
