"""The emergency stopper: hrpsys' stop table, the revert oracle of eq. 15, latching rules."""

from __future__ import annotations

import math
import os
import signal

import numpy as np
import pytest
from control_support import (
    assert_within_braking_limits,
    assert_within_limits,
    ideal,
    sensed_cycle,
)

from hubo_cli.control.estop import BRAKE_FLAG, RELIEF_S, EmergencyStopper, stop_on_signal
from hubo_cli.control.keys import WRIST_RELIEF
from hubo_cli.control.log import load_log
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import build_pipeline, find_module
from hubo_cli.control.target import Target
from hubo_cli.dataflow import Store
from hubo_cli.motion.limits import JointLimits
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

DT = 0.005


def smooth_ramp(t_s: float, speed_rad_s: float, blend_s: float = 1.5) -> float:
    """A ramp of ``speed_rad_s`` whose velocity rises along a minimum-jerk curve over
    ``blend_s`` (so the input itself keeps to the arm's 0.8 rad/s^2 and 4 rad/s^3 for speeds up
    to 0.5 rad/s); pure ramp after ``blend_s`` (rad)."""
    if t_s < blend_s:
        s = t_s / blend_s
        return speed_rad_s * blend_s * s**4 * (2.5 - 3 * s + s * s)
    return speed_rad_s * (0.5 * blend_s + t_s - blend_s)


def _revert_run(model, speed_rad_s, t_emer_s=2.0, end_s=6.0, **options):
    """Feed RSP a smooth ramp into an EmergencyStopper, latch at t_emer; return the input and
    the output (RSP, rad) per period."""
    stopper = EmergencyStopper(model, DT, **options)
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    stopper.reset(q0, state, Store())
    inputs, outputs = [], []
    for k in range(int(round(end_s / DT))):
        cycle = sensed_cycle(k * DT, DT, state)
        if k == int(round(t_emer_s / DT)):
            cycle.estop_requests.add("operator")
        q = q0.copy()
        q[0] += smooth_ramp(k * DT, speed_rad_s)
        out = stopper.update(q, state, cycle)
        inputs.append(q)
        outputs.append(out)
    return np.array(inputs), np.array(outputs)


def _settled_at(values: np.ndarray, final: float) -> float:
    """Time (s) from which ``values`` equal ``final`` for good."""
    away = np.nonzero(np.abs(values - final) > 1e-12)[0]
    return (away[-1] + 1) * DT if len(away) else 0.0


def _assert_braked_then_within_limits(model, outputs, k_emer, brake_s):
    """Every command within the emergency braking limits (its acceleration) and the model's
    position and velocity limits; after the first ``brake_s`` from the latch within the
    trajectory limits too (the revert goes back under them)."""
    commands = np.vstack([outputs[:1], outputs])
    assert_within_braking_limits(model, commands, DT)
    after = k_emer + int(math.ceil(brake_s / DT)) + 2
    assert_within_limits(model, commands[after:], DT)


def test_revert_oracle_issue_ramp(model):
    """0.5 rad/s ramp on RSP, emergency at 2.0 s, T1 = T2 = 0.5 s: the hold is the command of
    1.5 s, without overshoot. It first brakes to rest at the emergency limits (8 rad/s^2,
    400 rad/s^3): within v/2 (v/a + a/j) = 0.0206 rad and v/a + a/j = 0.0825 s (at the
    trajectories' 0.8 rad/s^2 and 4 rad/s^3 it ran on 0.206 rad); RSP's 0.8 rad/s^2 cannot
    bring it back within 0.5 s, so the way back takes longer (settled 3.455 s measured) but
    keeps to the trajectory limits."""
    inputs, outputs = _revert_run(model, 0.5)
    k_emer, k_rev = 400, 300
    hold = outputs[-1, 0]
    assert hold == pytest.approx(inputs[k_rev, 0], abs=1e-12)
    assert hold - home_posture(model)[0] == pytest.approx(0.375, abs=1e-9)  # 0.5*0.75
    assert np.min(outputs[k_emer:, 0]) >= hold - 1e-12            # no overshoot below it
    brake_rad, brake_s = 0.5 / 2 * (0.5 / 8.0 + 8.0 / 400.0), 0.5 / 8.0 + 8.0 / 400.0
    assert np.max(outputs[k_emer:, 0]) <= inputs[k_emer, 0] + brake_rad + 1e-9
    settled = _settled_at(outputs[:, 0], hold)
    assert 2.5 <= settled <= 4.5
    _assert_braked_then_within_limits(model, outputs, k_emer, brake_s)


def test_revert_oracle_within_t2_on_a_slow_ramp(model):
    """At 0.02 rad/s RSP's limits allow the full oracle: back on the command of 1.5 s by
    t_emer + T2 = 2.5 s, then holding."""
    inputs, outputs = _revert_run(model, 0.02)
    hold = outputs[-1, 0]
    assert hold == pytest.approx(inputs[300, 0], abs=1e-12)
    assert _settled_at(outputs[:, 0], hold) <= 2.5 + 1e-9
    assert np.min(outputs[400:, 0]) >= hold - 1e-12
    _assert_braked_then_within_limits(model, outputs, 400, 0.02 / 8.0 + 8.0 / 400.0)


def test_freeze_preset_brakes_and_holds(model):
    inputs, outputs = _revert_run(model, 0.5, revert_s=DT, stop_s=DT)
    hold = outputs[-1, 0]
    # it stops ahead of the emergency point by about the braking distance, then holds
    assert inputs[400, 0] < hold < inputs[400, 0] + 0.5 / 2 * (0.5 / 0.8 + 0.8 / 4.0)
    assert _settled_at(outputs[:, 0], hold) < 2.0 + 1.0
    assert_within_limits(model, np.vstack([outputs[:1], outputs]), DT)


@pytest.mark.parametrize("preset", ["freeze", "revert"])
def test_stop_table_hrpsys(model, tmp_path, preset):
    """hrpsys' emergency test on the whole default pipeline: a 10 s motion, stop at 4 s, the
    command does not drift (< 1e-3 rad summed over joints) over 3 s once stopped; release at
    8.0 s and the target is reached (< 1e-3 rad)."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    goal = q0.copy()
    names = model.joint_names
    for joint, delta in {"RSP": -0.5, "RSR": -0.3, "REB": -0.4, "LSP": -0.5, "LSR": 0.3,
                         "LEB": -0.4, "RWY": 0.3, "LWY": -0.3}.items():
        goal[names.index(joint)] += delta
    options = {}
    if preset == "freeze":
        options["estop"] = {"revert_s": DT, "stop_s": DT}

    def target(t_s, state):
        info = {}
        if abs(t_s - 4.0) < 1e-9:
            info["estop"] = "operator"
        if abs(t_s - 8.0) < 1e-9:
            info["release"] = True
        return q0 + (goal - q0) * min(t_s / 10.0, 1.0), info

    modules = build_pipeline(model, options=options)
    ControlLoop(robot, modules, target, log_path=tmp_path).run(duration_s=16.0)
    log = load_log(tmp_path)
    cmd, t = log.joints("cmd"), log["t_s"]
    mode = log["estop_mode_code"]
    held = np.nonzero(mode == 2)[0]
    assert len(held) and t[held[0]] <= (4.3 if preset == "freeze" else 4.8)
    k0 = held[0]
    k3 = k0 + int(round(3.0 / DT))
    assert t[k3] < 8.0
    assert np.abs(cmd[k3] - cmd[k0]).sum() < 1e-3
    assert np.abs(cmd[-1] - goal).max() < 1e-3
    recovered = np.nonzero((t > 8.0) & (mode == 0))[0]
    assert len(recovered) and t[recovered[0]] >= 8.0 + 2.5 - 1e-9
    if preset == "freeze":
        assert_within_limits(model, robot.commands(q0), DT)
    else:  # the revert brakes at the emergency limits, then keeps to the trajectory limits
        _assert_braked_then_within_limits(model, robot.commands(q0)[1:],
                                          int(np.searchsorted(t, 4.0)), 0.1)
    assert find_module(modules, "estop").events[0].sources == ("operator",)
    # the stop, the revert and the blend back kept to the limits on their own
    assert find_module(modules, "limiter").clamped_periods == 0


def _dir(parent, name):
    (parent / name).mkdir()
    return parent / name


def _wrist_stop_run(model, tmp_path, relief=None, source="wrist-torque", speed_rad_s=0.35):
    """The whole default pipeline on the ideal driver: RSP, RSR and REB ramp up to
    ``speed_rad_s`` (the right arm of a fast cut), ``source`` stops at 2.0 s; the stopper's
    relief is ``relief``. Returns the stopper, the limiter, time, commands and flags."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    names = model.joint_names
    joints = [names.index(j) for j in ("RSP", "RSR", "REB")]

    class Ramp(Target):
        writes = (WRIST_RELIEF,)

        def __call__(self, t_s, state):
            if relief is not None:  # as the task writes it: the stopper follows it
                self.store[WRIST_RELIEF] = relief
            q = q0.copy()
            q[joints] -= smooth_ramp(t_s, speed_rad_s)
            return q, ({"estop": source} if abs(t_s - 2.0) < 1e-9 else {})

    modules = build_pipeline(model)
    stopper = find_module(modules, "estop")
    ControlLoop(robot, modules, Ramp(), log_path=tmp_path).run(duration_s=3.5)
    log = load_log(tmp_path)
    return (stopper, find_module(modules, "limiter"), log["t_s"], log.joints("cmd"),
            log.flags, joints)


def test_wrist_torque_stop_brakes_at_the_emergency_limits_then_relieves(model, tmp_path):
    """A wrist-torque stop brakes at the robot file's emergency braking limits (8 rad/s^2,
    400 rad/s^3 on the arms): from 0.35 rad/s the command is at rest v/a + a/j = 0.064 s after
    the latch, 0.35^2/16 + 0.35*8/800 = 11 mrad on (as eq. 15's revert brakes); then it
    follows the relief path on a minimum-jerk time scale (RELIEF_S) to its end and holds there.
    Every command keeps to the braking limits and the limiter never has to clamp it."""
    delta = np.zeros(24)
    delta[:6] = [0.02, 0.03, -0.01, 0.04, 0.0, -0.02]
    relief_calls = []

    def relief(q_rad):
        relief_calls.append(q_rad.copy())
        return q_rad + np.linspace(0.0, 1.0, 5)[1:, None] * delta

    stopper, limiter, t, cmd, flags, joints = _wrist_stop_run(model, _dir(tmp_path, "w"), relief)
    k0 = int(np.searchsorted(t, 2.0))
    assert stopper.events[0].sources == ("wrist-torque",) and stopper.mode == "hold"
    assert len(relief_calls) == 1
    arm = model.limb_slice("right-arm")  # (the balancer moves the ankles; the log keeps 1e-6)
    rest = relief_calls[0]
    k_rest = int(np.nonzero(np.all(np.abs(cmd[:, arm] - rest[arm]) < 1e-5, axis=1))[0][0])
    assert t[k_rest] - 2.0 <= 0.064 + 3 * DT
    assert np.abs(rest[joints] - cmd[k0, joints]).max() < 0.011 + 1e-3
    assert np.abs(cmd[-1, arm] - (rest + delta)[arm]).max() < 1e-5  # holds the relief's end
    k_end = int(np.nonzero(np.abs(cmd[:, arm] - cmd[-1, arm]).max(axis=1) > 1e-12)[0][-1]) + 1
    assert t[k_end] - t[k_rest] == pytest.approx(RELIEF_S, abs=2 * DT)
    braking = [i for i, f in enumerate(flags) if BRAKE_FLAG in f]
    assert braking[0] == k0 and braking[-1] <= k_end           # only while braking, relieving
    brake = JointLimits.from_model(model).for_emergency_brake(model)
    a = np.diff(cmd, 2, axis=0) / DT**2
    assert np.all(np.abs(a) <= brake.acceleration_rad_s2 * (1 + 1e-6) + 1e-6)
    assert np.all(np.abs(np.diff(cmd, axis=0)) / DT <= model.velocity_rad_s + 1e-9)
    assert limiter.clamped_periods == 0

    # the same input stopped by the operator: eq. 15 brakes alike, then goes back along the
    # path to the command of T1 before (further than the relief)
    _, _, _, cmd_op, _, _ = _wrist_stop_run(model, _dir(tmp_path, "o"), relief,
                                           source="operator")
    overrun_op = np.max(np.abs(cmd_op[k0:, joints] - cmd_op[k0, joints]))
    assert overrun_op > 0.08 > 5 * np.abs(rest[joints] - cmd[k0, joints]).max()


@pytest.mark.parametrize("relief", [None, lambda q: None, lambda q: np.full((3, 24), np.nan),
                                    lambda q: np.zeros((0, 24))])
def test_wrist_torque_stop_without_a_usable_relief_holds_where_it_braked(model, tmp_path,
                                                                         relief):
    stopper, _, t, cmd, flags, joints = _wrist_stop_run(model, tmp_path, relief)
    k0 = int(np.searchsorted(t, 2.0))
    assert stopper.mode == "hold" and np.all(np.isfinite(cmd))
    held = t > 2.0 + 0.064 + 3 * DT
    arm = model.limb_slice("right-arm")  # (the balancer moves the ankles)
    assert np.abs(cmd[held, arm] - cmd[-1, arm]).max() < 1e-12
    assert np.abs(cmd[-1, joints] - cmd[k0, joints]).max() < 0.011 + 1e-3
    assert not any(BRAKE_FLAG in f for f, h in zip(flags, held, strict=True) if h)


@pytest.mark.parametrize("release_after_s", [0.02, 0.1, 0.2])
def test_a_release_while_the_wrist_stop_brakes_or_relieves_blends_back_smoothly(
        model, release_after_s):
    """Released while braking (0.02 s) or backing out (0.1, 0.2 s): the output blends back to
    the live input from where it is, no step (each period's move within the velocity limit)."""
    stopper = EmergencyStopper(model, DT)
    q0 = home_posture(model)
    stopper.reset(q0, RobotState(0.0, q0, np.zeros(24)), Store())
    delta = np.zeros(24)
    delta[:6] = [0.03, 0.02, -0.02, 0.04, 0.01, -0.03]
    relief = lambda q: q + np.linspace(0.0, 1.0, 4)[1:, None] * delta  # noqa: E731
    outputs = []
    for k in range(int(round(5.0 / DT))):
        t = k * DT
        state = RobotState(t, q0, np.zeros(24))
        if k == 200:
            state.ft["right-wrist"] = np.array([0, 0, 0, 0, 2.0, 0.0])
        if k == 200 + int(round(release_after_s / DT)):
            stopper.release()
        q = q0.copy()
        q[:4] -= smooth_ramp(t, 0.3)
        cycle = sensed_cycle(t, DT, state)
        cycle.store[WRIST_RELIEF] = relief
        outputs.append(stopper.update(q, state, cycle))
    outputs = np.array(outputs)
    assert stopper.events[-1].kind == "release" and stopper.mode in ("recover", "release")
    steps = np.abs(np.diff(outputs, axis=0)) / DT
    assert np.all(steps <= model.velocity_rad_s + 1e-9)


def test_latch_release_and_sources(model):
    stopper = EmergencyStopper(model, DT, sources=("operator", "wrist-torque"))
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    stopper.reset(q0, state, Store())

    def step(k, requests=(), torque_nm=0.0):
        s = RobotState(k * DT, q0, np.zeros(24))
        s.ft["left-wrist"] = np.array([0, 0, 0, 0, torque_nm, 0.0])  # bending, across the forearm
        cycle = sensed_cycle(k * DT, DT, s, estop_requests=set(requests))
        stopper.update(q0, s, cycle)
        return cycle

    step(0, ["capture-point"])           # not one of its sources
    assert stopper.mode == "release"
    step(1, torque_nm=1.0)               # under the 1.21 N m limit
    assert stopper.mode == "release"
    cycle = step(2, torque_nm=1.3)
    assert stopper.stopped and "estop" in cycle.flags
    assert stopper.events[-1].sources == ("wrist-torque",)
    for k in range(3, 10):
        step(k)                          # latched: stays stopped without requests
    assert stopper.mode in ("stop", "hold")
    stopper.release()
    step(10)
    assert stopper.mode == "recover"
    step(11, ["operator"])               # a new request during recovery stops again
    assert stopper.mode in ("stop", "hold") and stopper.events[-1].sources == ("operator",)
    stopper.reset(q0, state, Store())             # deactivation releases (hrpsys)
    assert stopper.mode == "release"


def test_hard_stop_reacts_only_to_hard_source(model):
    modules = build_pipeline(model)
    hard = find_module(modules, "hard-estop")
    assert hard.sources == frozenset({"hard"}) and hard.is_freeze
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    hard.reset(q0, state, Store())
    hard.update(q0, state, Cycle(0.0, DT, estop_requests={"operator", "capture-point"}))
    assert not hard.stopped
    hard.update(q0, state, Cycle(DT, DT, estop_requests={"hard"}))
    assert hard.stopped


def test_operator_signal_latches(model):
    stopper = EmergencyStopper(model, DT)
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    stopper.reset(q0, state, Store())
    restore = stop_on_signal([stopper])
    try:
        os.kill(os.getpid(), signal.SIGUSR1)
        stopper.update(q0, state, sensed_cycle(0.0, DT, state))
    finally:
        restore()
    assert stopper.stopped and stopper.events[0].sources == ("operator",)
    assert signal.getsignal(signal.SIGUSR1) is signal.SIG_DFL


@pytest.mark.parametrize("events, options", [
    # a wrist-torque stop, released, then latched again while blending back
    ([(1.0, "wrist-torque"), (2.0, "release"), (3.5, "wrist-torque")], {}),
    # a revert released while it still brakes (turns)
    ([(1.0, "operator"), (1.02, "release")], {}),
    # the freeze preset (it only brakes) with a wrist-torque stop, released while braking
    ([(1.0, "wrist-torque"), (1.03, "release")], {"revert_s": 0.005, "stop_s": 0.005}),
    # an operator stop latched during the recovery of another, then released
    ([(1.0, "operator"), (2.0, "release"), (3.0, "operator"), (3.02, "release")], {}),
], ids=["wrist-relatch-in-recover", "release-while-turning", "freeze-wrist-release",
        "relatch-in-recover"])
def test_no_latch_or_release_jumps_the_command(model, events, options):
    """Every latch and release goes on from the output's own motion, whichever tracker made
    it (a brake tracker left stale once jumped a re-latched wrist stop by 0.39 rad)."""
    dt, speed = 0.005, 0.35
    stopper = EmergencyStopper(model, dt, sources=("operator", "wrist-torque"), **options)
    q0 = home_posture(model)
    state = RobotState(0.0, q0, np.zeros(24))
    stopper.reset(q0, state, Store())
    at = {round(t_s / dt): what for t_s, what in events}
    outputs = []
    for k in range(round(5.0 / dt)):
        cycle = sensed_cycle(k * dt, dt, state)
        if at.get(k) == "release":
            stopper.release()
        elif k in at:
            cycle.estop_requests.add(at[k])
        q = q0.copy()
        q[0] += speed * k * dt
        outputs.append(stopper.update(q, state, cycle))
    steps = np.abs(np.diff(np.array(outputs)[:, 0]))
    # measured at most 0.0039 rad a period (the ramp's own 0.00175 plus braking): 1.5x
    assert steps.max() < 0.006, steps.max()
