"""Teleoperation at the edge of reach (ideal driver): out of reach and back, a straight elbow."""

import io
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from hubo_cli.cli.teleop import _direction, _reach_cell
from hubo_cli.control.log import load_log
from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.arm_reach import ArmReach, ReachSettings
from hubo_cli.kinematics.conditioning import SingularityScale, condition_number
from hubo_cli.kinematics.reach import branch_of, nearest_on_branch
from hubo_cli.model import load_model
from hubo_cli.teleop.session import FREE_READY_ARM_RAD, TeleopSettings, run_teleop

R_TRACKER_STANCE = np.diag([1.0, -1.0, -1.0])  # stance -> tracker (x fwd, y right, z down)
RATE_HZ = 60.0


def _min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


def _stream(path: Path, offsets_S_m, duration_s: float) -> Path:
    """A pose log: stations 1 and 2 (right, left hand) move by offsets_S_m(t) (stance frame)
    from wherever they start, orientation fixed."""
    rows = ["t_s,station,x_m,y_m,z_m,qw,qx,qy,qz"]
    for t in np.arange(0.0, duration_s, 1.0 / RATE_HZ):
        for station, arm in ((1, "right-arm"), (2, "left-arm")):
            p = np.array([0.3, 0.2 if station == 2 else -0.2, 0.0])
            p = p + R_TRACKER_STANCE @ offsets_S_m(arm, t)
            rows.append(f"{t + 0.004 * station:.6f},{station},{p[0]:.6f},{p[1]:.6f},"
                        f"{p[2]:.6f},1,0,0,0")
    path.write_text("\n".join(rows) + "\n")
    return path


def _distance_to_reach(limb, goals_m, q0, nearest_m=None):
    """Distance (m) of each goal position to the positions the arm reaches on its branch within
    its limits (a converged position-only nearest search from the ready pose); the nearest
    reachable positions into ``nearest_m`` (N x 3) if given. Each distinct goal is searched
    once (every search starts from the same pose: a goal's answer is its own, bit for bit);
    a run's goals repeat, its 60 Hz input held over the 200 Hz periods (2698 goals, 595
    distinct, on the 8 s walk back)."""
    goals_m = np.asarray(goals_m, dtype=float)
    distinct, back = np.unique(goals_m, axis=0, return_inverse=True)
    q, out = np.array(q0, dtype=float), np.empty(6)
    T = limb.fk(q)
    dist, nearest = np.empty(len(distinct)), np.empty((len(distinct), 3))
    for k, g in enumerate(distinct):
        T[:3, 3] = g
        dist[k], _, _ = nearest_on_branch(T, limb.chain, limb.lower_rad, limb.upper_rad, q,
                                          branch_of(q), np.zeros(3), 1.0, 1e-4, 300, out)
        if nearest_m is not None:
            nearest[k] = limb.fk(out)[:3, 3]
    back = back.reshape(-1)
    if nearest_m is not None:
        nearest_m[:] = nearest[back]
    return dist[back]


def _operate(log, key):
    sel = log["phase_code"] == 1
    goal = np.column_stack([log[f"goal_{c}_m_{key}"] for c in "xyz"])[sel]
    actual = np.column_stack([log[f"actual_{c}_m_{key}"] for c in "xyz"])[sel]
    return log["t_s"][sel], goal, actual


def _walk_beyond_reach(arms, back_s: float):
    """The out-of-reach walk of each arm in ``arms`` (the others still): forward from the ready
    pose to 30 cm beyond its reach (minimum jerk, 1-4 s), back along the same line in
    ``back_s`` from 4.5 s. Returns offsets_S_m(arm, t) for :func:`_stream` and the walk's
    end (s)."""
    ahead = np.linspace(0.0, 0.3, 301)
    edge = {}
    for arm in arms:
        limb = get_limb(arm, "hand")
        ready = limb.fk(np.array(FREE_READY_ARM_RAD[arm]))[:3, 3]
        edge[arm] = ahead[np.argmax(_distance_to_reach(
            limb, ready + np.outer(ahead, [1, 0, 0]), FREE_READY_ARM_RAD[arm]) > 1e-3)]
        assert 0.01 < edge[arm] < 0.25

    def offset(arm, t):
        if arm not in edge:
            return np.zeros(3)
        out = _min_jerk((t - 1.0) / 3.0)
        back = _min_jerk((t - 4.5) / back_s)
        return np.array([1.0, 0.0, 0.0]) * (edge[arm] + 0.3) * (out - back)

    return offset, 4.5 + back_s


def _return_figures(arm, t, goal, actual, walk_end_s):
    """How a hand met the out-of-reach walk (times from the stream's start, positions in S):
    its largest distance from the goal's nearest reachable point while it is parked (the goal
    out of reach, from 1 s after it turned back; m); its largest windowed excursion (hand to
    the nearest goal sample within +-1 s) beyond the goal's distance to the reachable set (m);
    when it is first within 2 mm of the goal after the goal is reachable again, and from when
    on it stays within 2 mm until the walk ends (s after re-entry)."""
    nearest = np.empty_like(goal)
    beyond = _distance_to_reach(get_limb(arm, "hand"), goal, FREE_READY_ARM_RAD[arm], nearest)
    out = beyond > 1e-3
    excursion = np.array([np.min(np.linalg.norm(goal[np.abs(t - ti) <= 1.0] - a, axis=1))
                          for ti, a in zip(t, actual, strict=True)])
    error = np.linalg.norm(goal - actual, axis=1)
    back_in = t[np.nonzero(out)[0][-1]]          # the goal is reachable again
    after = (t > back_in) & (t <= walk_end_s)
    within = after & (error < 0.002)
    outside = t[after & (error >= 0.002)]
    parked = out & (t >= t[np.argmax(goal[:, 0])] + 1.0)  # from 1 s after the goal turns
    return {"parked_m": float(np.max(np.linalg.norm(actual - nearest, axis=1)[parked])),
            "excursion_m": float(np.max(excursion - beyond)),
            "first_s": t[within][0] - back_in if within.any() else np.inf,
            "stays_s": (outside[-1] - back_in if len(outside) else 0.0)}


@pytest.mark.physical
def test_a_walk_out_of_reach_stops_at_the_boundary_and_comes_back(tmp_path):
    """Each hand walks forward to 30 cm beyond its reach (3 s), waits, walks back (8 s: the
    elbow has to bend by 1.3 rad on the way back, at most 1 rad/s and 0.8 rad/s^2).

    While the goal is out of reach the hand parks near the goal's nearest reachable point; as
    the goal heads back the hand leads it (teleop/reach_lead.py). The goal comes back into
    reach at about 90 mm/s. tools/reach_return_bound.py (an ideal elbow alone): reacting,
    back within 2 mm 1.88 s after re-entry at best; knowing the goal's future and never more
    than 10 mm ahead of its nearest reachable point, 0.90 s. Measured here (the same on both
    code paths, AVX-512 / portable): parked within 9.8 / 10.0 mm (left / right hand) of the
    nearest reachable point (4.7 mm without the lead), first within 2 mm 2.29 / 2.28 s and
    within 2 mm for good 2.28 / 2.27 s after re-entry (2.34 / 2.33 s before a returning hand
    far behind met the goal's prediction with its measured decay, teleop/reach_lead.
    RETURN_DECAY_S; 2.44 s before the goal back in reach was led and
    followed while slowed, teleop/target._led_back; 2.39 s before the arms' joints were traded,
    teleop/trade.py; 2.45 s before the arms' tracker met the goal's prediction,
    teleop/lead.tracking_target), excursion 11.5 / 11.5 mm beyond the goal's own (11.9 / 11.5
    mm before the measured decay, 10.2 / 10.7 mm before the return's lead, 20.1 / 20.6 mm
    before the trade). The parked figure's largest is 15 ms before re-entry
    (the goal 1.2 mm out), the hand 9-10 mm off the nearest point across the goal's path
    whatever the lead's cap (5 / 6 / 8 / 10 mm: 10.0 / 9.8 / 10.6 / 10.0 mm): the issue's 10
    mm is not met with a margin, nor its 0.5 s / 1.8 s (docs/history/teleop.md). With and
    without the lead, at three speeds: the next test."""
    model = load_model()
    offset, walk_end_s = _walk_beyond_reach(("right-arm", "left-arm"), 8.0)
    src = _stream(tmp_path / "walk.csv", offset, walk_end_s + 1.0)
    targets = []
    run = run_teleop(TeleopSettings(replay=src, driver="ideal", out=tmp_path / "run"),
                     on_ready=lambda target, loop: targets.append(target))
    assert run.summary["ended"] == "done"
    console = Console(width=240, record=True, file=io.StringIO())
    for hand in targets[0].hands.values():   # the live view's reach column renders
        console.print(_reach_cell(hand))
    assert console.export_text().count("ok") == 2
    log = load_log(run.run_dir)
    for arm, key in (("right-arm", "r"), ("left-arm", "l")):
        report = run.summary["reach"][arm]
        assert report["branch_changes"] == 0 and report["at_limit_s"] > 2.0
        t, goal, actual = _operate(log, key)
        got = _return_figures(arm, t - t[0], goal, actual, walk_end_s)
        assert got["parked_m"] <= 0.015, got        # measured 9.8-10.0 mm: bound 1.5x
        # measured 11.55-11.87 mm (the same on both code paths; 10.2-10.7 mm before the
        # return's lead): bound 1.36x, kept from before (the 15 mm at the next test)
        assert got["excursion_m"] <= 0.0161, got
    q_cmd = log.joints("cmd")
    index = [model.joint_names.index(j) for j in log.joint_names]
    lower = np.concatenate([model.limb(n).lower_rad for n in ("right-arm", "left-arm")])
    upper = np.concatenate([model.limb(n).upper_rad for n in ("right-arm", "left-arm")])
    arm_cols = [index.index(model.joint_names.index(j)) for n in ("right-arm", "left-arm")
                for j in model.limb(n).joints]
    assert np.all(q_cmd[:, arm_cols] >= lower - 1e-9) and np.all(q_cmd[:, arm_cols] <= upper + 1e-9)


def _follow_walk(tmp_path, back_s: float, lead: bool) -> dict:
    """The right hand's out-of-reach walk, walked back in ``back_s``, followed by the teleop
    target and the trajectory generator alone (stream_runs.follow_input), with its reach lead
    or without (the lead's cap set to zero): :func:`_return_figures`."""
    from hubo_cli.input.opener import open_input
    from hubo_cli.teleop.stream_runs import follow_input

    def no_lead(target, t_s):
        for reach_lead in target.leads.values():
            reach_lead.lead_m = 0.0

    arm = "right-arm"
    offset, walk_end_s = _walk_beyond_reach((arm,), back_s)
    src = _stream(tmp_path / "walk.csv", offset, walk_end_s + 1.0)
    with open_input(replay=src) as device:
        target, commands, ended, _ = follow_input(device, TeleopSettings(replay=src),
                                                  walk_end_s + 1.0, None if lead else no_lead)
    assert ended == "done" and commands.finite and commands.limit_excess_rad <= 1e-9
    assert commands.max_step_ratio <= 1.0 + 1e-6
    assert target.hands[arm].branch_changes == 0
    t = np.asarray(target.path_times_s[arm])
    goal, actual = (np.array([p[k] for p in target.paths[arm]]) for k in (0, 1))
    return _return_figures(arm, t - t[0], goal, actual, walk_end_s)


@pytest.mark.physical
@pytest.mark.parametrize("back_s", [8.0, 16.0, 32.0])
def test_the_lead_brings_the_hand_back_sooner_and_closer_at_three_speeds(tmp_path, back_s):
    """The out-of-reach walk of the right hand, walked back at full, half and a quarter of its
    speed (the goal back in reach at 90, 45 and 22 mm/s), with the reach lead and, at the two
    faster speeds, without it in the same test. tools/reach_return_bound.py's floors for an
    ideal elbow: reacting, first within 2 mm 1.88 / 1.57 / 1.20 s and within 2 mm for good
    2.30 / 1.86 / 1.30 s; knowing the goal's future within the 10 mm lead, 0.90 / 0.10 /
    0.00 s.
    Measured (the same to 0.1 mm and 0.01 s on both code paths, AVX-512 / portable, but the
    lasting 2 mm at half speed, 2.32 / 2.29 s: the issue's figures are asserted where met), with
    / without the lead, at full / half / quarter speed: parked within 10.0 / 4.7, 6.8 / 3.4, 5.4
    mm of the nearest reachable point; first within 2 mm 2.28 / 2.69, 0.35 / 0.09, 0.42 s after
    re-entry (at half and a quarter the goal passes the parked hand without the lead); within 2
    mm for good 2.27, 2.29-2.32, 2.60 s with the lead (2.34, 2.60-2.63, 2.66 s before a
    returning hand far behind met the goal's prediction with its measured decay,
    teleop/reach_lead.RETURN_DECAY_S, and then 2.68, 2.95 s without the lead; 2.45, 2.82, 2.85 s
    before the goal back in reach was led and followed while slowed, teleop/target._led_back;
    2.39, 2.76, 2.85 s before the arms' joints were traded, teleop/trade.py; 2.46, 3.14, 3.49 s
    before the arms' tracker met the goal's prediction, teleop/lead.tracking_target); excursion
    11.5 / 15.4, 11.3 / 15.3, 6.0 mm (10.7, 12.3, 6.0 mm before the return's lead; 20.6, 18.9,
    8.1 mm before the trade). After re-entry the elbow, near straight, bends at its 0.8 rad/s^2
    from the speed the lead gave it while the goal's elbow bends at 1.2 rad/s (half speed), then
    plans to stop at the goal and creeps up on it (docs/history/teleop.md, round 9)."""
    got = _follow_walk(tmp_path, back_s, lead=True)
    if back_s > 8.0:
        assert got["parked_m"] <= 0.010, got          # the 10 mm
        assert got["first_s"] <= 0.5, got             # the 0.5 s
    else:
        assert got["parked_m"] <= 0.015, got          # not the issue's: 1.5x 10.0 mm
    assert got["excursion_m"] <= 0.015, got           # the 15 mm
    # not the 1.8 s: measured 2.27 / 2.32 / 2.60 s (both code paths; 2.34 / 2.60-2.63
    # / 2.66 s before a returning hand far behind met the goal's prediction with its measured
    # decay, reach_lead.RETURN_DECAY_S; 2.45 / 2.82 / 2.85 s before teleop/target._led_back),
    # over 13 walks of 7-32 s and 20-40 cm 2.04-2.63 s (docs/history/teleop.md, round 10)
    assert got["stays_s"] <= (2.45 if back_s == 16.0 else 2.8), got
    if back_s == 32.0:
        return  # (without the lead, compared at the two faster speeds: this stream is the longest)
    without = _follow_walk(tmp_path, back_s, lead=False)
    # the lead shortens the excursion (by 3.9-4.0 mm), and never delays the lasting 2 mm by
    # more than 4 periods (0.34-0.35 s sooner)
    assert got["excursion_m"] < without["excursion_m"] - 0.001, (got, without)
    assert got["stays_s"] <= without["stays_s"] + 0.02, (got, without)


def test_the_lead_follows_a_goal_heading_back_only():
    """teleop/reach_lead.py: the goal's velocity is exact for a goal at constant velocity (from
    half a window on, with the input's uneven sample times); the lead is where the goal will
    be 0.12 s later, at most 10 mm, zero for a goal slower than 10 mm/s or faster than 0.2 m/s;
    out of reach, it grows from nothing 1.2 s before the predicted re-entry to all of it at
    re-entry, and is zero for a goal passing by or moving away."""
    from hubo_cli.teleop.reach_lead import ReachLead

    rng = np.random.default_rng(5)
    v = np.array([-0.09, 0.02, 0.01])
    lead = ReachLead()
    assert lead.velocity_m_s() is None
    for t in np.cumsum(rng.uniform(0.004, 0.02, 40)):
        lead.push(t, np.array([0.5, -0.2, -0.2]) + v * t)
    assert np.allclose(lead.velocity_m_s(), v, atol=1e-9)
    assert lead.lead_m_of(0.05) == pytest.approx(0.05 * 0.12)
    assert lead.lead_m_of(0.15) == 0.010
    assert lead.lead_m_of(0.005) == 0.0 and lead.lead_m_of(0.3) == 0.0
    out = -v / np.linalg.norm(v)      # the goal beyond the reach along this, heading back
    speed = np.linalg.norm(v)
    assert lead.run_up_share(v, out * speed * 1.3) == 0.0          # back in 1.3 s
    assert lead.run_up_share(v, out * speed * 0.6) == pytest.approx(0.25)
    assert lead.run_up_share(v, out * 1e-9) == pytest.approx(1.0)
    side = np.cross(v, [0.0, 0.0, 1.0])                  # passing by, moving away
    assert lead.run_up_share(v, side * 0.01 / np.linalg.norm(side)) == 0.0
    assert lead.run_up_share(v, -out * 0.01) == 0.0
    lead.clear()
    assert lead.velocity_m_s() is None


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_goal_not_finite_is_not_led(bad):
    """A NaN or inf among the goal's recent positions gives no velocity, and a goal not finite
    gives no lead (the target stays on the nearest reachable pose it was given)."""
    from hubo_cli.teleop.reach_lead import ReachLead
    from hubo_cli.teleop.target import TeleopTarget

    arm = "right-arm"
    limb = get_limb(arm, "hand")
    reach = ArmReach(limb)
    q_near = np.array(FREE_READY_ARM_RAD[arm])
    reach.start(q_near)
    T_near = limb.fk(q_near)
    v = np.array([-0.09, 0.0, 0.0])                 # heading back, 10 mm out of reach
    T_goal = T_near.copy()
    T_goal[:3, 3] += [0.01, 0.0, 0.0]
    lead = ReachLead()
    for i in range(30):
        p = T_goal[:3, 3] - v * (29 - i) * 0.005
        if i == 25:
            p[2] = bad
        lead.push(i * 0.005, p)
    assert lead.velocity_m_s() is None
    assert TeleopTarget._led(reach, lead, T_goal, T_near, q_near, q_near)[1] is False
    lead.clear()
    for i in range(30):
        lead.push(i * 0.005, T_goal[:3, 3] - v * (29 - i) * 0.005)
    assert np.allclose(lead.velocity_m_s(), v)
    q_led, led = TeleopTarget._led(reach, lead, T_goal, T_near, q_near, q_near)
    assert led and not np.array_equal(q_led, q_near)   # finite: led
    T_bad = T_goal.copy()
    T_bad[0, 3] = bad
    q_out, led = TeleopTarget._led(reach, lead, T_bad, T_near, q_near, q_near)
    assert led is False and q_out is q_near


def test_a_goal_back_in_reach_is_led_until_the_hand_has_caught_up():
    """A goal back in reach from beyond it, still moving (teleop/target._led_back,
    reach_lead.ReachLead.back_lead_m): the target leads it along its velocity by the lead
    (0.12 s of its motion, at most 10 mm) until it has passed the hand, then by no more than
    the hand lags behind it, and not at all once the hand is level or ahead, or the lag is not
    finite; a goal slower than 10 mm/s, or no longer closing in on the shoulder, ends the
    return (the goal's own joints)."""
    from hubo_cli.teleop.reach_lead import ReachLead
    from hubo_cli.teleop.target import HandTrack, TeleopTarget

    arm = "right-arm"
    limb = get_limb(arm, "hand")
    reach = ArmReach(limb)
    q_goal = np.array(FREE_READY_ARM_RAD[arm])
    reach.start(q_goal)
    T_goal = limb.fk(q_goal)
    rng = np.random.default_rng(11)
    for trial in range(6):
        v = rng.normal(size=3)
        v *= rng.uniform(0.04, 0.15) / np.linalg.norm(v)
        if v @ (T_goal[:3, 3] - limb.T_N_base[:3, 3]) > 0.0:
            v = -v  # closing in on the shoulder, as a goal coming back into reach
        speed = float(np.linalg.norm(v))
        lead = ReachLead()
        for i in range(30):
            lead.push(i * 0.005, T_goal[:3, 3] - v * (29 - i) * 0.005)
        full_m = min(0.010, 0.12 * speed)
        lag_m = rng.uniform(0.0005, 0.004)
        cases = ((False, -0.003, full_m), (True, lag_m, min(lag_m, full_m)),
                 (True, -0.001, 0.0), (True, np.nan, 0.0))
        for passed, behind_m, expect_m in cases:
            hand = HandTrack(returning=True, passed=passed)
            hand.goal_m = np.zeros(3)
            hand.actual_m = -v / speed * behind_m
            q, led = TeleopTarget._led_back(reach, hand, lead, T_goal, q_goal, q_goal)
            moved = limb.fk(q)[:3, 3] - T_goal[:3, 3]
            assert led == (expect_m > 0.0) and hand.returning, (trial, passed, behind_m)
            assert np.all(np.isfinite(q))
            # within the reach search's tolerance of the led position (0.1 mm)
            assert np.linalg.norm(moved - v / speed * expect_m) < 1e-4, (trial, moved)
    slow = ReachLead()
    for i in range(30):
        slow.push(i * 0.005, T_goal[:3, 3] + [0.005 * i * 0.005, 0.0, 0.0])  # 5 mm/s
    hand = HandTrack(returning=True)
    q, led = TeleopTarget._led_back(reach, hand, slow, T_goal, q_goal, q_goal)
    assert q is q_goal and not led and not hand.returning
    outward = ReachLead()  # 0.1 m/s away from the shoulder, toward the straight elbow
    away = T_goal[:3, 3] - limb.T_N_base[:3, 3]
    away *= 0.1 / np.linalg.norm(away)
    for i in range(30):
        outward.push(i * 0.005, T_goal[:3, 3] - away * (29 - i) * 0.005)
    hand = HandTrack(returning=True)
    q, led = TeleopTarget._led_back(reach, hand, outward, T_goal, q_goal, q_goal)
    assert q is q_goal and not led and not hand.returning


def test_a_joint_a_hair_inside_its_margin_does_not_stop_the_nearest_pose_search():
    """The right arm parked with its elbow 0.4 mrad inside the straight-elbow margin (where a
    walk out of reach left it) and the goal coming back to 23 mm beyond reach: the search's step
    pushes the elbow outward, the step clipped at the margin does not lower the cost, and the
    search used to stop there (the hand stayed 85 mm from the goal, parked for seconds while the
    goal came in). Holding the clipped joint, the other joints move: one call of the arm's
    10 steps brings the hand within a few mm of the distance to the reachable set."""
    limb = get_limb("right-arm", "hand")
    q = np.array([-1.213955, -0.052615, 0.139303, -0.100536, 0.00121, 0.040255])
    margin = ReachSettings().elbow_margin
    assert 0.0 < abs(q[3]) - np.arcsin(margin) < 1e-3          # just inside the margin
    T_goal = limb.fk(q)
    T_goal[:3, 3] = [0.4487, -0.2490, -0.2279]                  # neck frame, m
    beyond = _distance_to_reach(limb, [T_goal[:3, 3]], FREE_READY_ARM_RAD["right-arm"])[0]
    assert 0.015 < beyond < 0.035
    reach = ArmReach(limb)
    reach.start(q)
    result = reach.solve(T_goal, q)
    assert result.status == "nearest"
    assert result.position_error_m - beyond < 0.005, result.position_error_m
    assert abs(np.sin(result.q_rad[3])) >= margin - 1e-9        # the elbow kept its margin


@pytest.mark.physical
@pytest.mark.parametrize("scaled", [True, False])
def test_a_sweep_along_the_straight_elbow_is_slowed_only_with_the_scale(tmp_path, scaled):
    """The right hand's goal goes 3 cm beyond its reach straight ahead (the arm parks with the
    elbow straight, at its margin), sweeps 20 cm sideways and back in 1.6 s there, and returns.
    In the singular neighbourhood (condition number at or above the hard threshold) the arm's
    joints stay at or below half their speed limits with the speed scale, and go clearly above
    without it (the sweep needs them), so the scale is what keeps them there."""
    arm = "right-arm"
    limb = get_limb(arm, "hand")
    ready = limb.fk(np.array(FREE_READY_ARM_RAD[arm]))[:3, 3]
    ahead = np.linspace(0.0, 0.3, 301)
    edge = ahead[np.argmax(_distance_to_reach(limb, ready + np.outer(ahead, [1, 0, 0]),
                                              FREE_READY_ARM_RAD[arm]) > 1e-4)]

    def offset(name, t):
        if name != arm:
            return np.zeros(3)
        out = _min_jerk((t - 1.0) / 1.5) - _min_jerk((t - 4.6) / 1.5)
        sideways = _min_jerk((t - 2.5) / 0.8) - _min_jerk((t - 3.3) / 0.8)
        return np.array([(edge + 0.03) * out, -0.2 * sideways, 0.0])

    src = _stream(tmp_path / "sweep.csv", offset, 7.6)
    scale = SingularityScale() if scaled else SingularityScale.off()
    run = run_teleop(TeleopSettings(replay=src, driver="ideal", out=tmp_path / "run",
                                    reach=ReachSettings(singularity=scale)))
    assert run.summary["ended"] == "done" and not run.summary["estop_events"]
    log = load_log(run.run_dir)
    model = load_model()
    cols = [log.joint_names.index(j) for j in model.limb(arm).joints]
    q = log.joints("cmd")[:, cols]
    speed_ratio = np.abs(np.diff(q, axis=0)) / model.control_period_s / limb.spec.velocity_rad_s
    kappa = np.array([condition_number(limb, qi) for qi in q[1:]])
    near = kappa >= SingularityScale().hard
    assert near.sum() > 200                         # it did stay in the singular neighbourhood
    fastest = np.max(speed_ratio[near])
    # measured 0.480 with the scale, 0.752 without, on both code paths (AVX-512 / portable): the
    # scale's own cap of half the limit holds by construction, and without the scale the
    # joints exceed that cap by 1.5x
    if scaled:
        assert fastest <= 0.5, fastest
    else:
        assert fastest > 0.5, fastest
    assert run.summary["reach"][arm]["branch_changes"] == 0
    # the last period the target ran (a smooth-stop ramp after it logs no goal)
    last = np.flatnonzero(np.isfinite(log["goal_x_m_r"]))[-1]
    end = [np.array([log[f"{kind}_{c}_m_r"][last] for c in "xyz"]) for kind in ("goal", "actual")]
    assert np.linalg.norm(end[0] - end[1]) < 0.002   # and came back onto the goal at the end


def test_the_missing_part_is_named_in_words():
    assert _direction([0.02, 0.0, -0.02]) == "fwd-down"
    assert _direction([0.0, -0.03, 0.001]) == "right"


def test_collision_room_keeps_targets_out_of_the_band_and_slides_along_it():
    """The right arm's target rolls in toward the torso and pelvis (RSR 0 -> 0.3 rad, through
    the body from 0.12 rad on) while it swings forward (RSP 0 -> -0.6 rad): every returned
    target keeps the room, and the forward swing goes on along the band (it slides, it does
    not stop where it met it). Without the room the last target would be 22 mm inside the body."""
    from hubo_cli.control.collision import SelfCollisionChecker
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.room import ROOM_M, CollisionRoom

    model = load_model()
    room = CollisionRoom(model, arms=("right-arm",))
    checker = SelfCollisionChecker(model)
    q0 = home_posture(model)
    assert checker.check(q0).distance_m > ROOM_M
    q_prev, clear, out = q0.copy(), [], []
    for s in np.linspace(0.0, 1.0, 200):
        goal = q0.copy()
        goal[1], goal[0] = 0.3 * min(1.0, 2 * s), -0.6 * s
        q_prev = room.keep(q_prev, goal)
        clear.append(checker.check(q_prev).distance_m)
        out.append(q_prev.copy())
        assert np.array_equal(q_prev[6:], goal[6:])        # the other joints as asked
    out = np.array(out)
    assert min(clear) >= ROOM_M - 1e-4
    assert checker.check(goal).distance_m < -0.02
    assert room.pushed_periods["right-arm"] > 150
    assert out[-1, 0] < -0.55 and 0.0 < out[-1, 1] < 0.1   # swung on, rolled in only so far


def test_collision_room_finite_differences_are_those_of_every_near_pair():
    """Where the witness points give no gradient, the room's forward differences check each
    posture only for the pairs that could come closer than the closest pair can move: on drawn
    arm postures within NEAR_M of the room, the same gradient to the last bit as with every
    pair within NEAR_M checked, from fewer pairs computed."""
    from hubo_cli.teleop import room as room_module
    from hubo_cli.teleop.room import NEAR_M, CollisionRoom

    class EveryNearPair(CollisionRoom):
        def _distance(self, q_rad, near_m=NEAR_M, arm=None):
            return super()._distance(q_rad, arm=arm)

    model = load_model()
    rng = np.random.default_rng(43)
    rooms = [CollisionRoom(model), EveryNearPair(model)]
    computed = [0, 0]
    for room in rooms:
        room.checker.distance_gradient = lambda *args: None  # the differences, always
        check_near = room.checker.check_near

        def counted(q, band_m, pairs=None, room=room, check_near=check_near):
            answer = check_near(q, band_m, pairs)
            computed[rooms.index(room)] += int(room.checker._near.sum())
            return answer

        room.checker.check_near = counted
    q0 = rooms[0]._index["right-arm"]
    compared = 0
    while compared < 40:
        q = np.zeros(len(model.joint_names))
        q[q0] = rng.uniform(model.lower_rad[q0], model.upper_rad[q0])
        answers = [room._distance(q) for room in rooms]
        assert answers[0] == answers[1]
        d, pair = answers[0]
        if not -0.01 < d < room_module.ROOM_M + NEAR_M or not rooms[0]._arms_of(pair):
            continue
        index = np.concatenate([rooms[0]._index[a] for a in rooms[0]._arms_of(pair)])
        gradients = [room._gradient(q, d, pair, index) for room in rooms]
        assert np.array_equal(gradients[0], gradients[1]), compared
        compared += 1
    assert computed[0] < 0.7 * computed[1]  # measured: 1298 against 2433 pairs (0.53)


def test_collision_room_with_the_goal_reaches_inward_positions_with_the_hand_turned():
    """The right hand's goal moves 10 cm inward (toward the chest's midline) from the free-mode
    ready pose, orientation fixed. From 4-6 cm inward the goal's exact IK puts the upper arm
    into the torso (the shoulder roll moves it in; -28 mm at 8 cm); without the goal the room
    pushes the target back along the clearance and the hand stays out (65 mm short, measured).
    With the goal, the clear search keeps the room and reaches the position by turning the
    hand (measured 0.1 mm short, turned 15 deg: position first; bounds 20 mm and 1 mm)."""
    from hubo_cli.control.collision import SelfCollisionChecker
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.room import ROOM_M, CollisionRoom

    model = load_model()
    limb = get_limb("right-arm", "hand")
    sl = model.limb_slice("right-arm")
    reach = ArmReach(limb, ReachSettings())
    q0 = home_posture(model)
    q0[sl] = FREE_READY_ARM_RAD["right-arm"]
    q0[model.limb_slice("left-arm")] = FREE_READY_ARM_RAD["left-arm"]
    reach.start(q0[sl])
    T0 = limb.fk(q0[sl])
    checker = SelfCollisionChecker(model)
    results = {}
    for with_goal in (False, True):
        room = CollisionRoom(model, arms=("right-arm",))
        q = q0.copy()
        for s in np.linspace(0.0, 1.0, 400):
            T = T0.copy()
            T[1, 3] += 0.10 * min(1.0, 2 * s)  # inward in 200 periods, then 200 to settle
            q_next = q.copy()
            q_next[sl] = reach.solve(T, q[sl]).q_rad
            q = room.keep(q, q_next, {"right-arm": (reach, T)} if with_goal else None)
            assert checker.check(q).distance_m >= ROOM_M - 1e-4
        results[with_goal] = np.linalg.norm(limb.fk(q[sl])[:3, 3] - T[:3, 3])
    assert results[False] > 0.02, results   # the push alone holds the hand out
    assert results[True] < 0.001, results   # the clear search reaches the position


def _both_hands_inward(room, periods=300):
    """Both hands' goals 10 cm inward (toward the chest's midline) from the free-mode ready
    pose in 200 periods, then still, each arm's exact IK solution through ``room.keep``: per
    call the checks it made (coal distances and witness gradients), the target's clearance
    (an independent checker) and the hands' final distances to their goals (m)."""
    from hubo_cli.control.collision import SelfCollisionChecker
    from hubo_cli.posture import home_posture

    model = room.model
    q = home_posture(model)
    reach, T0, sl = {}, {}, {}
    for arm in room.arms:
        sl[arm] = model.limb_slice(arm)
        q[sl[arm]] = FREE_READY_ARM_RAD[arm]
        reach[arm] = ArmReach(get_limb(arm, "hand"), ReachSettings())
        reach[arm].start(q[sl[arm]])
        T0[arm] = reach[arm].limb.fk(q[sl[arm]])
    checker = SelfCollisionChecker(model)
    made = [0]

    def counting(call):
        def counted(*args):
            made[0] += 1
            return call(*args)
        return counted

    for name in ("check_near", "distance_gradient"):
        setattr(room.checker, name, counting(getattr(room.checker, name)))
    checks, clearance = [], []
    for s in np.linspace(0.0, 1.0, periods):
        goals, q_next = {}, q.copy()
        for arm in room.arms:
            T = T0[arm].copy()
            T[1, 3] += (1.0 if arm == "right-arm" else -1.0) * 0.10 * min(1.0, 1.5 * s)
            q_next[sl[arm]] = reach[arm].solve(T, q[sl[arm]]).q_rad
            goals[arm] = (reach[arm], T)
        made[0] = 0
        q = room.keep(q, q_next, goals)
        checks.append(made[0])
        clearance.append(checker.check(q).distance_m)
    short = {arm: float(np.linalg.norm(reach[arm].limb.fk(q[sl[arm]])[:3, 3] - T[:3, 3]))
             for arm, (_, T) in goals.items()}
    return np.array(checks), np.array(clearance), short


def test_collision_room_searches_each_arm_against_the_pairs_it_moves():
    """Both hands' goals move 10 cm inward: each arm's exact IK puts its upper arm 28 mm into
    the torso. An arm's clear search steps against the closest of the pairs its joints move:
    the other arm's target, deep in the torso, is a pair it cannot change. Searched against
    that pair (before round 16) a step saw a zero gradient (forward differences on
    overlapping shapes) and the same clearance whatever it did, the search walked its own arm
    into the body and the push and bisection after it brought it back: both hands stayed 75 mm
    short of their goals. Now each reaches its goal's position with the hand turned (0.3 mm
    short, measured; bound 1 mm), with at most 23 checks a call (coal distance passes and
    witness gradients; bound 30; main made 33 distance passes alone), and every target keeps
    the room."""
    from hubo_cli.teleop.room import ROOM_M, CollisionRoom

    room = CollisionRoom(load_model(), arms=("right-arm", "left-arm"))
    searched = []
    gradient = room._gradient

    def recorded(q, d, pair, index, *args):
        searched.append(bool(room.checker.rate_m_rad[room._pair_index[pair], index].any()))
        return gradient(q, d, pair, index, *args)

    room._gradient = recorded
    checks, clearance, short = _both_hands_inward(room)
    assert len(searched) > 100 and all(searched)  # every gradient of a pair the joints move
    assert clearance.min() >= ROOM_M - 1e-4
    assert max(short.values()) < 0.001, short
    assert checks.max() <= 30, checks.max()


def test_collision_room_holds_the_last_target_when_its_checks_run_out(monkeypatch):
    """The room's work per call is bounded: a search or Newton step, or the bisection, starts
    only if the most it can take fits in what is left of MAX_CHECKS checks, and a call that
    cannot afford the bisection holds the arms at the last target. Both hands moving inward
    (above) with a budget of 8 checks: no call makes more, every call in the band holds the
    last target (measured 235 of 300), and every target keeps the room."""
    from hubo_cli.teleop import room as room_module
    from hubo_cli.teleop.room import ROOM_M, CollisionRoom

    room = CollisionRoom(load_model(), arms=("right-arm", "left-arm"))
    monkeypatch.setattr(room_module, "MAX_CHECKS", 8)
    checks, clearance, _ = _both_hands_inward(room)
    assert checks.max() <= 8, checks.max()
    assert room.held > 100 and room.held == room.short
    assert clearance.min() >= ROOM_M - 1e-4


@pytest.mark.physical
def test_a_hand_the_room_moves_keeps_the_detectors_look_ahead_out_of_its_band(tmp_path):
    """The right hand's goal moves 12 cm inward in 0.6 s (its exact IK into the torso), then
    10 cm down in 0.8 s: the collision room slides the arm's target round the body. The
    pipeline's detector holds the arms when the command, or its way to where it would stop if
    it braked now, comes within 10 mm of the body (computed here as the detector does, from
    the trajectory generator's state each period). Before round 17 the target slid up to 0.2
    rad ahead of the lagging command, whose unsynchronised way cut inside the band: 7.9 mm,
    a hold (seed 3409 held twice so). Now the target leads the command by at most
    room.LEAD_RAD on the straight way toward the searched pose, tracked phase synchronised:
    21.7 mm (bound 12.5 mm)."""
    import math

    from hubo_cli.control.collision import (
        MAX_SAMPLES,
        SAMPLE_RAD,
        TOLERANCE_M,
        SelfCollisionChecker,
    )
    from hubo_cli.control.keys import TRACKER_STATES
    from hubo_cli.input.opener import open_input
    from hubo_cli.motion.limits import braking_distance
    from hubo_cli.teleop.stream_runs import follow_input

    def offset(arm, t):
        if arm != "right-arm":
            return np.zeros(3)
        return np.array([0.0, 0.12 * _min_jerk((t - 0.2) / 0.6),
                         0.10 * _min_jerk((t - 0.8) / 0.8)])

    model = load_model()
    checker = SelfCollisionChecker(model)
    sl = model.limb_slice("right-arm")
    ahead = []

    def look_ahead(target, t_s):
        states = target.store.get(TRACKER_STATES)
        if not states or target.phase != "operate":
            return
        q = target.q_out.copy()
        for arm in ("right-arm", "left-arm"):
            q[model.limb_slice(arm)] = states[arm].q_rad
        s = states["right-arm"]
        stop = s.limits.clip(s.q_rad + braking_distance(s.v_rad_s, s.a_rad_s2, s.limits))
        travel = float(np.abs(stop - s.q_rad).max())
        n = min(MAX_SAMPLES, max(1, math.ceil(travel / SAMPLE_RAD)))
        for k in range(n + 1):
            q[sl] = s.q_rad + (stop - s.q_rad) * (k / n)
            ahead.append(checker.check(q).distance_m)

    src = _stream(tmp_path / "inward.csv", offset, 1.7)
    with open_input(replay=src) as device:
        target, commands, ended, _ = follow_input(device, TeleopSettings(replay=src), 1.7,
                                                  look_ahead)
    assert ended == "done" and commands.finite and commands.limit_excess_rad <= 1e-9
    assert min(ahead) > TOLERANCE_M + 0.0025, min(ahead)
    assert target.room.led > 50  # the room led the arm from its command


def test_the_two_hand_capture_delivers_the_pose_logs_stream_period_by_period():
    """The shipped two-hand sample's raw FASTRAK capture and its pose log are the same operator:
    read by the control period (5 ms) from the same input class, each period delivers the same
    hands' poses in the same order, the same flags, times within 1 us and positions within
    1 um (measured 0.42 us and 0.50 um: the pose log's six decimals), rotations within 1e-6
    (measured 1.1e-7). So the next test's run of the pose log is the capture's run as well
    (the whole run's paths differed by 0.0001 mm when both were run, 11.8 s of CPU each)."""
    from hubo_cli.input.opener import open_input
    from hubo_cli.resources import data_file

    with (open_input(replay=data_file("trajectories", "two-hand-free.csv")) as log,
          open_input(replay=data_file("trajectories", "two-hand-free.fastrak")) as capture):
        assert type(log) is type(capture) and log.hands == capture.hands == ("right", "left")
        assert capture.recorded_s == pytest.approx(log.recorded_s, abs=1e-6)
        k = delivered = 0
        while not (log.done and capture.done):
            t_s = k * 0.005
            k += 1
            ours, theirs = log.read_until(t_s), capture.read_until(t_s)
            assert [p.hand for p in ours] == [p.hand for p in theirs], t_s
            for a, b in zip(ours, theirs, strict=True):
                assert (a.reliable, a.engaged) == (b.reliable, b.engaged), t_s
                assert abs(a.t_s - b.t_s) < 1e-6, t_s
                assert np.abs(a.position_m - b.position_m).max() < 1e-6, t_s
                assert np.abs(a.T_operator_hand[:3, :3]
                              - b.T_operator_hand[:3, :3]).max() < 1e-6, t_s
                delivered += 1
        assert delivered == log.stats()["good_records"] == capture.stats()["good_records"] == 2880


@pytest.mark.physical
@pytest.mark.slow
def test_the_two_hand_sample_keeps_up_with_the_operator(tmp_path):
    """The shipped two-hand sample (its raw FASTRAK capture; its pose log delivers the same
    stream, the test above) through the CLI (``hubo teleop --replay ... --json``) in free mode
    on the simulated robot: both hands reported, no joint beyond its speed limit, no stop, the
    input's latency within 10 ms (3.80 ms p99 on both code paths, AVX-512 / portable: 2.6x);
    each arm on its own trajectory generator
    (its joints unsynchronised unless that swings the hand off the straight line to the target, the
    arms' jerk limit 40 rad/s^3 of the robot file's teleop limit set) keeps each hand within 7.5 mm
    RMS of the operator's goal and within 14 mm of the goal's path (measured 5.7-6.5 mm RMS,
    12.8-13.3 mm max excursion on both code paths, AVX-512 / portable, free mode's 0.8 s orientation
    filter; 11.4-11.7 mm with the 1 s filter; 11.8 mm RMS with one phase-synchronised tracker for
    the body at 4 rad/s^3; 15.5 mm excursion on the capture with a switch on the joints' lag), and
    the goal passing 6 mm from the torso slides the arm along the collision band instead of tripping
    a hold. (Round 18, this capture through the CLI: RMS 5.85 / 6.25 mm and 5.70 / 6.29 mm
    right / left, excursion 5.92 / 6.45 mm on both, AVX-512 / portable; the pose log's run
    5.70 / 6.48 mm, 6.58 / 6.72 mm. The CLI's own test ran the capture's first 5 s again until
    then, test_teleop.py.)

    The RMS bound is 1.5x the worst measured (10.5 mm, short of the synchronised tracker's
    11.8). The excursion's stays at 14 mm, 1.05x: 1.5x (19 mm) would pass the 15.5 mm of the
    switch it is there to catch; the two code paths differ by up to 0.3 mm on it (the right
    hand's, in the collision room's slide), the 0.7 mm left 2.3x that."""
    import json

    from click.testing import CliRunner

    from hubo_cli.cli.main import main
    from hubo_cli.resources import data_file

    result = CliRunner().invoke(main, ["teleop", "--replay",
                                       str(data_file("trajectories", "two-hand-free.fastrak")),
                                       "--out", str(tmp_path / "run"), "--json"])
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert s["ended"] == "done" and not s["estop_events"] and not s["collision_holds"]
    assert s["collision_periods"] == 0
    assert set(s["rms_error_mm"]) == {"right-arm", "left-arm"}
    assert s["max_joint_velocity_ratio"] <= 1.0 + 1e-9
    assert s["latency_ms"]["p99"] < 10.0
    for arm in ("right-arm", "left-arm"):
        report = s["reach"][arm]
        assert report["position_rms_mm"] <= 10.5, report
        assert report["max_excursion_mm"] <= 14.0, report
        assert report["branch_changes"] == 0
        assert 0.2 < report["collision_room_s"] < 5.0, report   # the room did the work


def test_free_mode_runs_the_teleop_limits_and_a_tracker_per_arm_drill_mode_does_not(tmp_path):
    """Free mode: the robot file's ``teleop`` limit set (the arms' jerk 40 rad/s^3, the rest
    the robot's) and a trajectory-generator tracker per limb; drill mode: the robot's own
    limits (4 rad/s^3) and one tracker for the whole body."""
    from hubo_cli.teleop.session import prepare, teleop_setup

    robot = load_model()
    for mode, limits, groups, arm_jerk in (("free", "teleop", "limbs", 40.0),
                                           ("drill", "table4", "body", 4.0)):
        settings = TeleopSettings(replay=tmp_path / "x.csv", mode=mode)
        model, body, _, _ = prepare(settings)
        assert model.limits_name == limits
        setup = teleop_setup(settings, body, None)
        assert setup.model is model and setup.safety.tracker_groups == groups
        for arm in ("right-arm", "left-arm"):
            assert np.all(model.limb(arm).jerk_rad_s3 == arm_jerk)
        legs = model.limb_slice("right-leg").start
        assert np.array_equal(model.jerk_rad_s3[legs:], robot.jerk_rad_s3[legs:])
        assert np.array_equal(model.acceleration_rad_s2, robot.acceleration_rad_s2)
        assert np.array_equal(model.velocity_rad_s, robot.velocity_rad_s)


def test_free_modes_orientation_filter_is_faster_only_while_the_arm_follows_freely():
    """Free mode smooths the orientation over FREE_ORIENTATION_TIME_CONSTANT_S while the arm
    follows its goal freely and has for FREE_ORIENTATION_HOLD_S, over the slower time constant
    from the period its goal is relaxed (reach limit, collision room); drill mode always over
    the slower one. A 30 deg turn of the goal is followed faster while free."""
    from scipy.spatial.transform import Rotation

    from hubo_cli.kinematics.arm_reach import (
        FREE_ORIENTATION_HOLD_S,
        FREE_ORIENTATION_TIME_CONSTANT_S,
    )

    dt = 0.005
    limb = get_limb("right-arm")
    free, drill = (ArmReach(limb, ReachSettings.for_mode(mode)) for mode in ("free", "drill"))
    slow = free.settings.orientation_time_constant_s
    assert FREE_ORIENTATION_TIME_CONSTANT_S < slow == drill.settings.orientation_time_constant_s
    assert free.time_constant_s(dt, True) == FREE_ORIENTATION_TIME_CONSTANT_S
    assert drill.time_constant_s(dt, True) == slow
    assert free.time_constant_s(dt, False) == slow
    held = [free.time_constant_s(dt, True)
            for _ in range(2 * round(FREE_ORIENTATION_HOLD_S / dt))]
    first_fast = held.index(FREE_ORIENTATION_TIME_CONSTANT_S)
    assert abs(first_fast * dt - FREE_ORIENTATION_HOLD_S) <= 1.5 * dt
    assert set(held[first_fast:]) == {FREE_ORIENTATION_TIME_CONSTANT_S}

    T0, T1 = np.eye(4), np.eye(4)
    T1[:3, :3] = Rotation.from_rotvec(np.radians([0.0, 0.0, 30.0])).as_matrix()
    lag_deg = {}
    for follows in (True, False):
        reach = ArmReach(limb, ReachSettings.for_mode("free"))
        reach.smoothed(T0, dt, follows)
        for _ in range(round(0.5 / dt)):
            T = reach.smoothed(T1, dt, follows)
        lag_deg[follows] = np.degrees(Rotation.from_matrix(T[:3, :3].T @ T1[:3, :3]).magnitude())
    # first order: 30 deg x exp(-0.5 s / tau)
    assert lag_deg[True] == pytest.approx(30 * np.exp(-0.5 / FREE_ORIENTATION_TIME_CONSTANT_S),
                                          rel=0.01)
    assert lag_deg[False] == pytest.approx(30 * np.exp(-0.5 / slow), rel=0.01)


def test_the_live_views_reachable_share_and_errors_are_the_reports():
    """The live view's running figures (per hand: the share of the time so far that the goal
    was reachable, the position and orientation RMS over it) end as the run's report gives
    them; a generated stream that goes out of reach and back, followed by the target."""
    from hubo_cli.cli.teleop import _reachable_cell
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.teleop.stream_runs import follow_generated

    seen = {}
    run = follow_generated(3409, StreamSettings(duration_s=3.0),
                           observe=lambda target, t_s: seen.setdefault("target", target))
    hands = seen["target"].hands
    assert all(0.0 < figures["reachable_share"] < 1.0 for figures in run.hands.values())
    for arm, figures in run.hands.items():
        share, position_mm, rotation_deg = hands[arm].reachable_so_far()
        assert share == pytest.approx(figures["reachable_share"], abs=1e-12)
        assert position_mm == pytest.approx(figures["reachable_position_rms_mm"], rel=1e-9)
        assert rotation_deg == pytest.approx(figures["reachable_orientation_rms_deg"], rel=1e-9)
        assert _reachable_cell(hands[arm]) == (f"{share:.0%}  {position_mm:.1f} mm  "
                                               f"{rotation_deg:.1f} deg")
