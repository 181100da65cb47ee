"""Force control (issue 36 parts 2-4): hand wrench references from task steps through the
emergency stopper (reverted with the motion) to the ImpedanceController's force setpoint, force
tracking against walls wherever they are, the ReferenceForceUpdater, the plan's thrust and its
CoM shift (eq. 6), the drill's depth guide. The cut under force control on misplaced walls is
measured in docs/history/impedance.md (about a minute of simulation each)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hubo_cli.control.estop import EmergencyStopper
from hubo_cli.control.impedance import LIMIT_FLAG, ImpedanceController
from hubo_cli.control.keys import IMPEDANCE_ON, STOP_MODE, WRIST_RELIEF
from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import SafetyProfile, find_module
from hubo_cli.control.reference_force import ReferenceForceUpdater
from hubo_cli.control.target import FunctionTarget
from hubo_cli.control.wrench import HAND_WRENCH_PLAN, HAND_WRENCH_REF
from hubo_cli.dataflow import FlowError, Store, check_flow
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import (
    ESTIMATE_KEYS,
    QUAT_WORLD_TORSO,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
)
from hubo_cli.geometry import min_jerk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.posture import home_posture
from hubo_cli.scene import CuttingModel
from hubo_cli.state import RobotState, T_frame_sensor
from hubo_cli.tasks.plan import (
    FORCE_RAMP_S,
    Placement,
    UnguidedPress,
    _ramped,
    _with_com_shift,
    make_plan,
)
from hubo_cli.tasks.spec import load_task

DT = 0.005
ARM = "right-arm"


# ------------------------------------------------------------------ force tracking (eq. 3)
def _press_run(model, wall_ahead_m, thrust_n, wall_n_m, seconds=10.0, lateral_n=0.0):
    """The right hand, ideal arm (measured = commanded), pressing a spring wall that stands
    ``wall_ahead_m`` ahead of it along N's x (negative: already pressed in), with the reference
    thrust ``thrust_n`` through the store; a sideways force ``lateral_n`` (N's y) on the hand
    while touching. Returns the measured force along x (N, on the hand), the hand positions
    (N, m) and the flags per period."""
    q0 = home_posture(model)
    limb = Limb(model, ARM, "hand")
    sl = model.limb_slice(ARM)
    p0 = limb.fk(q0[sl])[:3, 3]
    ic = ImpedanceController(model, DT, reference=HAND_WRENCH_REF, axes=("x",), arms=(ARM,))
    state = RobotState(0.0, q0.copy(), np.zeros(len(q0)))
    store = Store()
    store[WRENCHES] = {}
    ic.reset(q0, state, store)
    forces, positions, flags = [], [], []
    fx = 0.0
    for k in range(int(seconds / DT)):
        T = limb.fk(state.q_rad[sl])
        pressed = T[0, 3] - (p0[0] + wall_ahead_m)
        fx = -wall_n_m * pressed if pressed > 0 else 0.0
        f_N = np.array([fx, lateral_n if pressed > 0 else 0.0, 0.0])
        store[WRENCHES] = {"right-wrist": _hubo_reading(T[:3, :3], f_N)}
        store[HAND_WRENCH_REF] = {ARM: np.array([-thrust_n, 0, 0, 0, 0, 0], dtype=float)}
        cycle = Cycle(k * DT, DT, store=store)
        out = ic.update(q0, state, cycle)
        state = RobotState(k * DT, out, np.zeros(len(out)))
        forces.append(fx)
        positions.append(T[:3, 3])
        flags.append(cycle.flags)
    return np.array(forces), np.array(positions) - p0, flags


def _hubo_reading(R_N_H, f_N):
    """What Hubo's wrist sensor reads of a force f_N (neck axes) on the hand: its sensor-frame
    components, only f_z (along the forearm) real (FT_MEASURED), no moments."""
    f_S = (R_N_H @ T_frame_sensor("right-wrist")[:3, :3]).T @ f_N
    reading = np.zeros(6)
    reading[2] = f_S[2]
    return reading


def test_the_whole_force_at_the_bit_from_hubos_three_axis_sensor(model):
    """f_z with the moments m_x, m_y of a force at the bit's known point give the whole
    force, the part across the forearm included (what f_z alone, 45 deg off the bit, cannot
    see); a moment about the bit (the spindle) leaves the thrust alone; a point near the
    sensor along the forearm, or a garbled reading, gives NaN, never a number."""
    from hubo_cli.control.wrench import TIP_MIN_M, force_at_point, tool_point_S_m

    r_S = tool_point_S_m(model, "drill", T_frame_sensor("right-wrist"))
    T_6_S = model.tool_transform("hand") @ T_frame_sensor("right-wrist")
    bit_S = np.linalg.inv(T_6_S)[:3, :3] @ model.tool_transform("drill")[:3, 0]
    assert abs(r_S[2]) > TIP_MIN_M
    rng = np.random.default_rng(36)
    for _ in range(200):
        f_S = rng.normal(size=3) * rng.uniform(0.1, 30.0)
        spindle_nm = rng.uniform(-0.1, 0.1)
        m_S = np.cross(r_S, f_S) + spindle_nm * bit_S
        reading = np.array([0.0, 0.0, f_S[2], m_S[0], m_S[1], 0.0])  # Hubo: fz, mx, my
        found = force_at_point(reading, r_S)
        # the spindle's moment along the bit reads into the force across it, never the thrust
        assert found @ bit_S == pytest.approx(f_S @ bit_S, abs=1e-9)
        if spindle_nm == 0.0:
            np.testing.assert_allclose(found, f_S, atol=1e-9)
    assert np.all(np.isnan(force_at_point(np.ones(6), np.array([0.1, 0.0, 0.01]))))
    assert np.all(np.isnan(force_at_point(np.full(6, np.nan), r_S)))


def test_the_drill_yields_to_the_thrust_not_to_the_force_across_the_bit(model):
    """With the drill's point, eq. 3 and force tracking see the thrust along the bit even with
    a force across it (the cut's, turning at a corner): pressing exactly the reference along
    N's x with 2 N across that then reverses, neither the hand nor the spring's centre moves
    (issue 36: read from f_z alone, the force across read into the spring's input and every
    turn of the cut's direction moved the hand along the bit: the thrust left +-2 N). Read
    from f_z alone both move."""
    q0 = home_posture(model)
    sl = model.limb_slice(ARM)
    T_N_H = Limb(model, ARM, "hand").fk(q0[sl])
    R_N_S = T_N_H[:3, :3] @ T_frame_sensor("right-wrist")[:3, :3]
    from hubo_cli.control.wrench import tool_point_S_m

    r_S = tool_point_S_m(model, "drill", T_frame_sensor("right-wrist"))

    def reading(across_n):
        f_S = R_N_S.T @ np.array([-3.0, 0.0, across_n])  # 3 N back along x (the reference)
        m_S = np.cross(r_S, f_S)
        return np.array([0.0, 0.0, f_S[2], m_S[0], m_S[1], 0.0])

    moved, offset = {}, {}
    for tools in ({ARM: "drill"}, None):
        ic = ImpedanceController(model, DT, reference=HAND_WRENCH_REF, axes=("x",), arms=(ARM,),
                                 tools=tools)
        state = RobotState(0.0, q0.copy(), np.zeros(len(q0)))
        store = Store()
        store[WRENCHES] = {"right-wrist": reading(2.0)}
        ic.reset(q0, state, store)
        largest = centre = 0.0
        for k in range(400):
            store[WRENCHES] = {"right-wrist": reading(2.0 if k < 200 else -2.0)}
            store[HAND_WRENCH_REF] = {ARM: np.array([-3.0, 0, 0, 0, 0, 0])}
            ic.update(q0, state, Cycle(k * DT, DT, store=store))
            largest = max(largest, float(np.linalg.norm(ic.offset(ARM))))
            centre = max(centre, float(np.linalg.norm(ic.hands[0].centre_m)))
        moved[tools is not None] = centre
        offset[tools is not None] = largest
    assert moved[True] < 1e-9 and offset[True] < 1e-9
    assert moved[False] > 1e-4  # 1 s at 2 mm/s per N of misread force
    assert offset[False] > 1e-3  # the misread force on the 500 N/m spring


@pytest.mark.parametrize("seed", range(4))
def test_force_tracking_holds_the_thrust_wherever_the_wall_is(model, seed):
    """Walls from 10 mm pressed in to 18 mm ahead, thrusts of 1-8 N, faces of 500-5000 N/m
    (random), read by Hubo's wrist sensor (the force along the forearm only): the force along
    the reference settles on it (force tracking moves the spring's centre), the hand never
    moves across x (only x yields), and it ends pressed into the wall by thrust / stiffness.
    Seen over these seeds: within 1e-4 N and 0.1 um after 10 s (plain arithmetic, no physics);
    bounds 0.05 N and 50 um."""
    rng = np.random.default_rng(seed)
    wall = rng.uniform(-0.010, 0.018)
    thrust, stiffness = rng.uniform(1.0, 8.0), rng.uniform(500.0, 5000.0)
    force, position, _ = _press_run(model, wall, thrust, stiffness)
    assert abs(force[-1] + thrust) < 0.05
    assert np.abs(position[:, 1:]).max() < 1e-9
    assert position[-1, 0] == pytest.approx(wall + thrust / stiffness, abs=5e-5)


@pytest.mark.parametrize("seed", range(3))
def test_a_hand_approaches_a_face_at_most_4_mm_s_of_its_own(model, seed):
    """Round 22: a hand pressing with a thrust reached a rigid face at 20-24 mm/s (the spring's
    give to the thrust, the force tracking's 2 mm/s per N and the plan's plunge together) and
    tripped the wrist-torque stop on contact. The impedance now moves a hand toward the face
    at most APPROACH_M_S (4 mm/s) of its own, the spring's centre alike; the force still
    settles on the reference. Walls 2-18 mm ahead, thrusts 1-15 N, faces of 2-100 kN/m
    (random; seeds 200-207 seen): at most 4.15-4.55 mm/s before the touch (the offset's rate
    capped each period, its acceleration within one on top; main: 12.6-36.9 mm/s), bound
    5 mm/s; 0.001-0.072 N off the reference after 12 s (main: up to 0.17 N, the stiff faces
    settling slowly), bound 0.25 N."""
    from hubo_cli.control.impedance import APPROACH_M_S

    assert APPROACH_M_S == 0.004
    rng = np.random.default_rng(200 + seed)
    wall = rng.uniform(0.002, 0.018)
    thrust, stiffness = rng.uniform(1.0, 15.0), rng.uniform(2e3, 1e5)
    force, position, _ = _press_run(model, wall, thrust, stiffness, seconds=12.0)
    touch = int(np.argmax(force < 0))
    assert touch > 0
    assert np.diff(position[:touch, 0]).max() / DT <= 0.005
    assert abs(force[-1] + thrust) < 0.25


def test_force_tracking_stops_at_the_offset_limit(model):
    """A wall beyond the 30 mm offset limit: the hand advances to the limit and no further,
    flagged, never touching it."""
    force, position, flags = _press_run(model, 0.05, 3.0, 2000.0, seconds=12.0)
    assert not force.any()
    assert position[:, 0].max() <= 0.030 + 1e-9
    assert position[-1, 0] == pytest.approx(0.030, abs=1e-4)
    assert LIMIT_FLAG in flags[-1]


def test_without_a_reference_nothing_moves(model):
    """A zero reference and no contact: the command passes through bit for bit."""
    q0 = home_posture(model)
    ic = ImpedanceController(model, DT, reference=HAND_WRENCH_REF, axes=("x",))
    state = RobotState(0.0, q0, np.zeros(len(q0)))
    store = Store()
    store[HAND_WRENCH_REF], store[WRENCHES] = {}, {}
    ic.reset(q0, state, store)
    for k in range(100):
        assert np.array_equal(ic.update(q0, state, Cycle(k * DT, DT, store=store)), q0)


def test_bad_impedance_settings_are_refused(model):
    with pytest.raises(ConfigError, match="unknown axis"):
        ImpedanceController(model, DT, axes=("x", "w"))
    with pytest.raises(ConfigError, match="force tracking"):
        ImpedanceController(model, DT, force_tracking_m_per_n_s=-1.0)
    with pytest.raises(ConfigError, match="force tracking"):
        ImpedanceController(model, DT, force_tracking_m_per_n_s=math.inf)


# ------------------------------------------------------------------ the flow of references
def test_the_pipeline_takes_references_from_the_stopper_or_the_target(model):
    profile = SafetyProfile(impedance=True, wrench_reference=True)
    modules = profile.build(model, DT, {})
    assert find_module(modules, "impedance").reads == (WRENCHES, HAND_WRENCH_REF)
    assert find_module(modules, "estop").writes == (HAND_WRENCH_REF, STOP_MODE)
    writer = FunctionTarget(lambda t, s: (None, {}))
    writer.writes = (HAND_WRENCH_PLAN,)
    check_flow([writer, *modules], provided=ESTIMATE_KEYS)
    with pytest.raises(FlowError, match=HAND_WRENCH_PLAN.name):  # nobody writes the plan's
        check_flow([FunctionTarget(lambda t, s: (None, {})), *modules], provided=ESTIMATE_KEYS)
    no_stop = SafetyProfile(impedance=True, wrench_reference=True, estop=False)
    assert find_module(no_stop.build(model, DT, {}),
                       "impedance").reads == (WRENCHES, HAND_WRENCH_PLAN)
    assert find_module(SafetyProfile(impedance=True).build(model, DT, {}),
                       "impedance").reads == (WRENCHES,)


def _stopper_run(model, wrench_at, t_emer_s=2.0, t_release_s=None, end_s=8.0,
                 source="operator", **options):
    """A stopper passing the plan's wrench ``wrench_at(t)`` (6-vector or None) through; a stop
    from ``source`` at ``t_emer_s`` (``wrist-torque``: a 2 N m wrist moment in that period),
    a release at ``t_release_s``. Returns the times, the plan's x force and the stopper's x
    force per period."""
    stopper = EmergencyStopper(model, DT, wrench_reference=True, **options)
    q0 = home_posture(model)
    store = Store()
    store[WRENCHES] = {}
    stopper.reset(q0, RobotState(0.0, q0, np.zeros(len(q0))), store)
    t, planned, out = [], [], []
    for k in range(int(end_s / DT)):
        state = RobotState(k * DT, q0, np.zeros(len(q0)))
        cycle = Cycle(k * DT, DT, store=store)
        store[WRENCHES] = {}
        if k == round(t_emer_s / DT):
            if source == "wrist-torque":
                store[WRENCHES] = {"right-wrist": np.array([0.0, 0.0, 0.0, 0.0, 2.0, 0.0])}
            else:
                cycle.estop_requests.add(source)
        if t_release_s is not None and k == round(t_release_s / DT):
            stopper.release()
        w = wrench_at(k * DT)
        store[HAND_WRENCH_PLAN] = {} if w is None else {ARM: w}
        stopper.update(q0, state, cycle)
        ref = store[HAND_WRENCH_REF].get(ARM, np.zeros(6))
        assert np.all(np.isfinite(ref))
        t.append(k * DT)
        planned.append(np.nan if w is None else w[0])
        out.append(ref[0])
    return np.array(t), np.array(planned), np.array(out)


def _ramp(t):
    return np.array([-2.0 * t, 0, 0, 0, 0, 0])


def test_a_stop_reverts_the_wrench_with_the_motion_then_recovers(model):
    """eq. 15 for forces: from the stop at 2 s the reference blends (minimum jerk, T2 = 0.5 s)
    to the plan's of t_emer - T1 = 1.5 s, holds it while the plan goes on, and after the
    release at 5 s blends back to the live plan over the 2.5 s recovery."""
    t, planned, out = _stopper_run(model, _ramp, t_release_s=5.0, end_s=8.5)
    k_emer = round(2.0 / DT)
    assert np.array_equal(out[:k_emer], planned[:k_emer])  # passed through until the stop
    back = -2.0 * (2.0 - 0.5 - DT)  # the plan's of T1 before the stop (one period's lag)
    u = np.array([min_jerk(min(1.0, (x - 2.0) / 0.5)) for x in t[k_emer:k_emer + 100]])
    at_stop = out[k_emer - 1]
    assert np.allclose(out[k_emer:k_emer + 100], at_stop + u * (back - at_stop), atol=0.03)
    held = (t > 2.6) & (t < 5.0)
    assert np.allclose(out[held], back, atol=0.03)
    assert np.allclose(out[t > 7.6], planned[t > 7.6])
    assert np.abs(np.diff(out)).max() < 0.05  # no jump: at most 10 N/s per period


@pytest.mark.parametrize("preset", ["freeze", "wrist-torque"])
def test_a_freeze_or_a_wrist_stop_lets_go_of_the_force(model, preset):
    """The freeze preset (T1 = T2 = one period) and the wrist-torque stop (which backs the tool
    out) do not push on: the reference goes to zero within T2, monotonically, and stays."""
    options = {"revert_s": DT, "stop_s": DT} if preset == "freeze" else {}
    t, _, out = _stopper_run(model, lambda t: np.array([-4.0, 0, 0, 0, 0, 0]), end_s=4.0,
                             source="wrist-torque" if preset == "wrist-torque" else "operator",
                             **options)
    t2 = DT if preset == "freeze" else 0.5
    assert np.allclose(out[t < 2.0], -4.0)
    assert np.all(np.diff(out[t >= 2.0 - DT]) >= -1e-12)
    assert np.all(out[t >= 2.0 + t2 + DT] == 0.0)


@pytest.mark.parametrize("soft_stop_too", [False, True])
def test_a_hard_stop_lets_go_of_the_force_smoothly_until_released(model, soft_stop_too):
    """A hard stop (the hard-estop downstream freezes the joints) takes the wrench reference
    to zero on a minimum-jerk blend over the soft stopper's T2 (0.5 s), holds zero until the
    release at 5 s, then blends back to the live plan over the 2.5 s recovery, never jumping;
    the same when the soft stopper stops in the same period (its revert gives way to zero)."""
    stopper = EmergencyStopper(model, DT, wrench_reference=True)
    assert stopper.hard_sources == {"hard"}
    q0 = home_posture(model)
    store = Store()
    store[WRENCHES] = {}
    stopper.reset(q0, RobotState(0.0, q0, np.zeros(len(q0))), store)
    t, out = np.arange(0.0, 8.5, DT), []
    for k, tk in enumerate(t):
        cycle = Cycle(tk, DT, store=store)
        if 2.0 <= tk < 3.0:  # the hard request stays a while: it latches once
            cycle.estop_requests.add("hard")
            if soft_stop_too and k == round(2.0 / DT):
                cycle.estop_requests.add("operator")
        if k == round(5.0 / DT):
            stopper.release()
        store[HAND_WRENCH_PLAN] = {ARM: _ramp(tk)}
        stopper.update(q0, RobotState(tk, q0, np.zeros(len(q0))), cycle)
        out.append(store[HAND_WRENCH_REF].get(ARM, np.zeros(6))[0])
    out = np.array(out)
    k_emer = round(2.0 / DT)
    at_stop = out[k_emer - 1]
    u = np.array([min_jerk(min(1.0, (x - 2.0) / 0.5)) for x in t[k_emer:k_emer + 100]])
    assert np.allclose(out[k_emer:k_emer + 100], at_stop * (1.0 - u), atol=1e-9)
    assert np.all(out[(t >= 2.5) & (t < 5.0)] == 0.0)  # held at zero until the release
    assert np.allclose(out[t > 7.6], -2.0 * t[t > 7.6])  # back on the live plan
    # no jump: the recovery joins a plan 15-17 N away in 2.5 s (min-jerk peak 1.875 x 6.5 N/s
    # + the plan's 2 N/s: 0.075 N per period); a step would be 10 N
    assert np.abs(np.diff(out)).max() < 0.1


def test_garbled_plan_wrenches_never_leave_the_stopper(model):
    """NaN, infinite or wrongly shaped plan wrenches count as no wrench: zero, never NaN."""
    bad = [np.full(6, np.nan), np.array([np.inf, 0, 0, 0, 0, 0]), np.zeros(3), None]
    t, _, out = _stopper_run(model, lambda t: bad[int(t / DT) % len(bad)], end_s=3.0)
    assert np.all(out == 0.0)


# ------------------------------------------------------------------ ReferenceForceUpdater
def test_the_balance_force_follows_the_measured_one_rate_limited():
    rfu = ReferenceForceUpdater((1.0, 0.0, 0.0), DT, max_rate_n_s=1.0, gain_per_s=2.0)
    values = [rfu.update((-5.0, 3.0, 1.0)) for _ in range(int(8 / DT))]
    steps = np.diff([0.0, *values])
    assert np.abs(steps).max() <= 1.0 * DT + 1e-12  # never faster than 1 N/s
    assert values[int(2 / DT)] == pytest.approx(-2.0, abs=0.05)  # rate-limited at first
    assert values[-1] == pytest.approx(-5.0, abs=0.01)  # then on the measured force
    assert np.allclose(rfu.force_n, (values[-1], 0.0, 0.0))
    rfu.update((np.nan, 0.0, 0.0))  # a garbled reading is skipped
    assert math.isfinite(rfu.reference_n)
    rfu.hold()
    held = rfu.reference_n
    for _ in range(100):
        rfu.update((10.0, 0.0, 0.0))
    assert rfu.reference_n == held
    with pytest.raises(ValueError):
        ReferenceForceUpdater((0.0, 0.0, 0.0), DT)


# ------------------------------------------------------------------ task files and plans
def _task(tmp_path, steps: str, wall: str = "") -> str:
    path = tmp_path / "press.toml"
    path.write_text(f"""\
name = "press"
[stance]
wall_distance_mm = 450.0
centre_mm = [-250.0, 50.0]
[scene.wall]
{wall}
[[steps]]
kind = "move"
depth_mm = -20.0
duration_s = 1.0
{steps}""", encoding="utf-8")
    return path


PRESS = """
[[steps]]
kind = "plunge"
depth_mm = 2.5
speed_mm_s = 10.0
thrust_n = 4.0
[[steps]]
kind = "wait"
duration_s = 1.0
thrust_n = 4.0
[[steps]]
kind = "retract"
depth_mm = -20.0
speed_mm_s = 20.0
"""


def test_thrust_steps_are_read_and_checked(tmp_path):
    spec = load_task(_task(tmp_path, PRESS, "misplaced_mm = -15.0"))
    assert [s.thrust_n for s in spec.steps] == [0.0, 4.0, 4.0, 0.0]
    assert "pressing 4 N" in spec.steps[1].describe()
    assert spec.scene.wall_misplaced_m == pytest.approx(-0.015)
    for bad, field in ((PRESS.replace("thrust_n = 4.0\n[[steps]]\nkind = \"wait\"",
                                      "thrust_n = -1.0\n[[steps]]\nkind = \"wait\""), "thrust_n"),
                       (PRESS.replace("4.0", "16.0"), "thrust_n"),
                       (PRESS.replace("4.0", '"hard"'), "thrust_n"),
                       (PRESS + "thrust_n = 2.0\n", "thrust_n")):  # a retract cannot press
        with pytest.raises(ConfigError, match=field):
            load_task(_task(tmp_path, bad))
    with pytest.raises(ConfigError, match="misplaced_mm"):
        load_task(_task(tmp_path, PRESS, "misplaced_mm = 150.0"))


def test_the_plan_ramps_the_thrust_and_only_a_thrust_asks_for_force(model, tmp_path):
    plan = make_plan(load_task(_task(tmp_path, PRESS)), model)
    assert plan.preflight.ok and plan.has_force
    thrust = plan.thrust_n
    n = round(FORCE_RAMP_S / DT)
    start = int(np.argmax(plan.step_index == 1))
    assert start == 0  # the plan starts with the plunge, from no force
    assert np.allclose(thrust[start:start + n], 4.0 * np.arange(1, n + 1) / n)
    assert np.abs(np.diff(thrust)).max() <= 4.0 / n + 1e-12  # never a jump
    end = int(np.argmax(plan.step_index == 3))
    assert thrust[end + n:].max() == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(plan.hand_force_S_n(start + n), (-4.0, 0.0, 0.0))
    assert not make_plan(load_task(_task(tmp_path, PRESS.replace("thrust_n = 4.0", ""))),
                         model).has_force


def test_a_drill_pressed_with_no_depth_guide_is_warned_of(model, tmp_path):
    """Round 30: generated force cuts with no depth guide drove the bit 25-30 mm through the
    wall (the flutes in it 15-80 % of the cut), with no word before the run."""
    unguided = make_plan(load_task(_task(tmp_path, PRESS)), model).preflight
    assert unguided.unguided == UnguidedPress(4.0, model.impedance_max_offset_m)
    assert any("no depth guide" in line and "4 N" in line for line in unguided.warnings)
    guided = load_task(_task(tmp_path, PRESS, "[scene.cutting]\nguide_depth_m = 0.0025"))
    assert make_plan(guided, model).preflight.unguided is None
    # the run folder keeps what was said before the run (a --json run prints no warning)
    from hubo_cli.tasks.runner import run_task

    s = run_task(make_plan(load_task(_task(tmp_path, PRESS)), model), driver="ideal",
                 out=tmp_path / "run").summary
    assert s["preflight_warnings"] == unguided.warnings


def test_ramped_spreads_each_change():
    out = _ramped(np.array([0.0, 0, 3, 3, 3, 3, 0, 0, 0, 0]), 2)
    assert np.allclose(out, [0, 0, 1.5, 3, 3, 3, 1.5, 0, 0, 0])
    assert np.allclose(_ramped(np.array([4.0, 4, 4]), 2), [2, 4, 4])  # from zero at the start
    assert np.array_equal(_ramped(np.zeros(5), 10), np.zeros(5))


def test_the_waist_leans_into_the_thrust_eq6(model, tmp_path):
    """Eq. 6: the plan's CoM shift with a thrust lies ahead of the one without, by about the
    slope it reports times the thrust; the slope is negative (a force pushing the hand back,
    -x, moves the waist forward)."""
    pressing, plain = (load_task(_task(tmp_path, PRESS.replace("4.0", f)))
                       for f in ("8.0", "0.0"))
    found = Placement(0.45, (-0.25, 0.05), 0.1, True, 0.1)
    with_force, without = (_with_com_shift(s, model, found) for s in (pressing, plain))
    assert with_force.shift_per_force_m_n < -0.001
    assert without.shift_per_force_m_n == 0.0
    lean = with_force.shift_m - without.shift_m
    assert lean == pytest.approx(-8.0 * with_force.shift_per_force_m_n, rel=0.1)


# ------------------------------------------------------------------ the depth guide
def test_the_depth_guide_pushes_out_never_pulls_and_slides_with_friction():
    none, guide = CuttingModel(), CuttingModel(guide_depth_m=0.0025)
    assert none.guide_force_n(0.002, (0.0, 0.01, 0.0)) == (0.0, 0.0, 0.0)
    assert guide.guide_force_n(-0.001, (0.0, 0.01, 0.0)) == (0.0, 0.0, 0.0)
    fx, fy, fz = guide.guide_force_n(0.002, (0.0, 0.0, 0.0))
    assert fx == pytest.approx(-guide.guide_stiffness_n_m * 0.002) and fy == fz == 0.0
    assert guide.guide_force_n(0.001, (-1.0, 0.0, 0.0))[0] == 0.0  # withdrawing fast: no pull
    fx, fy, fz = guide.guide_force_n(0.002, (0.0, 0.05, -0.05))
    assert fy < 0 < fz and math.hypot(fy, fz) <= guide.guide_friction * -fx + 1e-12


def test_the_task_target_writes_the_plans_force_and_measures_the_thrust(model, tmp_path):
    """Once the plan runs, the target writes the plan's hand force (N axes) to the store every
    period and reads the wrist: a 5 N push back along the bit is a 5 N thrust. A task without a
    thrust declares and writes nothing."""
    from hubo_cli.tasks.target import TaskTarget

    plan = make_plan(load_task(_task(tmp_path, PRESS)), model)
    target = TaskTarget(plan, correction=False)
    assert target.writes == (WRIST_RELIEF, HAND_WRENCH_PLAN, IMPEDANCE_ON)
    store = Store()
    impedance = ImpedanceController(model, DT, active=False)  # as force_control builds it
    impedance.reset(plan.q_first_rad, RobotState(0.0, plan.q_first_rad, np.zeros(24)), store)
    target.attach(None, [impedance], store)
    sl = model.limb_slice(ARM)
    q = plan.q_first_rad.copy()
    R_N_H = Limb(model, ARM, "hand").fk(q[sl])[:3, :3]
    store[WRENCHES] = {"right-wrist": _hubo_reading(R_N_H, np.array([-5.0, 0.0, 0.0]))}
    store[QUAT_WORLD_TORSO] = np.array([1.0, 0.0, 0.0, 0.0])
    store[T_WORLD_TORSO] = np.eye(4)  # the estimate's torso and soles, standing at the origin
    store[T_WORLD_SOLES] = np.stack([np.eye(4), np.eye(4)])
    moving = RobotState(0.0, q, np.full(len(q), 0.1))
    _, info = target(0.0, moving)  # the raise (the robot still moving): no force yet
    assert target.phase == "raise" and np.allclose(store[HAND_WRENCH_PLAN][ARM], 0.0)
    impedance.update(q, moving, Cycle(0.0, DT, store=store))  # it follows IMPEDANCE_ON
    assert impedance.mode == "off"  # the first move swings the arm up without it
    assert info["thrust_n"] == pytest.approx(5.0, abs=1e-6)
    state = RobotState(0.0, q, np.zeros(len(q)))
    target(DT, state)  # still: the plan runs from its first row, the ramp's first step
    impedance.update(q, state, Cycle(DT, DT, store=store))
    assert target.phase == "run" and store[IMPEDANCE_ON] and impedance.mode == "on"
    first = -4.0 / round(FORCE_RAMP_S / DT)
    assert np.allclose(store[HAND_WRENCH_PLAN][ARM], (first, 0, 0, 0, 0, 0))
    k = round(FORCE_RAMP_S / DT) + 10
    target(DT + k * DT, state)
    assert np.allclose(store[HAND_WRENCH_PLAN][ARM], (-4.0, 0, 0, 0, 0, 0), atol=1e-3)
    plain = TaskTarget(make_plan(load_task(_task(tmp_path, PRESS.replace("thrust_n = 4.0", ""))),
                                 model))
    plain.store = Store()
    for key in (WRENCHES, QUAT_WORLD_TORSO, T_WORLD_TORSO, T_WORLD_SOLES):
        plain.store[key] = store[key]
    plain(0.0, state)
    assert plain.writes == (WRIST_RELIEF,) and HAND_WRENCH_PLAN not in plain.store


def test_the_task_target_measures_the_hands_thrust_too(model, tmp_path):
    """The hand's point is the wrist sensor's origin, where the moments cannot place a force
    (main: a NaN thrust, so a hand task's summary had no thrust and the waist never leaned
    into the force the hand met): f_z alone, taken to lie along the bit, as the hand's force
    tracking takes it. A 5 N push back along the bit is a 5 N thrust."""
    from hubo_cli.tasks.target import TaskTarget

    path = _task(tmp_path, PRESS.replace("depth_mm = 2.5", "depth_mm = -15.0"))
    with open(path, encoding="utf-8") as f:
        text = f.read().replace("[stance]\n", '[stance]\ntool = "hand"\n', 1)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
    plan = make_plan(load_task(path), model)
    assert plan.spec.stance.tool == "hand"
    target = TaskTarget(plan, correction=False)
    target.attach(None, [], Store())
    sl = model.limb_slice(ARM)
    q = plan.q_first_rad.copy()
    R_N_H = Limb(model, ARM, "hand").fk(q[sl])[:3, :3]
    store = target.store
    store[WRENCHES] = {"right-wrist": _hubo_reading(R_N_H, np.array([-5.0, 0.0, 0.0]))}
    store[QUAT_WORLD_TORSO] = np.array([1.0, 0.0, 0.0, 0.0])
    store[T_WORLD_TORSO] = np.eye(4)
    store[T_WORLD_SOLES] = np.stack([np.eye(4), np.eye(4)])
    _, info = target(0.0, RobotState(0.0, q, np.full(len(q), 0.1)))
    assert info["thrust_n"] == pytest.approx(5.0, abs=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("misplaced_mm", [
    # the portable code path gives the same to 6e-5 N (below): it checks the far wall only
    pytest.param(15.0, marks=pytest.mark.physical), -15.0])
def test_the_cut_holds_its_thrust_on_a_misplaced_wall(model, tmp_path, misplaced_mm):
    """cut-rectangle-force on a 45 x 30 mm rectangle (its four corners and both kinds of edge,
    in 32 s of simulation), the wall 15 mm farther or nearer than planned: it completes, the
    hole RMS is 1.60 / 1.57 mm (bound 3 mm, the issue's: 1.9x), and while cutting (the path,
    after the plunge and the 2 s press) the thrust stays within the issue's +-2 N of its 3 N
    reference all the time: at most 1.56 / 1.30 N off (where the lift ends, at the corners),
    RMS error 0.46 / 0.42 N (far / near; the portable code path gives the far wall's to the
    digits shown). The band's headroom over the largest error, 0.44 N, is thousands of times
    that spread; the RMS bound 0.6 N is 1.30x the 0.46 N. (On the 60 x 40 mm rectangle, 37 s:
    1.46 / 1.44 mm, 1.59 / 1.38 N, RMS 0.38 / 0.35 N, 60 % more CPU; on 30 x 20 mm the RMS came
    to 0.59 N, the corners' share of the cut larger.) Before (r3-thrust2): 99.76 / 100 %
    within the band, RMS 0.61 / 0.64 N, the lean ringing the hand at 0.55 Hz
    (docs/history/impedance.md)."""
    from hubo_cli.tasks.runner import check_task, run_task

    spec = load_task("cut-rectangle-force", {"misplaced_mm": misplaced_mm, "width_mm": 45.0,
                                             "height_mm": 30.0})
    s = run_task(check_task(spec, model), out=tmp_path).summary
    assert s["completed"] and not s["estop_events"] and s["preflight_warnings"] == []
    assert s["hole_rms_error_mm"] <= 3.0
    thrust = s["thrust_n"]
    assert thrust["force_control"] and thrust["reference_mean"] == pytest.approx(3.0)
    assert thrust["max_error"] <= 2.0 and thrust["share_within_band"] == 1.0
    assert thrust["rms_error"] <= 0.6
