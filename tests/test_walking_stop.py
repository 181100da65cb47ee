"""Stopping while walking and moving footsteps after the capture point (issue 37, item 3): the
soft stopper's ``finish`` mode, the re-planned pattern's continuity and limits, and one walk
stopped in mid-swing on the simulated robot."""

from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pytest
from walking_support import standing_walk

from hubo_cli.control.estop import MAX_FINISH_S, MODE_CODE, EmergencyStopper
from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.module import Cycle
from hubo_cli.control.phase import PHASE_STOP, PhaseStop
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import COM_WORLD, WRENCHES
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.state import ANKLE_SENSORS, RobotState
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps
from hubo_cli.walking.gait import make_gait
from hubo_cli.walking.params import DEFAULT_GAIT, walking_params
from hubo_cli.walking.replan import (
    CP_GAP_M,
    CP_MAX_SHIFT_M,
    CP_STEP_BACKWARD_M,
    CP_STEP_FORWARD_M,
    CP_WIDTH_MAX_M,
    pattern_from,
    shift_steps,
    shifted_landing,
)

DT = 0.005


@pytest.fixture(scope="module")
def model():
    return load_model()


def _stopper_run(model, phase_stops, latch_k=3, periods=400, release_k=None):
    """Feed a moving joint command through the soft stopper; the store's PHASE_STOP per
    period from ``phase_stops(k)``; an operator stop at ``latch_k``, released at
    ``release_k`` (None: never). Returns (inputs, outputs, modes, stopper)."""
    stopper = EmergencyStopper(model, DT)
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    store = Store()
    store[WRENCHES] = state.ft
    stopper.reset(q0, state, store)
    inputs, outputs, modes = [], [], []
    for k in range(periods):
        cycle = Cycle(k * DT, DT, store=store)
        store[PHASE_STOP] = phase_stops(k)
        if k == latch_k:
            cycle.estop_requests.add("operator")
        if k == release_k:
            stopper.release()
        q = q0.copy()
        q[0] += 0.2 * math.sin(k * DT)  # a slow motion (within every limit)
        outputs.append(stopper.update(q, state, cycle))
        inputs.append(q)
        modes.append(store[STOP_MODE])
    return np.array(inputs), np.array(outputs), modes, stopper


def test_a_phase_that_stops_itself_is_passed_through_then_held(model):
    settle_k = 200
    inputs, outputs, modes, stopper = _stopper_run(
        model, lambda k: PhaseStop(k >= settle_k, 2.0))
    assert modes[2] == "release" and modes[3] == "finish" and modes[settle_k - 1] == "finish"
    # the phase's own motion passes unchanged while it finishes its step
    assert np.array_equal(outputs[3:settle_k], inputs[3:settle_k])
    # settled: held at that period's posture, for good (the stop is still the stopper's)
    assert set(modes[settle_k:]) == {"hold"}
    assert np.allclose(outputs[settle_k:], inputs[settle_k])
    assert [e.kind for e in stopper.events] == ["stop", "finish"]  # both in the summary
    assert MODE_CODE["finish"] == 4


@pytest.mark.parametrize("phase_stops, braked_k, event, why", [
    (lambda k: PhaseStop(False, 0.5), 3 + round(0.5 / DT) + 1, "finish-deadline",
     "never settles within 0.5 s"),
    (lambda k: PhaseStop(False, 1e9), 3 + round(MAX_FINISH_S / DT) + 1, "finish-deadline",
     "asks for more than MAX_FINISH_S"),
    (lambda k: PhaseStop(False, 2.0) if k < 50 else None, 50, "finish-lost",
     "stops saying how it stops"),
])
def test_a_phase_that_does_not_settle_is_braked_and_held(model, phase_stops, braked_k, event,
                                                         why):
    inputs, outputs, modes, stopper = _stopper_run(model, phase_stops, periods=braked_k + 200)
    assert modes.index("stop") == braked_k, why
    assert event in [e.kind for e in stopper.events], why
    assert modes[-1] == "hold", why
    # braked from its motion: no jump beyond one period's travel at the input's speed
    assert np.max(np.abs(np.diff(outputs[:, 0]))) < 0.2 * DT * 1.5


def test_without_a_phase_stop_the_stop_reverts_as_before(model):
    _, _, modes, _ = _stopper_run(model, lambda k: None)
    assert modes[3] == "stop" and "finish" not in modes


def test_a_release_during_finish_joins_the_phase_at_once(model):
    """Released while it passes the phase's motion, the stopper passes it on (release, not a
    2.5 s blend that would play the open-loop motion late); a second stop is then a finish
    again, not a brake (review: a blend lagged a capture step's pattern by up to 1.3 rad)."""
    inputs, outputs, modes, stopper = _stopper_run(model, lambda k: PhaseStop(False, 2.0),
                                                   latch_k=2, periods=40, release_k=10)
    assert modes[9] == "finish" and set(modes[10:]) == {"release"}
    assert np.array_equal(outputs, inputs)  # nothing lagged, before, during or after
    assert [e.kind for e in stopper.events] == ["stop", "finish", "release"]

    state = RobotState(0.0, inputs[-1], np.zeros(24))
    cycle = Cycle(40 * DT, DT, store=Store())
    cycle.store[WRENCHES] = state.ft
    cycle.store[PHASE_STOP] = PhaseStop(False, 2.0)
    cycle.estop_requests.add("operator")
    assert np.array_equal(stopper.update(inputs[-1], state, cycle), inputs[-1])
    assert cycle.store[STOP_MODE] == "finish"


@pytest.mark.parametrize("phase_stops, release_k, why", [
    (lambda k: PhaseStop(k >= 10, 2.0), 20, "settled and held"),
    (lambda k: PhaseStop(False, 0.05), 40, "braked at its deadline"),
])
def test_a_release_after_the_finish_held_or_braked_blends_back(model, phase_stops, release_k,
                                                               why):
    inputs, outputs, modes, _ = _stopper_run(model, phase_stops, latch_k=2, periods=60,
                                             release_k=release_k)
    assert modes[release_k - 1] in ("hold", "stop"), why
    assert modes[release_k] == "recover", why
    # from the held output, no jump
    assert np.max(np.abs(outputs[release_k] - outputs[release_k - 1])) < 1e-3, why


@pytest.fixture(scope="module")
def walk_pattern(model):
    from hubo_cli.model import load_model as load

    walking = load(model.params_name, "walking")
    params = walking_params(walking)
    here = Stance(0.0, 0.0, 0.0)
    right, left = here.foot("right", params.step_width_m), here.foot("left", params.step_width_m)
    steps = plan_footsteps(right, left, Stance(0.6, 0.0, 0.0), params)
    gait = make_gait(right, left, steps, params, DT, 0.6, 0.0, walking.feet.forward_m,
                     com_start_m=np.zeros(2))
    return params, walking, (right, left), steps, gait


def _continuous(before: np.ndarray, after: np.ndarray, step: float) -> bool:
    return float(np.max(np.abs(after - before))) <= step


@pytest.mark.parametrize("seed", range(6))
def test_a_replanned_pattern_continues_without_a_jump(walk_pattern, seed):
    """Stop (steps cut after the one in progress) or move the landing, at a random period:
    the CoM, its velocity and every foot continue from where the pattern was."""
    params, walking, start, steps, gait = walk_pattern
    rng = np.random.default_rng(seed)
    swinging = np.nonzero(~gait.support.all(axis=1))[0]
    # a landing moves while its foot swings (as the walk does); a stop comes at any period
    k = int(rng.choice(swinging)) if seed % 2 else int(rng.integers(1, gait.n - 2))
    step = int(gait.step_index[k])
    if seed % 2:
        new = shift_steps(steps, step, Footstep(steps[step].side,
                                                steps[step].x_m + rng.uniform(-0.05, 0.05),
                                                steps[step].y_m + rng.uniform(-0.05, 0.05),
                                                steps[step].yaw_rad))
    else:
        new = steps[:step + 1] if step >= 0 else []
    suffix = pattern_from(gait, k, k, start, new, params, 0.0, walking.feet.forward_m,
                          np.zeros(2))
    # one period's motion at most (the pattern's own speeds: < 1 m/s for the CoM and feet)
    assert _continuous(gait.com.com_m[k], suffix.com.com_m[0], 1e-9)
    assert _continuous(gait.com.com_velocity_m_s[k], suffix.com.com_velocity_m_s[0], 1e-9)
    for side in ("right", "left"):
        assert _continuous(gait.feet[side][k - 1], suffix.feet[side][0], 1.0 * DT * 2)
        assert np.all(np.abs(np.diff(suffix.feet[side][:, :2], axis=0)) <= 2.0 * DT)
    assert suffix.support[-1].all()  # it ends with both feet down
    assert np.all(np.isfinite(suffix.com.com_m))


def test_a_pattern_replanned_mid_swing_plans_its_support_on_the_floor(walk_pattern):
    """A landing moved while its foot is up (the re-plan's first row has the foot 19 mm up):
    the capture-point monitor's planned support still has both soles on the floor the plan
    was made on (it drops a sole 5 mm above the other; with the first row's height the swing
    foot's landing was dropped and the monitor stopped fast walks whose landing moved)."""
    from hubo_cli.walking.support import planned_support

    params, walking, start, steps, gait = walk_pattern
    swinging = np.nonzero(~gait.support.all(axis=1))[0]
    k = int(swinging[np.argmax(gait.feet["right"][swinging, 2] + gait.feet["left"][swinging, 2])])
    step = int(gait.step_index[k])
    new = shift_steps(steps, step, Footstep(steps[step].side, steps[step].x_m + 0.02,
                                            steps[step].y_m, steps[step].yaw_rad))
    suffix = pattern_from(gait, k, k, start, new, params, 0.0, walking.feet.forward_m,
                          np.zeros(2))
    assert max(suffix.feet[side][0, 2] for side in ("right", "left")) > 0.015
    assert np.all(planned_support(suffix, 0.0)[:, :, 2, 3] == 0.0)
    floor_z = 0.0123  # an estimated floor elsewhere: the soles lie on it
    assert np.all(planned_support(suffix, floor_z)[:, :, 2, 3] == floor_z)


def _early_touchdown(gait, steps, seed: int):
    """A swing foot down early at a random period ``k`` of its swing (past a third of it),
    within 2 cm of where the pattern has it: (k, its step, side, the planned landing's period,
    the sole's pattern row (x, y, z, yaw) moved so)."""
    rng = np.random.default_rng(seed)
    swinging = np.nonzero(~gait.support.all(axis=1) & (gait.step_index >= 0))[0]
    k = int(rng.choice(swinging[len(swinging) // 3:]))
    step = int(gait.step_index[k])
    side = steps[step].side
    landing = k + int(np.argmax(gait.support[k:].all(axis=1)))
    row = gait.feet[side][k] + np.append(rng.uniform(-0.02, 0.02, 2), [0.0, 0.0])
    return k, step, side, landing, row


@pytest.mark.parametrize("seed", range(8))
def test_a_swing_ended_early_puts_the_foot_down_without_a_jump(walk_pattern, seed):
    """A swing foot down early at a random period of its swing (past a third of it), within
    2 cm of where the pattern has it (the estimate's sole, pushed down): the re-plan plays
    from that landing's row on, the foot is down from this period and moves from its command
    onto the new place within TOUCH_BLEND_ROWS without a jump, the other foot stays, and the
    CoM continues."""
    from hubo_cli.walking.replan import TOUCH_BLEND_ROWS

    params, walking, start, steps, gait = walk_pattern
    k, step, side, landing, (x, y, _, yaw) = _early_touchdown(gait, steps, seed)
    column = 0 if side == "right" else 1
    moved = Footstep(side, x, y, yaw)
    suffix = pattern_from(gait, k, landing, start, shift_steps(steps, step, moved), params,
                          0.0, walking.feet.forward_m, np.zeros(2))
    assert suffix.support[0].all()  # down at once, the double support from now
    foot = suffix.feet[side]
    assert _continuous(gait.feet[side][k], foot[0], 0.2 * abs(gait.feet[side][k, 2]) + 1e-3)
    np.testing.assert_allclose(foot[TOUCH_BLEND_ROWS - 1:TOUCH_BLEND_ROWS + 5, :2],
                               np.tile([moved.x_m, moved.y_m], (6, 1)), atol=1e-9)
    # 2 cm (and the swing height, <= 2 cm) over TOUCH_BLEND_ROWS: at most 1.875 x 2 cm / 10
    # a row (the quintic's peak speed); a swing moves up to 5 mm a row
    assert np.all(np.abs(np.diff(foot[:, :3], axis=0)) <= 0.006)
    other = "left" if side == "right" else "right"
    np.testing.assert_allclose(suffix.feet[other][0], gait.feet[other][k], atol=1e-9)
    assert _continuous(gait.com.com_m[k], suffix.com.com_m[0], 1e-9)
    assert _continuous(gait.com.com_velocity_m_s[k], suffix.com.com_velocity_m_s[0], 1e-9)
    assert not gait.support[k, column]


@pytest.mark.parametrize("seed", range(8))
def test_a_swing_ended_early_without_a_push_keeps_its_timeline(walk_pattern, seed):
    """A swing foot down early (past a third of its swing, within 2 cm of where the pattern
    has it) while the robot follows its pattern: the re-plan holds that step's foot down
    (``planted``) from this period on, at its new place from TOUCH_BLEND_ROWS on, the ZMP
    reference the pattern's until the planned landing, and the CoM keeps the pattern's pace.
    Skipped to the landing instead, the fast gait's CoM was driven at 0.8 m/s."""
    from hubo_cli.walking.replan import TOUCH_BLEND_ROWS

    params, walking, start, steps, gait = walk_pattern
    k, step, side, landing, (x, y, _, yaw) = _early_touchdown(gait, steps, seed)
    held = pattern_from(gait, k, k, start, shift_steps(steps, step, Footstep(side, x, y, yaw)),
                        params, 0.0, walking.feet.forward_m, np.zeros(2), step)
    rows = landing - k
    assert held.support[:rows].all()
    np.testing.assert_allclose(held.feet[side][TOUCH_BLEND_ROWS - 1:TOUCH_BLEND_ROWS + 5, :2],
                               np.tile([x, y], (6, 1)), atol=1e-9)
    np.testing.assert_allclose(held.zmp_ref_m[:rows], gait.zmp_ref_m[k:landing], atol=1e-12)
    assert _continuous(gait.com.com_velocity_m_s[k], held.com.com_velocity_m_s[0], 1e-9)
    # measured on these 8 seeds: the CoM's velocity at most 0.068 m/s from the pattern's up to
    # the landing (the landing moved up to 2.8 cm); skipped to the landing 0.12-0.38 m/s.
    # Bound 0.12 m/s = 1.8x the measured
    pace = np.abs(held.com.com_velocity_m_s[:rows] - gait.com.com_velocity_m_s[k:landing])
    assert float(pace.max()) <= 0.12


@pytest.mark.parametrize("seed", range(40))
def test_a_moved_landing_keeps_the_limits_and_never_crosses(model, seed):
    """Hostile shifts, headings and sides: the landing stays within the step limits seen from
    the stance foot, on its own side of it with a gap, and moves at most CP_MAX_SHIFT_M."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-math.pi, math.pi)
    side = ("right", "left")[seed % 2]
    other = "left" if side == "right" else "right"
    stance = Footstep(other, *rng.uniform(-2, 2, 2), yaw)
    planned = Stance(stance.x_m, stance.y_m, yaw).foot(side, 0.48)  # 0.24 beside the stance
    shift = rng.normal(0.0, 0.3, 2) * (10.0 if seed % 5 == 0 else 1.0)
    moved = shifted_landing(stance, planned, shift, model.feet.width_m, 0.24)
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = moved.x_m - stance.x_m, moved.y_m - stance.y_m
    ahead, left = c * dx + s * dy, -s * dx + c * dy
    across = left if side == "left" else -left
    assert -CP_STEP_BACKWARD_M - 1e-9 <= ahead <= CP_STEP_FORWARD_M + 1e-9
    assert model.feet.width_m + CP_GAP_M - 1e-9 <= across <= CP_WIDTH_MAX_M + 1e-9
    assert moved.side == side and moved.yaw_rad == planned.yaw_rad
    assert math.hypot(moved.x_m - planned.x_m, moved.y_m - planned.y_m) <= (
        CP_MAX_SHIFT_M + CP_WIDTH_MAX_M + 1e-9)


def test_later_footsteps_move_with_the_landing(walk_pattern):
    _, _, _, steps, _ = walk_pattern
    moved = Footstep(steps[1].side, steps[1].x_m + 0.03, steps[1].y_m - 0.02, steps[1].yaw_rad)
    new = shift_steps(steps, 1, moved)
    assert new[:1] == steps[:1] and new[1] == moved
    for before, after in zip(steps[2:], new[2:], strict=True):
        assert (after.x_m - before.x_m, after.y_m - before.y_m) == pytest.approx((0.03, -0.02))


BACKWARD, RIGHTWARD, LEFTWARD = (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 1.0, 0.0)
# The simulated walks the tests below push or stop: name -> (goal, the disturbance as
# Disturbance's at_s, push_n, direction, stop; the test that reads it). Walks to the same goal
# are the same walk until their disturbance: the pushed_walks fixture walks them together.
PUSHED_WALKS = {
    "stop at 3.418": ((1.0, 0.0, 0.0), (3.418, 0.0, (1.0, 0.0, 0.0), True),
                      "test_a_stop_late_in_a_swing_comes_to_rest_in_the_held_stance"),
    "front 4.841": ((1.0, 0.0, 0.0), (4.841, 100.0, BACKWARD),
                    "test_a_push_from_the_front_is_caught_by_the_capture_point_stop"),
    **{f"front {at_s}": ((1.0, 0.0, 0.0), (at_s, 100.0, BACKWARD),
                         f"test_a_push_from_the_front_mid_walk_moves_the_landing_at_once[{at_s}]")
       for at_s in (1.88999, 5.26526)},
    "front 1.9": ((1.0, 0.0, 0.0), (1.900, 100.0, BACKWARD),
                  "test_a_push_from_the_front_early_in_a_swing_puts_the_rear_foot_back_down"),
    "front 2.936": ((1.0, 0.0, 0.0), (2.936, 100.0, BACKWARD),
                    "test_a_rear_foot_put_back_down_is_not_held_in_the_air"),
    "from the left 4.13692": (
        (1.0, 0.0, 0.0), (4.13692, 100.0, RIGHTWARD),
        "test_a_side_push_that_puts_the_swing_foot_down_ends_the_swing_there"),
    "front 8.16153": ((1.0, 0.0, 0.0), (8.16153, 100.0, BACKWARD),
                      "test_a_swing_foot_carried_back_by_a_tipping_body_still_lands_flat"),
    "from the right 3.155": ((1.0, 0.0, 0.0), (3.155, 100.0, LEFTWARD),
                             "test_a_foot_does_not_lift_off_while_the_robot_bounces"),
    "front 7.558941": ((1.0, 0.0, 0.0), (7.558941, 100.0, BACKWARD),
                       "test_a_landing_waits_for_its_foot_after_a_push_just_before_it"),
    "2 m front 1.075": ((2.0, 0.0, 0.0), (1.075, 100.0, BACKWARD),
                        "test_a_stops_last_landing_after_a_push_from_the_front_holds_the_capture_point"),
}


@pytest.fixture(scope="module")
def pushed_walks(request, tmp_path_factory):
    """``pushed_walks(name)``: the WalkResult of ``walk(model, goal, out=...,
    disturbances=[Disturbance(...)])`` for PUSHED_WALKS[name]. The walks to a goal are walked
    together the first time one of them is asked for (those of the selected tests): they share
    their first seconds, up to each one's disturbance (tests/walk_branches.py; each continued
    walk is the fresh walk, its log and summary the same: docs/history/
    performance-latest-round.md, round 19)."""
    from walk_branches import branched_walks

    from hubo_cli.experiments.walk import Disturbance

    selected = {item.name for item in request.session.items if item.module is request.module}
    results = {}

    def walked(name: str):
        if name not in results:
            goal = PUSHED_WALKS[name][0]
            together = {other: [Disturbance(*disturbance)]
                        for other, (to, disturbance, test) in PUSHED_WALKS.items()
                        if to == goal and (test in selected or other == name)}
            results.update(branched_walks(goal, together, tmp_path_factory.mktemp("pushed")))
        if isinstance(results[name], BaseException):
            raise results[name]
        return results[name]

    return walked


@pytest.mark.physical
@pytest.mark.slow
def test_ctrl_c_in_mid_swing_ends_standing_as_the_operators_stop(tmp_path, model, monkeypatch):
    """hubo walk --to 0.3 0 0 given Ctrl-C at 2.2 s, half way through the second step's swing
    (1.9-2.6 s): the loop asks the walk for the operator's stop (the space key's, --stop-at's)
    instead of braking where it is; the step lands, the walk stands in double support, the
    stopper holds it (no revert, no fall) and the run ends interrupted once the stance has
    held 0.5 s. On main the loop's brake stopped the joints in 15 ms with the swing foot in the
    air (its sole -11 N) and the run ended there. (The operator's own stop by the same path:
    the next test's.)"""
    from hubo_cli.control.log import load_log
    from hubo_cli.experiments import walk as walking

    played = walking.Disturbed.__call__

    def interrupted(self, t_s, state):
        if abs(t_s - 2.2) < DT / 2:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C
        return played(self, t_s, state)

    monkeypatch.setattr(walking.Disturbed, "__call__", interrupted)
    result = walking.walk(model, (0.3, 0.0, 0.0), corrections=0, out=tmp_path / "run",
                          disturbances=[walking.Disturbance(99.0, stop=True)])  # (none)
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.ended == "interrupted" and result.fell is False and result.stood is True
    assert summary["interrupt_stop"] == "stood"
    assert result.stopped_s == pytest.approx(2.21, abs=0.011)  # taken at 2.205, seen next
    assert [e["kind"] for e in summary["estop_events"]] == ["stop", "finish"]
    assert len(result.footsteps) == 2  # the step in the air was finished, no more
    log = load_log(result.run_dir / "log.parquet")
    modes = np.asarray(log["estop_mode_code"], dtype=float)
    modes = modes[np.isfinite(modes)]
    # finish (the walk's own stop passed through), then hold; never the revert's stop mode
    assert MODE_CODE["stop"] not in set(modes) and modes[-1] == MODE_CODE["hold"]
    assert summary["smooth_stop_s"] < 0.05  # the loop's brake had nothing left to stop
    contact = np.column_stack([np.asarray(log[f"{s}_foot_contact_flag"], dtype=float)[-100:]
                               for s in ("right", "left")])
    assert np.all(contact == 1)  # both feet down the last 0.5 s
    # the torso leans toward the stance foot by design: measured max tilt 8.37 deg (AVX-512;
    # 8.37-8.58 deg over 20 random stops of a 1 m walk, 8.37-8.84 over seeds 1-5 with the
    # re-plan played at once), bound 15 deg = 1.7x (a fall: 30)
    assert summary["max_torso_tilt_deg"] < 15.0


def test_a_walks_summary_fields_are_written_once(tmp_path, model):
    """summary.json's fields every run has are the session's alone: the walk's own fields
    repeat none of them (main wrote ``interrupt_stop`` from both, round 15's review)."""
    from hubo_cli.control.loop import LoopResult
    from hubo_cli.experiments.walk import WalkResult
    from hubo_cli.session import RunSetup, common_summary

    common = common_summary(RunSetup(command="walk", model=model), None,
                            LoopResult("interrupted", 1, DT, interrupt_stop="stood"), [],
                            tmp_path)
    walked = WalkResult(
        fell=False, stopped_s=None, stood=True, shifts=0, touchdowns_early=0, liftoff_waits=0,
        landing_waits=0, reaims=0, final_error_mm=1.0, final_error_deg=0.1,
        estimated_final_error_mm=1.0, estimated_final_error_deg=0.1, steps=2,
        average_speed_m_s=None, zmp_inside_fraction=1.0, walking_s=1.0, ended="interrupted",
        estop_events=0, footsteps=[], gait="normal", run_dir=tmp_path, interrupt_stop="stood")
    assert common["interrupt_stop"] == "stood"
    assert set(walked.summary()).isdisjoint(common)


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_stop_late_in_a_swing_comes_to_rest_in_the_held_stance(pushed_walks):
    """hubo walk --to 1.0 0 0 stopped by the operator 0.52 s into the third step's 0.7 s swing
    (tools/walk_disturbances.py's seed 8): the step lands and the stance comes to rest. With
    the stabilizer's torso offset still integrating the CoM's error after the stop, the robot
    rocked on its sole edges and was still rocking when the run ended 1 s into the hold."""
    from hubo_cli.control.log import load_log

    result = pushed_walks("stop at 3.418")
    assert result.fell is False and result.stood is True
    log = load_log(result.run_dir / "log.parquet")
    rows = np.isfinite(np.asarray(log["estop_mode_code"], dtype=float))
    roll, pitch = (np.asarray(log[f"torso_{axis}_rad"], dtype=float)[rows][-100:]
                   for axis in ("roll", "pitch"))
    tilt_deg = np.degrees(np.arccos(np.cos(roll) * np.cos(pitch)))
    # the torso's tilt over the run's last 0.5 s: measured 0.43-0.43 deg on both CPU paths
    # (the offset integrating on: 2.48-5.97 deg AVX-512, 2.41-5.57 portable); bounds 1.5 deg
    # (3.5x) and a range of 1 deg (measured 0.00; 3.2-3.5 while rocking)
    assert tilt_deg.max() < 1.5 and np.ptp(tilt_deg) < 1.0


@pytest.mark.parametrize("args, words", [
    (["--push", "nan"], "--push must be a force"),
    (["--push", "-5"], "--push must be a force"),
    (["--push", "1e9"], "--push must be a force"),
    (["--push", "100", "--push-at", "nan"], "--push-at must be a time"),
    (["--push", "100", "--push-at", "-1"], "--push-at must be a time"),
    (["--stop-at", "inf"], "--stop-at must be a time"),
    (["--stop-at", "-0.1"], "--stop-at must be a time"),
    (["--push", "100", "--driver", "hardware", "--arm"], "--push needs the simulator"),
])
def test_hubo_walk_refuses_a_bad_disturbance_clearly(tmp_path, args, words):
    from click.testing import CliRunner

    from hubo_cli.cli.main import main

    result = CliRunner().invoke(main, ["walk", "--to", "1", "0", "0", *args,
                                       "--out", str(tmp_path / "run")])
    assert result.exit_code == 2, result.output
    assert words in result.output and "Traceback" not in result.output
    assert not (tmp_path / "run").exists()  # refused before anything ran


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_push_from_the_front_is_caught_by_the_capture_point_stop(pushed_walks):
    """hubo walk --to 1.0 0 0 --push 100 --push-direction backward --push-at 4.84 (seed 1 of
    tools/walk_disturbances.py): the push comes in a double support; the capture point moves
    the next landing back, its monitor stops the walk, the step finishes and the robot stands."""
    result = pushed_walks("front 4.841")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    assert summary["estop_events"][0]["sources"] == ["capture-point"]
    # measured max tilt 10.2 deg (AVX-512; 12.9 deg with the footsteps left as planned),
    # bound 19.5 deg = 1.5x the larger (a fall: 30)
    assert summary["max_torso_tilt_deg"] < 19.5


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.parametrize("at_s", [1.88999, 5.26526])  # tools/walk_disturbances.py seeds 11 and 16
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_push_from_the_front_mid_walk_moves_the_landing_at_once(pushed_walks, at_s):
    """hubo walk --to 1.0 0 0 pushed from the front (100 N, 0.2 s) in the first step's
    double support (seed 11) and in the fifth step's swing (seed 16): the capture point moves
    the landing from the period it is decided in, the walk stops and stands. Both fell while
    the re-plan took effect 0.2-0.4 s late (the first shift then came 0.57 s after the push on
    seed 11, none on seed 16)."""
    result = pushed_walks(f"front {at_s}")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    assert result.shifts >= 1
    # measured max tilt 12.2 / 11.1 deg (AVX-512); the 10 caught pushes of the 20-seed sweep
    # peaked at 10.5-16.1 deg: bound 25 deg = 1.55x the sweep's worst (a fall: 30)
    assert summary["max_torso_tilt_deg"] < 25.0


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_stops_last_landing_after_a_push_from_the_front_holds_the_capture_point(pushed_walks):
    """hubo walk --to 2.0 0 0 pushed from the front (100 N, 0.2 s) at 1.075 s, in the first
    step's swing (tools/walk_disturbances.py's seed 53): the monitor stops the walk past the
    point where the swing is abandoned, and the landing is taken back to where its heel lies
    behind the capture point. Moved by the error alone (main before round 36) it landed
    beside the stance foot, the capture point 60-80 mm behind both heels, and the robot
    tipped over backward a second later."""
    from hubo_cli.control.log import load_log

    result = pushed_walks("2 m front 1.075")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    # the stop's landing: measured 67 mm behind the stance foot on both CPU paths (3 mm
    # ahead before); bound 30 mm behind
    assert [step["x_m"] for step in result.footsteps] == [pytest.approx(-0.067, abs=0.037)]
    log = load_log(result.run_dir / "log.parquet")
    # standing, the capture point inside the monitor's polygon over the run's last 0.5 s
    # (measured at most 62 mm inside; main before round 36: 60-300 mm outside, falling)
    assert np.nanmax(np.asarray(log["cp_outside_m"], dtype=float)[-100:]) < 0.0
    # measured max tilt 12.5 deg (AVX-512), bound 19 deg = 1.5x (a fall: 30)
    assert summary["max_torso_tilt_deg"] < 19.0


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_push_from_the_front_early_in_a_swing_puts_the_rear_foot_back_down(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed from the front (100 N, 0.2 s) at 1.900 s, as the rear
    (right) foot lifts off for the first step (seed 11's moment 10 ms later): the landing that
    would capture the body lies behind that foot, so its swing is abandoned and the foot put
    back down where it is; the walk stops and stands. Swinging on (main before round 9) it
    fell (docs/history/walking.md, round 9)."""
    from hubo_cli.control.log import load_log

    at_s = 1.900
    result = pushed_walks("front 1.9")
    assert result.fell is False and result.stood is True
    log = load_log(result.run_dir / "log.parquet")
    t_s = np.asarray(log["t_s"], dtype=float)
    planned = np.asarray(log["planned_right_foot_contact_flag"], dtype=float)
    down_s = t_s[(t_s > at_s) & (planned == 1)][0] - at_s
    # measured: planned down again 0.220 s (AVX-512) / 0.225 s (portable) after the push,
    # the planned landing 0.71 s after it: bound 0.45 s, 2.0x the measured and 0.26 s short
    # of the landing
    assert down_s < 0.45


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_rear_foot_put_back_down_is_not_held_in_the_air(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed from the front (100 N, 0.2 s) 36 ms after the third
    step's lift-off (the phase of the 2 m walk's pushed seed 1 of tools/walk_disturbances.py):
    the swing is abandoned and the rear foot put back down; its landing's weight transfer
    does not wait for it. Waiting (main before round 22), the timeline held at the landing's
    first row held the foot in the air while the body tipped back over the stance heel:
    12.2 deg here, and the 2 m walk fell (docs/history/walking.md, round 22)."""
    result = pushed_walks("front 2.936")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    assert result.landing_waits == 0
    # measured max tilt 8.97 / 8.93 deg (AVX-512 / portable; 8.4-9.5 deg pushed so 36 ms
    # after each of the walk's lift-offs, AVX-512); waiting, 12.16 / 12.15 deg (10.7-14.1 at
    # those lift-offs, AVX-512): bound 10.5 deg
    assert summary["max_torso_tilt_deg"] < 10.5


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_side_push_that_puts_the_swing_foot_down_ends_the_swing_there(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed 100 N for 0.2 s from the left in the fourth step's
    swing (right foot swinging; seed 19 of tools/walk_disturbances.py): the swing foot is
    pushed onto the floor 0.17 s later; the swing ends there (the estimate's sole loaded, the
    step lands where it stands: the plan puts that foot down within a period), and the robot
    does not fall. It fell while the pattern lifted that foot again under the robot's weight.
    What comes after is not this test's: on main before round 13's slip turn the floor reach
    stopped the walk at the next landing (1 early touchdown); with the estimate seeing the
    pushed stance sole's twist the roll stays smaller, the walk goes on a step and the
    monitor's stop's own swing is put down early too (2; docs/history/walking.md, round 13);
    with round 15's hop wait (that landing's foot off the floor again, the weight transfer
    held 0.025-0.05 s) the walk goes on to its goal unstopped."""
    from hubo_cli.control.log import load_log

    at_s = 4.13692
    result = pushed_walks("from the left 4.13692")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and (result.stood is True or result.stopped_s is None)
    assert result.touchdowns_early >= 1
    log = load_log(result.run_dir / "log.parquet")
    t = np.asarray(log["t_s"], dtype=float)
    after = t > at_s
    touched = np.asarray(log["right_foot_contact_flag"], dtype=float)[after] == 1
    planned = np.asarray(log["planned_right_foot_contact_flag"], dtype=float)[after] == 1
    down = int(np.argmax(touched))  # the pushed swing foot's touchdown
    # measured: at 4.310 s, 0.173 s after the push, the plan's foot down 5 ms (one period)
    # later, on both paths; swung on, it stays up until the planned landing. Bounds: down
    # within 0.4 s of the push (the swing), the plan within 25 ms (5 periods)
    assert touched[down] and t[after][down] - at_s < 0.4 and not planned[:down].any()
    assert t[after][down + int(np.argmax(planned[down:]))] - t[after][down] < 0.025
    # measured max tilt 8.6 deg (main, AVX-512), 10.0 (AVX-512: 2 early touchdowns, stopped
    # at 5.895 s) and 12.7 (portable: 1, stopped at 5.315 s as main); the six pushes the rule
    # caught (seeds 2, 5, 8, 17, 19, 20) peaked at 8.4-11.9 deg: bound 25 deg = 2.0x the
    # worst (a fall: 30). Round 15 (the hop wait, unstopped): 11.7 deg AVX-512, 10.5 portable
    assert summary["max_torso_tilt_deg"] < 25.0


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_swing_foot_carried_back_by_a_tipping_body_still_lands_flat(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed from the front (100 N, 0.2 s) in the last step's swing,
    right foot in the air (seed 4 of tools/walk_disturbances.py): the body tips back over the
    stance heel. The swing leg is pitched at its hip against the torso's estimated pitch, so
    the foot lands flat where the capture point moved it and the walk stops standing. With the
    foot fixed in the torso's frame it came down 7 deg toe-up on its heel, bounced and fell.
    Both soles loaded, the turn goes back: the stop's stance ends on both soles, flat, with the
    torso at its planned pitch (held, the turn held the torso 0.16 rad back and the left sole
    7.6 deg toe-up on its heel to the end)."""
    from hubo_cli.control.log import load_log

    at_s = 8.16153
    result = pushed_walks("front 8.16153")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    # measured max tilt 15.1 deg (AVX-512) and 15.0 (portable path); a fall: 30; bound 25
    assert summary["max_torso_tilt_deg"] < 25.0
    log = load_log(result.run_dir / "log.parquet")
    t = np.asarray(log["t_s"], dtype=float)
    after = t > at_s
    level = np.asarray(log["walk.right_level_rad"], dtype=float)[after]
    contact = np.asarray(log["right_foot_contact_flag"], dtype=float)[after]
    pitch = np.asarray(log["walk.right_angle_rad"], dtype=float)[after]
    landed = int(np.argmax(contact == 1))
    # pitched in the air: measured 0.156-0.157 rad before the landing on both CPU paths
    assert contact[landed] == 1 and np.max(np.abs(level[:landed])) > 0.08
    # the estimated sole's pitch as it touches down: measured -0.0345 rad on both CPU paths
    # levelled, -0.123 (7 deg toe-up) without: bound 0.07 rad, 2x the first
    assert abs(pitch[landed]) < 0.07
    end = t > t[-1] - 0.5  # the stop's stance, held

    def last(name: str) -> np.ndarray:
        return np.abs(np.asarray(log[name], dtype=float)[end])

    assert np.all(last("walk.right_level_rad") == 0) and np.all(last("walk.left_level_rad") == 0)
    # measured at most 1.8 mrad (AVX-512) / 1.4 (portable); with the turn held to the end:
    # the left sole 140 mrad toe-up, the torso 163 mrad back. Bound 30 mrad (1.7 deg)
    for name in ("walk.right_angle_rad", "walk.left_angle_rad", "walk.pitch_error_rad"):
        assert last(name).max() < 0.03, name
    # both feet carry it: measured at least 111 N (AVX-512) / 145 N (portable): bound 50 N
    assert min(last("right_foot_fz_n").min(), last("left_foot_fz_n").min()) > 50.0


@pytest.mark.parametrize("rows_per_slice", [1, 7, 40, 10_000])
def test_a_sliced_solution_is_the_whole_one(walk_pattern, rows_per_slice):
    """The re-plan's work spread over periods (a slice of rows each) makes exactly the joints
    and corrected CoM of the solution in one go."""
    from hubo_cli.walking.body import WalkingBody, run_slices, walking_posture

    params, walking, start, steps, gait = walk_pattern
    q0, T0 = walking_posture(walking, params.step_width_m, params.crouch_m)
    args = (gait, 0.0, params.preview_s, params.zmp_weight, params.jerk_weight)
    lean = params.lean_rad_per_m
    whole_gait, whole = WalkingBody(walking, q0, T0, lean).solve_corrected(*args)
    sliced_gait, sliced = run_slices(WalkingBody(walking, q0, T0, lean).solve_corrected_slices(
        *args, None, rows_per_slice))
    assert np.array_equal(sliced.q_rad, whole.q_rad)
    assert np.array_equal(sliced_gait.com.com_m, whole_gait.com.com_m)


REPLAN_REVIEW = (
    "open (review): a re-plan's rest seeded from stale joints kinks at the hand-over (the "
    "limiter clamps it). Iterating the first row's CoM offset until it settles removes the "
    "kink but flipped a push to a fall on the portable CPU path (round 3: the front push the "
    "capture-point stop catches; round 26: the 2 m walk's push of seed 20); "
    "docs/history/walking.md")


def _offline_walk(goal_m, periods, stop_k=None, cp_offset_m=(0.0, 0.0), offset_k=(0, 0),
                  each=None, ankles_fz_n=190.0, drift_m=(0.0, 0.0), double_only=False,
                  contact=None, gait=DEFAULT_GAIT, cp_of=None):
    """A walk's target played offline (no physics): the estimate is where the pattern is
    (its capture point moved by ``cp_offset_m`` over periods ``offset_k``, ``double_only``: in
    its double supports only; after the first plan, its soles and capture point ``drift_m``
    behind the pattern's: world x, y; its contacts the pattern's or ``contact(k)`` where that
    is not None), each ankle's F/T sensor reads ``ankles_fz_n`` (one value, or right and
    left, or ``ankles_fz_n(k, target)`` giving them), the operator's stop from ``stop_k``;
    ``each(k, target, before)`` runs after every period (``before``: the plan and the pending
    re-plan before it). Returns the target, its commands and the periods a new pattern was
    installed. ``gait``: the robot file's gait walked. ``cp_of(k)``: the estimated capture
    point at period ``k`` (world x, y) instead of the pattern's."""
    from hubo_cli.estimation.keys import (
        CAPTURE_POINT_WORLD,
        COM_VELOCITY_WORLD,
        CONTACT,
        T_WORLD_SOLES,
    )
    from hubo_cli.walking.body import poses_of_rows

    _, q0, _, target, store = standing_walk(goal_m, None, gait)
    store[COM_VELOCITY_WORLD] = np.zeros(3)
    fz_of = ankles_fz_n if callable(ankles_fz_n) else None
    fz_n = np.broadcast_to(np.asarray(0.0 if fz_of else ankles_fz_n, dtype=float), (2,))
    state = RobotState(0.0, q0, np.zeros_like(q0),
                       ft={name: np.array([0.0, 0.0, fz, 0.0, 0.0, 0.0])
                           for name, fz in zip(ANKLE_SENSORS, fz_n, strict=True)})
    commands, installs = [], []
    for k in range(periods):
        if target.gait is None:
            store[CAPTURE_POINT_WORLD] = store[COM_WORLD][:2]
        else:  # the estimate where the pattern is, the capture point moved as asked
            j = min(target.k, target.gait.n - 1)
            com = target.gait.com
            offset = offset_k[0] <= k < offset_k[1] and (
                not double_only or all(target._rows["support"][j]))
            store[CAPTURE_POINT_WORLD] = com.com_m[j] + com.com_velocity_m_s[j] / target._omega \
                + (np.asarray(cp_offset_m) if offset else 0.0) - np.asarray(drift_m)
            if cp_of is not None:
                store[CAPTURE_POINT_WORLD] = np.asarray(cp_of(k), dtype=float)
            store[T_WORLD_SOLES] = poses_of_rows(np.array([target._rows[side][j]
                                                           for side in ("right", "left")]))
            store[T_WORLD_SOLES][:, :2, 3] -= np.asarray(drift_m)
            store[CONTACT] = (contact is not None and contact(k)) \
                or tuple(target._rows["support"][j])  # (no swing foot pushed down)
        store[STOP_MODE] = "finish" if stop_k is not None and k >= stop_k else "release"
        if fz_of is not None:
            for name, fz in zip(ANKLE_SENSORS, fz_of(k, target), strict=True):
                state.ft[name][2] = fz
        before = target.plan, target._pending
        q, info = target(k * DT, state)
        commands.append(np.array(q, dtype=float))
        if target.plan is not before[0]:
            installs.append(k)
        if each is not None:
            each(k, target, before)
        if info["done"]:
            break
    return target, np.array(commands), installs


@pytest.mark.parametrize("ankles_fz_n", [0.0, 30.0])
def test_a_walk_whose_soles_read_no_load_waits_then_ends_with_a_device_error(ankles_fz_n):
    """Ankle sensors reading zero (or the robot held in the air): the first lift-off waits
    (the soles would carry under a fifth of the weight), then the walk ends in its double
    support with one line naming the sensors, not a step into the air."""
    from hubo_cli.errors import DeviceError
    from hubo_cli.walking.target import LIFTOFF_WAIT_MAX_S

    lifted = []

    def each(k, target, before):
        lifted.append(not all(target._rows["support"][min(target.k, target.gait.n - 1)]))

    with pytest.raises(DeviceError, match="ankle force sensors read") as raised:
        _offline_walk((0.3, 0.0, 0.0), 1000, each=each, ankles_fz_n=ankles_fz_n)
    assert "\n" not in str(raised.value) and raised.value.hint
    assert not any(lifted)  # no foot ever planned up
    # (the first lift-off at 0.9 s of the default gait, then the wait)
    assert len(lifted) * DT == pytest.approx(0.9 + LIFTOFF_WAIT_MAX_S, abs=0.15)


@pytest.mark.parametrize("stop_k", [150, 300, 430])  # the lead-in, a double support, a swing
def test_a_stop_re_plans_at_once_a_bounded_share_each_period(monkeypatch, stop_k):
    """The stop's re-plan acts in the period the stop comes in and never stalls the loop:
    each period solves the legs for at most PREFIX_ROWS_PER_PERIOD rows of its first part
    and REPLAN_ROWS_PER_PERIOD of the rest (twice each, the CoM offset's iteration; and once
    more the landing's row when decided) and the multi-body ZMP of at most
    REPLAN_ROWS_PER_PERIOD rows; the joints never jump where the first part hands over to the
    rest; the walk stands in double support at its end. (Counted work, not time: a time
    would measure the machine's load.)"""
    import pinocchio as pin

    from hubo_cli.walking import body as body_module
    from hubo_cli.walking.target import PREFIX_ROWS_PER_PERIOD, REPLAN_ROWS_PER_PERIOD

    counts = {"legs": 0, "momentum": 0}
    solve_legs, momentum = body_module._solve_legs, pin.computeCentroidalMomentum

    def counted_legs(*args):
        counts["legs"] += 1
        return solve_legs(*args)

    def counted_momentum(*args):
        counts["momentum"] += 1
        return momentum(*args)

    monkeypatch.setattr(body_module, "_solve_legs", counted_legs)
    monkeypatch.setattr(pin, "computeCentroidalMomentum", counted_momentum)
    per_period, installed_k, last = [], [], dict(counts)

    def each(k, target, before):
        nonlocal last
        if k == stop_k:
            assert target.plan is not before[0]  # played from this period
        if k > 0:
            per_period.append((counts["legs"] - last["legs"],
                               counts["momentum"] - last["momentum"]))
        last = dict(counts)
        if before[1] is not None and target._pending is None:
            installed_k.append(k)

    target, commands, _ = _offline_walk((0.3, 0.0, 0.0), 3000, stop_k=stop_k, each=each)
    assert target.phase == "stood" and not target.stop_failed
    assert installed_k and installed_k[0] > stop_k  # the rest, after it was computed
    legs, moments = np.array(per_period).T
    assert legs.max() <= 2 * (PREFIX_ROWS_PER_PERIOD + REPLAN_ROWS_PER_PERIOD + 1), legs.max()
    assert moments.max() <= REPLAN_ROWS_PER_PERIOD, moments.max()
    # the pattern's joints move at most 2.1 rad/s (the walking limit set: 2.6 rad/s)
    assert np.abs(np.diff(commands, axis=0)).max() <= 2.6 * DT, np.abs(np.diff(commands,
                                                                                axis=0)).max()
    assert np.all(target.gait.support[-1])  # both feet down at the end


def test_a_capture_point_beyond_the_steps_reach_re_plans_once_not_every_period():
    """A capture point 0.4 m ahead of the pattern's for a second (beyond what a step may
    move a landing): the landing moves to its limit once a step, and no re-plan is decided
    while the limits hold it there (review: one every period, 109 in a row, before)."""
    target, _, installs = _offline_walk((0.6, 0.0, 0.0), 1200, cp_offset_m=(0.4, 0.0),
                                        offset_k=(400, 600))
    during = [k for k in installs if 400 <= k < 600]
    assert 1 <= len(during) <= 4, installs  # measured: 3 (400, 470, 580)


def test_a_landing_moved_for_a_capture_point_ahead_of_the_first_plan_keeps_its_move():
    """The estimated capture point 80 mm ahead of the pattern as first planned through the
    first swing (periods 400-600: a robot that keeps its own way, not the re-planned
    pattern's): the landing moves 60 mm forward (the error beyond the 20 mm margin) once and
    keeps that move to its landing. Judged against the re-planned pattern, whose capture point
    the move itself carries forward, the error shrank and the landing moved back to 40 mm at
    period 479 (main before round 32; in a fast walk such moves turned and grew until the robot
    fell: docs/history/walking.md, round 32)."""
    planned = {}

    def record(k, target, before):
        j = min(target.k, target.gait.n - 1)
        com = target.gait.com
        planned[k + 1] = com.com_m[j] + com.com_velocity_m_s[j] / target._omega

    _offline_walk((0.6, 0.0, 0.0), 620, each=record)
    shifts = {}

    def each(k, target, before):
        shifts[k] = (target._shift[0], float(target._shift[1][0]))

    def ahead(k):
        return planned.get(k, planned[max(planned)]) + (
            np.array((0.08, 0.0)) if 400 <= k < 600 else 0.0)

    _offline_walk((0.6, 0.0, 0.0), 580, cp_of=ahead, each=each)
    first_swing = [shift for k, (step, shift) in shifts.items() if step == 1 and k >= 400]
    assert len(first_swing) >= 150 and first_swing[0] == pytest.approx(0.06, abs=1e-6)
    assert np.ptp(first_swing) < 1e-9  # moved once, never back


def test_a_landing_move_only_grows_in_its_swing():
    """The capture point's wish for a landing already moved in its swing: further the same
    way is taken, back or the other way is not; an axis not yet moved takes the wish."""
    from hubo_cli.walking.target import _not_turned_back

    applied = np.array((0.04, 0.0))
    for wanted, kept in (((0.06, 0.01), (0.06, 0.01)), ((0.02, -0.03), (0.04, -0.03)),
                         ((-0.05, 0.0), (0.04, 0.0))):
        assert np.allclose(_not_turned_back(np.array(wanted), applied), kept)
    applied = np.array((-0.03, 0.02))
    assert np.allclose(_not_turned_back(np.array((0.01, 0.05)), applied), (-0.03, 0.05))
    assert np.allclose(_not_turned_back(np.array((-0.07, -0.01)), applied), (-0.07, 0.02))


@pytest.mark.xfail(strict=True, reason=REPLAN_REVIEW)
def test_re_plans_within_one_first_part_hand_over_without_a_kink():
    """Landings moved again while a re-plan's first rows still play (a capture point 0.12 m
    ahead over a second): where each pattern takes over, the joints' second difference stays
    near the pattern's own (review: 0.020 rad at the hand-over, the rest's first row solved
    from stale joints with two CoM-offset iterations; 0.0011 with the first row's offset
    iterated until it settles). Bound 0.005 rad: 4.5x the measured."""
    _, commands, installs = _offline_walk((0.6, 0.0, 0.0), 1200, cp_offset_m=(0.12, 0.0),
                                          offset_k=(400, 600))
    assert len(installs) >= 4, installs
    kink = np.abs(commands[2:] - 2 * commands[1:-1] + commands[:-2]).max(axis=1)
    assert kink.max() <= 0.005, (kink.max(), int(kink.argmax()) + 1, installs)


def test_a_landing_moved_mid_swing_keeps_the_monitors_support_on_the_floor(model):
    """The capture point 6 cm ahead of the pattern's for 25 ms while the first swing foot is
    16 mm up moves that landing (a re-plan from a row with the foot in the air); back on the
    pattern, the capture-point monitor never flags: its planned support has both soles on the
    estimated floor the walk was planned on. (With the re-plan's first row's heights the
    monitor dropped the landing as a lifted sole and judged the capture point against the
    stance sole alone: it flagged from the re-plan on, and stopped fast walks.)"""
    from hubo_cli.control.capture_point import CapturePointMonitor
    from hubo_cli.control.phase import SUPPORT_PLAN

    walking = load_model("as-built", "walking")
    monitor = CapturePointMonitor(walking, DT)
    flags, floors = [], []

    def each(k, target, before):
        store = target.store
        floors.append(store[SUPPORT_PLAN].T_world_soles[:, 2, 3] - target._basis[2])
        monitor.measure(RobotState(k * DT, target.q_start, np.zeros_like(target.q_start)),
                        store)
        flags.append(monitor.flag)

    # (the first swing: periods 180-320 of the default gait; 230: tau 0.36, the foot 16 mm up)
    target, _, installs = _offline_walk((0.6, 0.0, 0.0), 700, cp_offset_m=(0.06, 0.0),
                                        offset_k=(230, 235), each=each)
    assert target.shifts >= 1 and any(230 <= k < 235 for k in installs), installs
    assert np.all(np.array(floors) == 0.0)
    assert not any(flags[240:]), np.flatnonzero(flags)


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_foot_does_not_lift_off_while_the_robot_bounces(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed 100 N for 0.2 s from the right in the third step's swing
    (seed 20 of tools/walk_disturbances.py, at 3.05658 s until round 23): the left foot lands
    hard and the robot bounces, its ankle sensors reading a median 33-37 N of its 380 N (both
    CPU paths) over the 0.1 s before the right foot's planned lift-off at 3.54 s, 2x under the
    guard's 76 N. Lifting it then left the robot on no foot, and it fell over the left one's
    edge. The timeline waits at that lift-off (65 ms) until the soles carry the body again; the
    capture-point monitor stops the walk and it stands. Since round 15 the timeline may wait
    earlier, at the hop itself (:meth:`WalkTarget._unloaded_landing`). Round 23: with the ankle
    sensors reading the period's mean, the push at 3.05658 s no longer makes the robot bounce
    (it walks on to the goal); pushed at 3.14 s it bounces, a landing and the lift-off wait and
    the walk stops at 3.67 s and stands, tilting 9.2 / 9.0 deg (AVX-512 / portable). Found by
    a sweep of push moments (docs/history/walking.md, round 23's second pass): the test's
    outcome (a wait, a stop, standing) holds pushed at 3.13-3.18 s on both paths, the lift-off
    itself waiting from 3.13 to 3.14 s (3.145 s AVX-512). Round 32: with the landing's moves
    judged against the pattern before them, the walk pushed at 3.14 s (AVX-512) or 3.13 s (both)
    lands on its moved landings without a lift-off wait and walks on to the goal; the outcome
    with the lift-off wait holds pushed at 3.15, 3.155 and 3.16 s on both paths (3.14 s
    portable), so the push is at 3.155 s: waits, a stop at 3.68 / 3.685 s, standing, 8.9 / 8.8
    deg."""
    result = pushed_walks("from the right 3.155")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    # since round 15 the hop after that landing waits first (a landing wait) and the lift-off
    # need not
    assert result.liftoff_waits + result.landing_waits >= 1
    assert result.fell is False and result.stood is True
    # measured max tilt 13.8 deg (AVX-512) and 13.4 (portable); a fall: 30; bound 25 (1.8x).
    # Round 15: 25.5 deg AVX-512 (the hop wait puts the lift-off in a single support the hips
    # catch) and 12.7 portable: bound 28 deg (docs/history/walking.md, round 15; left open).
    # Round 23, pushed at 3.14 s: 9.2 / 9.0 deg (3.0x)
    assert summary["max_torso_tilt_deg"] < 28.0


@pytest.mark.physical
@pytest.mark.slow
@pytest.mark.xdist_group("pushed_walks")  # one worker walks the trunk once
def test_a_landing_waits_for_its_foot_after_a_push_just_before_it(pushed_walks):
    """hubo walk --to 1.0 0 0 pushed from the front (100 N, 0.2 s) at 7.559 s, 0.01 s before
    the left foot's landing (seed 13 of tools/walk_disturbances.py): the body tips back onto
    the right sole and the landed foot bounces off the floor. The monitor stops the walk and
    the double support's weight transfer waits in the periods that foot reads unloaded; it
    stands. Played
    on, the transfer moved the ZMP reference onto the foot in the air and the robot rolled
    over its outer edge (main before round 10: fell, stop 7.845 s)."""
    result = pushed_walks("front 7.558941")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.landing_waits >= 1
    assert result.fell is False and result.stood is True
    # measured max tilt 17.7 deg (AVX-512) and 16.5 (portable); a fall: 30; bound 25 (1.4x)
    assert summary["max_torso_tilt_deg"] < 25.0


@pytest.mark.physical
@pytest.mark.slow
def test_a_side_push_toward_the_stance_foot_is_caught_on_the_swing_foot(tmp_path, model):
    """hubo walk --to 0.3 0 0 pushed right (60 N, 0.2 s) at 1.285 s, mid-way through the
    first swing (the left foot's; the push comes toward the right, stance, foot): the body
    rolls onto the right sole's outer edge; the swing foot, turned back against that roll
    (:mod:`hubo_cli.walking.floor_reach`), stays over the floor and lands as the body rolls
    back, and the walk stops there and stands. Without it the foot, lifted with the body,
    came down after the rebound with the capture point at its outer edge (main before round
    11: fell at 50, 60 and 70 N, both CPU paths)."""
    from hubo_cli.control.log import load_log
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS
    from hubo_cli.experiments.walk import Disturbance, walk
    from hubo_cli.walking.floor_reach import REACH_STOP_RAD

    result = walk(model, (0.3, 0.0, 0.0), out=tmp_path / "run",
                  disturbances=[Disturbance(1.285, 60.0, PUSH_DIRECTIONS["right"])])
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    # measured max tilt 10.1 deg (AVX-512) and 10.3 deg (portable); 9.0-9.5 deg at 50 and 70 N
    # on both paths; a fall: 30; bound 15 deg (1.45x the larger at 60 N)
    assert summary["max_torso_tilt_deg"] < 15.0
    # the reach did it: the left foot turned beyond the stop's threshold (0.040 rad measured)
    log = load_log(result.run_dir / "log.parquet")
    assert np.nanmax(np.abs(log["walk.left_reach_rad"])) > REACH_STOP_RAD


@pytest.mark.physical
@pytest.mark.slow
def test_a_side_push_over_the_stance_soles_edge_is_caught_by_the_hips(tmp_path, model):
    """hubo walk --to 0.3 0 0 pushed left (90 N, 0.2 s) at 2.08 s, early in the second swing
    (the right foot's; the push comes toward the left, stance, foot): the capture point rushes
    at the left sole's outer edge, the momentum strategy starts (the swing hip roll abducting,
    then the stance one: :mod:`hubo_cli.walking.momentum`) and the walk stops and stands.
    Without it the capture point crosses the edge and the robot rolls over it (main before
    round 12: fell at 90 and 100 N, AVX-512)."""
    from hubo_cli.control.log import load_log
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS
    from hubo_cli.experiments.walk import Disturbance, walk

    result = walk(model, (0.3, 0.0, 0.0), out=tmp_path / "run",
                  disturbances=[Disturbance(2.08, 90.0, PUSH_DIRECTIONS["left"])])
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False and result.stood is True
    # measured max tilt 25.1 deg on both paths (25.3 / 25.2 before the profile braked a period
    # ahead); a fall: 30; bound 28.5 deg
    assert summary["max_torso_tilt_deg"] < 28.5
    log = load_log(result.run_dir / "log.parquet")  # the hips did it (0.25 rad each)
    assert np.nanmax(np.abs(log["walk.right_momentum_rad"])) > 0.2
    assert np.nanmax(np.abs(log["walk.left_momentum_rad"])) > 0.2


@pytest.mark.parametrize("early", [True, False])
def test_a_hop_after_a_landing_pushed_down_early_holds_the_weight_transfer(early):
    """A walk nobody stopped, the estimated capture point 80 mm off the pattern's sideways from
    period 470 on (a 70-90 N side push as the robot hops: 63-118 mm, seeds 5 and 20, under
    LANDING_WALK_PUSHED_M). ``early``: the swinging (right) foot is measured down at 470,
    pushed onto the floor early; it carries for 0.15 s, then reads 0 N for 0.1 s (the robot
    off its soles, docs/history/walking.md, round 15): the landing, made, is watched till the
    lift-off, the timeline waits while the foot is off the floor (one landing wait, 0.1 s),
    and the walk goes on, unstopped. Main took the landing as made after LANDING_CARRIED_S
    and played the weight transfer on in the air (seed 20 fell at 70-90 N). Not pushed down
    early (the foot lands when planned, the same readings from its landing on): no landing
    wait, as before; the next lift-off, due while that foot is off the floor with the capture
    point off the pattern's, waits and stops the walk (round 17's lift-off rule)."""
    landed, waited = [], []

    def fz(k, target):
        if not landed and target._played_support is not None and k > 460 \
                and all(target._played_support):
            landed.append(k)  # the right foot's landing played
        hop = bool(landed) and landed[0] + 30 <= k < landed[0] + 50
        return (0.0 if hop else 380.0), 380.0

    target, _, _ = _offline_walk(  # (through the landing's double support and the lift-off)
        (0.3, 0.0, 0.0), 640, cp_offset_m=(0.0, 0.08), offset_k=(470, 3000),
        ankles_fz_n=fz,
        contact=lambda k: (True, True) if early and 470 <= k < 480 else None,
        each=lambda k, target, before: waited.append(target._landing_waited_s))
    assert target.touchdowns_early == int(early)
    assert landed  # (the hop played in the landing's double support)
    if early:
        assert target.stopped_s is None
        assert not all(target._played_support)  # the next step has lifted off
        assert target.landing_waits == 1
        assert max(waited) == pytest.approx(0.1, abs=0.011)
    else:
        assert target.landing_waits == 0
        assert target.liftoff_waits == 1 and target.stopped_s is not None


@pytest.mark.parametrize("pushed", [True, False])
def test_a_lift_off_onto_a_landed_foot_that_does_not_carry_stops_a_pushed_walk(pushed):
    """A walk nobody stopped: the right foot lands on time (after period 460) and reads 0 N
    through its double support while the left carries the body; at the left foot's lift-off
    the estimated capture point is 40 mm off the pattern's sideways (``pushed``: a push the
    estimate sees; pushed seed 40 at 80 N, 15-37 mm an axis, fell lifting off onto the foot
    in the air, docs/history/walking.md, round 17) and the lift-off waits and the walk stops
    there (main lifted the left foot and the body came down on the right one). Unpushed (the
    capture point on the pattern's: perturbed robots' bounced landings, at most 15.5 mm an
    axis at such lift-offs), the left foot lifts off as on main."""
    landed = []

    def fz(k, target):
        if not landed and target._played_support is not None and k > 460 \
                and all(target._played_support):
            landed.append(k)  # the right foot's landing played
        return (0.0 if landed else 380.0), (760.0 if landed else 380.0)

    target, _, _ = _offline_walk(
        (0.3, 0.0, 0.0), 700, cp_offset_m=(0.0, 0.04 if pushed else 0.0),
        offset_k=(landed_k := 465, 3000), ankles_fz_n=fz)
    assert landed and landed[0] > landed_k
    if pushed:
        assert target.liftoff_waits == 1 and target.stopped_s is not None
    else:
        assert target.liftoff_waits == 0 and target.stopped_s is None
        assert not all(target._played_support)  # the left foot has lifted off


def _cart_zmp_y(walk):
    """``each`` for :func:`_offline_walk`: appends to ``walk`` the played cart-table pattern's
    lateral ZMP (world y, m) and the step and support of its row."""
    def each(k, target, before):
        j = min(target.k, target.gait.n - 1)
        walk.append((target._cart.com.zmp_m[min(target.k, target._cart.n - 1), 1],
                     target._rows["step"][j], all(target._rows["support"][j])))
    return each


def test_a_stop_in_mid_swing_lets_the_landing_foot_take_the_weight():
    """An operator's stop in mid-swing (no push): the foot lands where it was going and takes
    the weight as walking would before the CoM comes to rest between the feet, so the
    pattern's ZMP stays where the walk's own goes (over the soles). Offline, a 1 m walk
    stopped 84 periods into its third step's swing. Before, the stop turned the CoM back at
    once: the ZMP reference went 384 mm out to the side (261 mm beyond the walk's), and on
    the simulated robot a 2 m walk's stop tipped over (docs/history/walking.md, round 24)."""
    walk, stopped = [], []
    target, _, _ = _offline_walk((1.0, 0.0, 0.0), 4000, each=_cart_zmp_y(walk))
    third_swing = next(k for k, (_, step, double) in enumerate(walk) if step == 2 and not double)
    stopped_target, _, _ = _offline_walk((1.0, 0.0, 0.0), 4000, stop_k=third_swing + 84,
                                         each=_cart_zmp_y(stopped))
    walk_y_m = max(abs(row[0]) for row in walk)
    stop_y_m = max(abs(row[0]) for row in stopped)
    sole_edge_y_m = target.params.step_width_m / 2 + target.model.feet.width_m / 2
    assert stop_y_m <= walk_y_m + 0.010
    assert stop_y_m <= sole_edge_y_m - 0.010
    assert stopped_target.phase == "stood" and len(stopped_target.steps) == 3


def test_a_pushed_stops_landing_waits_whichever_pattern_it_lands_in():
    """The landing wait (after a push, once the walk stops) keys on the rows played, not on
    the pattern's own rows: a stop whose rest is installed at the landing's period, and a
    swing foot measured down early (its pattern starts at the landing's double support), wait
    as a landing inside one pattern does. Offline: the landed (right) foot reads 0 N, the
    capture point 50 mm off the pattern's from the stop on (a pushed stop: the foot in the
    air keeps the capture point's landing). Before the review fix the
    landing at a pattern's row 0 did not wait (a stop at period 495 here; an early
    touchdown)."""
    from hubo_cli.walking.target import LANDING_WAIT_MAX_S

    at_install = 0
    for stop_k in range(490, 501):
        played = []
        target, _, installs = _offline_walk(
            (0.3, 0.0, 0.0), 3000, stop_k=stop_k, cp_offset_m=(0.0, 0.05),
            offset_k=(stop_k, 3000), ankles_fz_n=(0.0, 380.0),
            each=lambda k, target, before, played=played: played.append(
                all(target._played_support)))
        landing = next(k for k in range(stop_k, len(played)) if played[k] and not played[k - 1])
        at_install += landing in installs
        assert target.landing_waits == 1 and target.phase == "stood", stop_k
    assert at_install >= 1  # the case the fix is for is among them
    for early in (True, False):
        waited = []
        target, _, _ = _offline_walk(
            (0.3, 0.0, 0.0), 3000, stop_k=430, cp_offset_m=(0.0, 0.05), offset_k=(470, 3000),
            ankles_fz_n=(0.0, 380.0),
            contact=lambda k, early=early: (True, True) if early and 470 <= k < 480 else None,
            each=lambda k, target, before, waited=waited: waited.append(target._landing_waited_s))
        assert target.touchdowns_early == int(early)
        assert target.landing_waits == 1 and target.phase == "stood"
        assert max(waited) == pytest.approx(LANDING_WAIT_MAX_S)


def test_the_fast_gaits_landing_waits_once_it_stops_not_while_it_walks():
    """The fast gait, offline, its right sole reading 0 N and the capture point 50 mm off the
    pattern's throughout: walking on, no landing or lift-off waits and no stop (its own
    bounces and lag would set them off: the normal gait under the same readings waits at its
    first lift-off and stops); stopped in a swing, the landing waits for the foot (before
    round 24 the fast gait never waited, and a pushed landing bounced between the soles)."""
    pushed = {"cp_offset_m": (0.0, 0.05), "offset_k": (0, 3000), "ankles_fz_n": (0.0, 380.0),
              "gait": "fast"}
    walking, _, _ = _offline_walk((0.6, 0.0, 0.0), 3000, **pushed)
    assert walking.stopped_s is None and walking.phase == "walk"
    assert walking.landing_waits == walking.liftoff_waits == 0
    for stop_k in (300, 330, 360):
        stopped, _, _ = _offline_walk((0.6, 0.0, 0.0), 3000, stop_k=stop_k, **pushed)
        assert stopped.landing_waits == 1 and stopped.phase == "stood", stop_k


@pytest.mark.parametrize("drift_m", [(0.012, -0.009), (-0.015, 0.006), (0.005, 0.004)])
def test_the_last_landings_take_back_the_stance_soles_drift_in_the_walks_own_steps(
        monkeypatch, drift_m):
    """The estimate's soles standing ``drift_m`` off the pattern's from the walk's start (the
    soles' slips as the estimate sees them): the plan's last landings are re-aimed by as much
    at their lift-offs, so the estimated feet end on the goal with the planned steps (no
    correction walk needed), every step within the gait's limits, and the legs' commands move
    no more in a period than on the same walk without the drift. Without the re-aim the feet
    end ``drift_m`` off (the test can fail). A drift under ARRIVED_M, which needs no
    correction, is left as it is: the walk is the one without the re-aim."""
    from hubo_cli.walking import target as target_module
    from hubo_cli.walking.footsteps import within_limits

    goal = (0.6, 0.0, 0.0)
    drift = math.hypot(*drift_m)
    monkeypatch.setattr(target_module, "REAIM_STEPS", 0)
    unaimed, unaimed_commands, _ = _offline_walk(goal, 3000, drift_m=drift_m)
    assert unaimed.reaims == 0
    assert unaimed.final_error()[0] == pytest.approx(drift, abs=1e-4)
    monkeypatch.undo()
    walked, commands, _ = _offline_walk(goal, 3000, drift_m=drift_m)
    if drift < target_module.ARRIVED_M:
        assert walked.reaims == 0 and np.array_equal(commands, unaimed_commands)
        return
    plain, plain_commands, _ = _offline_walk(goal, 3000)
    assert walked.reaims >= 1
    assert len(walked.steps) == len(plain.steps)
    error_m, error_rad = walked.final_error()
    assert error_m <= 1e-4 and error_rad <= 1e-6, (error_m, error_rad)  # measured: 1e-17 m
    assert within_limits(walked.steps, *walked.start_feet, walked.params)
    legs = [i for i, name in enumerate(walked.model.joint_names) if name[1] in "HKA"]
    step = np.abs(np.diff(commands[:, legs], axis=0)).max()
    plain_step = np.abs(np.diff(plain_commands[:, legs], axis=0)).max()
    # measured: 0.00870 and 0.00837 rad against 0.00847 (one re-aim, the 3rd step's lift-off)
    assert step <= 1.05 * plain_step, (step, plain_step)


def test_a_plan_the_capture_point_moved_is_re_aimed_at_the_goal_in_its_last_steps(monkeypatch):
    """The estimated capture point 40 mm left of the pattern's through the first swing moves
    that landing and every later one 20 mm left (the capture point's footstep modification),
    then the robot follows the pattern again. In a gait that re-aims moved plans (the fast
    gait's, ``reaim_moved``) the plan's last REAIM_MOVED_STEPS landings are re-aimed at the
    goal, and the estimated feet end within ARRIVED_M of it in the planned steps, every step
    within the gait's limits. Before round 20 a moved plan was never re-aimed and the feet
    ended the move off (measured on main: no re-aim, 20 mm), and a correction walk followed
    (it cost the fast 2 m walks their 0.2 m/s)."""
    import walking_support

    from hubo_cli.walking import target as target_module
    from hubo_cli.walking.footsteps import plan_footsteps, within_limits

    class FastWalk(target_module.WalkTarget):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.reaim_moved = True

    monkeypatch.setattr(walking_support, "WalkTarget", FastWalk)
    walked, _, _ = _offline_walk((0.6, 0.0, 0.0), 3000, cp_offset_m=(0.0, 0.04),
                                 offset_k=(190, 300))
    planned = plan_footsteps(*walked.start_feet, walked.goal, walked.params)
    assert walked.shifts == 1 and walked.reaims >= 1
    assert len(walked.steps) == len(planned)
    left_m = max(step.y_m - plan.y_m for step, plan in zip(walked.steps, planned, strict=True))
    assert left_m >= 0.015  # the move (measured: 20 mm)
    assert walked.final_error()[0] < target_module.ARRIVED_M
    assert within_limits(walked.steps, *walked.start_feet, walked.params)


def test_a_plan_whose_closing_steps_lie_outside_the_gaits_limits_is_not_re_aimed(monkeypatch):
    """An approach ends at the working stance, narrower than the gait's lateral bound, so its
    closing steps are outside the limits the re-aim keeps; the re-aim does not move them
    unchecked (round 9's review: a drifting sole's re-aims put the soles 0.147 m apart, on
    0.13 m wide soles). The drift is left to the correction after the pattern."""
    import walking_support

    from hubo_cli.walking import target as target_module

    class ClosingWalk(target_module.WalkTarget):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, end_width_m=0.17686, **kwargs)  # the working stance's

    monkeypatch.setattr(walking_support, "WalkTarget", ClosingWalk)
    walked, _, _ = _offline_walk((0.5, 0.0, 0.0), 3000, drift_m=(0.0, -0.03))
    assert walked.reaims == 0
    assert walked.final_error()[0] == pytest.approx(0.03, abs=1e-4)  # the drift, as it was


def test_the_monitors_planned_support_stands_where_the_estimated_soles_stand():
    """The walk's first period made its plan; then the estimate's soles turned 0.1 rad and
    moved 22 mm together (a stance sole slipped round, seen by the gyro): the capture-point
    monitor's planned support turns and moves with them, as the fast gait has it (on main it
    stayed where the pattern put it, and the estimated capture point was judged against
    soles off the robot's own)."""
    from hubo_cli.control.phase import SUPPORT_PLAN
    from hubo_cli.estimation.keys import T_WORLD_SOLES

    _, q0, _, target, store = standing_walk((0.3, 0.0, 0.0), None)
    target.support_where_standing = True  # (the fast gait's)
    state = RobotState(0.0, q0, np.zeros_like(q0))
    target(0.0, state)
    planned = store[SUPPORT_PLAN].T_world_soles.copy()
    c, s = math.cos(0.1), math.sin(0.1)
    move = np.array([[c, -s, 0.0, 0.02], [s, c, 0.0, -0.01], [0.0, 0.0, 1.0, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])
    store[T_WORLD_SOLES] = move @ store[T_WORLD_SOLES]
    target(DT, state)
    np.testing.assert_allclose(store[SUPPORT_PLAN].T_world_soles, move @ planned, atol=1e-6)


def test_the_monitors_planned_support_does_not_jump_when_the_other_sole_takes_the_load():
    """Both soles planned down, the estimate's left sole 87 mm behind where the plan has it
    against the right (a landing short of its place): the planned support has each sole where
    the estimate has it, whichever carries more. On main it was laid from the more loaded
    sole alone (the pattern's frame) and moved 87 mm back when the load passed from the left
    sole to the right (portable seed 22's fast 2 m walk at its last landing: the capture point
    past the jumped hull's front line, a false stop; docs/history/walking.md, round 19)."""
    from hubo_cli.control.phase import SUPPORT_PLAN
    from hubo_cli.estimation.keys import T_WORLD_SOLES

    _, q0, _, target, store = standing_walk((0.3, 0.0, 0.0), None)
    target.support_where_standing = True  # (the fast gait's)
    state = RobotState(0.0, q0, np.zeros_like(q0))
    target(0.0, state)
    soles = store[T_WORLD_SOLES].copy()
    soles[1, 0, 3] -= 0.087
    store[T_WORLD_SOLES] = soles
    supports = []
    for k, loads_n in enumerate(((100.0, 300.0), (300.0, 100.0)), start=1):
        store[WRENCHES] = store[WRENCHES] | {
            sensor: np.array([0.0, 0.0, fz_n, 0.0, 0.0, 0.0])
            for sensor, fz_n in zip(ANKLE_SENSORS, loads_n, strict=True)}
        target(k * DT, state)
        assert all(target._rows["support"][target.k - 1])  # both planned down
        supports.append(store[SUPPORT_PLAN].T_world_soles.copy())
    np.testing.assert_allclose(supports[1], supports[0], atol=1e-9)
    np.testing.assert_allclose(supports[1][:, :2, 3], soles[:, :2, 3], atol=1e-9)


@pytest.mark.parametrize("error_m", [0.05, 0.15])
def test_a_pushed_landing_that_bounces_while_walking_stops_the_walk(error_m):
    """A walk nobody stopped: its landed (right) foot reads 0 N in the double supports, the
    estimated capture point ``error_m`` off the pattern's there. 150 mm off (a 60-90 N side
    push's landing, seed 2 at 70 N: 121-195 mm; docs/history/walking.md, round 14): the
    landing waits and the walk stops, finishing into a double-support stance, as a stop
    latched there would (main walked on, lifting the other foot with the body bouncing
    between the soles: seeds 2, 5, 19 and 20 fell at 60-90 N). 50 mm off (unpushed walks'
    errors, 57 mm at most in round 10): the landing does not stop the walk; the next
    lift-off, onto that foot still reading 0 N with the capture point off the pattern's, waits
    and stops it (round 17's lift-off rule; main walked on), and the stop stands."""
    target, _, _ = _offline_walk((0.3, 0.0, 0.0), 3000, cp_offset_m=(0.0, error_m),
                                 offset_k=(400, 3000), double_only=True,
                                 ankles_fz_n=(0.0, 380.0))
    if error_m > 0.1:  # (LANDING_WALK_PUSHED_M)
        assert target.stopped_s is not None and target.phase == "stood"
        assert target.landing_waits == 1
    else:
        assert target.liftoff_waits == 1
        assert target.stopped_s is not None and target.phase == "stood"


def test_the_stoppers_deadline_covers_a_stop_just_into_a_swing_and_its_landings_waits():
    """A stop latched in the first period of a swing plays the rest of the swing, the next
    step planted where the other foot stands and the settle; the deadline the walk gives the
    stopper (its PHASE_STOP's ``within_s`` the period before) covers that and the most its
    landings can wait (LANDING_WAIT_MAX_S each), and stays under the stopper's cap. Offline,
    a 1 m walk: 3.6 s played and one landing. Before round 25 the deadline counted one step,
    3.6 s, with nothing left for the landing's wait, and a SIGHUP'd 3 m walk whose landing
    waited 0.19 s stood 0.08 s late, held where it was."""
    from hubo_cli.walking.target import LANDING_WAIT_MAX_S

    walk, within = [], {}
    _offline_walk((1.0, 0.0, 0.0), 4000, each=_cart_zmp_y(walk))
    third_swing = next(k for k, (_, step, double) in enumerate(walk) if step == 2 and not double)
    stop_k = third_swing + 1
    played = []

    def each(k, target, before):
        if k == stop_k - 1:
            within["s"] = target.store[PHASE_STOP].within_s
        played.append((target.phase, all(target._played_support)))

    _offline_walk((1.0, 0.0, 0.0), 4000, stop_k=stop_k, each=each)
    stood_k = next(k for k, (phase, _) in enumerate(played) if phase == "stood")
    landings = sum(1 for k in range(stop_k + 1, stood_k)
                   if played[k][1] and not played[k - 1][1])
    assert landings >= 1
    needed_s = (stood_k - stop_k) * DT + landings * LANDING_WAIT_MAX_S
    assert needed_s <= within["s"] <= MAX_FINISH_S, (needed_s, within["s"], landings)
