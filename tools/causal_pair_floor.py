"""A lower bound for causal controllers on generated operator streams, from pairs that part.

Take a generated stream (A) and, at the start t0 of one of a hand's moves, a *twin* (B) the
generator can produce as well: the same gestures and the same noise up to t0, then another
gesture (``pause``: the hand rests instead; ``no-turn``: the same stroke with the orientation
kept; ``no-move``: the same turn with the position kept), then a rest to the end. A controller
that knows only the past gets the same input on both until the first input sample that
differs, at t_p, so its joints are the same on both up to t_p, and with their velocities: from
there each joint's acceleration limit (the teleop model's, ``load_model(limits="teleop")``)
bounds how far the two arms can part. The floor is a lower bound of

    max(E_pre + E_A, E_pre + E_B)

(E: the sum over the reachable control periods of the squared hand error, E_pre over the
``PRE_S`` before t_p that both share, E_A and E_B over the ``POST_S`` after it) over every pair
of joint trajectories that agree up to t_p and keep every joint's acceleration within the
limit. Every causal controller's pair is one such, so on A or on B it pays at least the floor,
and its RMS over that run's reachable time is at least sqrt(floor / N), N the larger of the two
runs' reachable period counts. Why it is a lower bound (each step can only lower it):

- max(x, y) >= lam x + (1 - lam) y for every lam in [0, 1]: the floor is the largest such
  relaxation over a golden-section search of lam (each lam tried is itself a bound);
- the joints are known only at nodes ``NODE_S`` apart (shared up to the node at t_p, each
  branch's own after), with every second difference within a H^2 (what |q''| <= a implies) and
  the first node's position and velocity free; no speed, jerk or position limit, no latency;
- between nodes the joints are taken on the nodes' straight line: a trajectory within the limit
  is within a H^2 theta (1 - theta) / 2 of it (theta the share of the way between the nodes,
  at most a H^2 / 8), which moves the weighted error vector by at most eta (the Jacobians'
  column norms times that); the floor subtracts eta from the root of the cost;
- the node problem (a bounded least squares) is solved by L-BFGS-B and its value certified by
  convexity: the cost at the solver's point plus the least its gradient's linear model reaches
  over the box, below the true minimum whatever the solver's accuracy;
- the errors outside the window and the other hand's are left out.

The one approximation: the hand's error is linearised about the goal's joints, J(q*) (q - q*),
as the round-4 floors of ``tools/teleop_lag_floor.py`` (first order in the error; the floors
are a few millimetres, the joints' share of that is milliradians). The goal's joints are the
exact IK of each run's goals (``teleop_lag_floor.generated_goals``); each twin goes through the
same ``follow_input`` as the stream, so main's figures on the twin are a check too: a floor
above max(main on A, main on B) would be a bug.

Three floors per pair: position alone (m), orientation alone (rad), and the weighted one
(position^2 + w^2 rotation^2, w = 10 mm / 3 deg): a hand within both of issue 34's targets on
a run has its weighted mean at most 2 (10 mm)^2, so a weighted floor above that says no causal
controller meets both targets on A and on B.

    python tools/causal_pair_floor.py [--streams 50 | --seeds 1634:25] [--first SEED,SEED,...]

(Measured in round 21, docs/history/teleop.md: too weak to decide issue 34's figure.)
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import minimize
from teleop_lag_floor import TARGET_POSITION_M, TARGET_ROTATION_RAD, generated_goals

from hubo_cli.input.operator_stream import (
    RATE_HZ,
    HandStream,
    StreamSettings,
    _Gestures,
    finish_stream,
)
from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.reach import jacobian

PRE_S = 0.3    # the shared past counted before the parting
POST_S = 0.5   # the window after it, on each branch
NODE_S = 0.025  # the joints' nodes (second differences bounded) this far apart
W_ROT_M = TARGET_POSITION_M / TARGET_ROTATION_RAD
FLOORS = {"position": (1.0, 0.0), "orientation": (0.0, 1.0), "weighted": (1.0, W_ROT_M)}
"""Each floor's weights on the error's position rows (m) and rotation rows (rad)."""


def pair_cost_floor(t_s, t_part, J_pre, q_pre, J_a, q_a, J_b, q_b, accel, lam,
                    node_s=NODE_S):
    """A certified lower bound of min (E_pre + lam E_A + (1 - lam) E_B) over joint
    trajectories that agree up to ``t_part`` with every joint's acceleration within ``accel``
    (rad/s^2, per joint), the errors linear: E = sum over samples of |J (q(t) - q*)|^2.

    ``t_s`` = (times before or at t_part, times after it on A, after it on B) (s); ``J_*``
    (n, r, 6) the weighted Jacobians at those samples (rows with zero weight left out), ``q_*``
    (n, 6) the goal's joints there. See the module docstring for the relaxations."""
    t_pre, t_a, t_b = (np.asarray(t, float) for t in t_s)
    accel = np.broadcast_to(np.asarray(accel, float), (6,))
    k_pre = max(1, int(np.ceil((t_part - min(t_pre.min(initial=t_part), t_part)) / node_s - 1e-9)))
    t_last = max(t_a.max(initial=t_part), t_b.max(initial=t_part))
    m_post = max(1, int(np.ceil((t_last - t_part) / node_s - 1e-9)))
    n_shared = k_pre - 1                     # second differences s_1 .. s_{k_pre - 1}
    blocks = 2 + n_shared + 2 * m_post       # q0, v, shared s, A's s, B's s

    def node_rows(branch: int) -> np.ndarray:
        """Per node i (0 at t_part - k_pre H) its position's coefficients on the blocks."""
        rows = np.zeros((k_pre + m_post + 1, blocks))
        for i in range(len(rows)):
            rows[i, 0], rows[i, 1] = 1.0, i
            for j in range(1, i):
                col = 1 + j if j < k_pre else 2 + n_shared + branch * m_post + (j - k_pre)
                rows[i, col] = i - j
        return rows

    def sample_rows(t, branch):
        x = (np.asarray(t) - (t_part - k_pre * node_s)) / node_s
        i = np.clip(np.floor(x).astype(int), 0, k_pre + m_post - 1)
        theta = (x - i)[:, None]
        nodes = node_rows(branch)
        return (1 - theta) * nodes[i] + theta * nodes[i + 1], (theta * (1 - theta))[:, 0]

    parts = [(*sample_rows(t_pre, 0), J_pre, q_pre, 1.0),
             (*sample_rows(t_a, 0), J_a, q_a, lam), (*sample_rows(t_b, 1), J_b, q_b, 1.0 - lam)]
    A_rows, b_rows, eta2 = [], [], 0.0
    for coef, between, J, q, weight in parts:
        if not len(coef) or weight <= 0:
            continue
        w = np.sqrt(weight)
        A_rows.append(w * np.einsum("nb,nrj->nrbj", coef, J).reshape(-1, 6 * blocks))
        b_rows.append(w * np.einsum("nrj,nj->nr", J, q).ravel())
        # a joint within the limit is within a H^2 theta (1 - theta) / 2 of its nodes' line
        eps = 0.5 * node_s**2 * between[:, None] * accel[None, :]
        eta2 += weight * float(np.sum(np.einsum("nj,nj->n", np.linalg.norm(J, axis=1), eps)
                                      ** 2))
    beta = np.tile(accel * node_s**2, blocks - 2)
    root = np.sqrt(_box_ls_floor(np.vstack(A_rows), np.concatenate(b_rows), 12, beta))
    return max(0.0, root - np.sqrt(eta2)) ** 2


def _box_ls_floor(A, b, n_free, beta) -> float:
    """A certified lower bound of min |A x - b|^2 over x whose first ``n_free`` entries are
    free and the others within +-``beta``: L-BFGS-B on the problem with the free entries solved
    out (normal equations: LAPACK's QR crawls on a loaded machine), then by convexity the cost
    at its point plus the least the gradient's linear model reaches over the box."""
    Af, Ab = A[:, :n_free], A[:, n_free:]
    H, g = A.T @ A, A.T @ b
    Hff_inv = np.linalg.pinv(H[:n_free, :n_free])
    S = H[n_free:, n_free:] - H[n_free:, :n_free] @ Hff_inv @ H[:n_free, n_free:]
    g_red = g[n_free:] - H[n_free:, :n_free] @ Hff_inv @ g[:n_free]
    x = minimize(lambda x: (0.5 * x @ S @ x - g_red @ x, S @ x - g_red), np.zeros(len(beta)),
                 jac=True, method="L-BFGS-B", bounds=list(zip(-beta, beta, strict=True)),
                 options={"maxiter": 20000, "ftol": 1e-15, "gtol": 1e-14}).x
    xf = Hff_inv @ (g[:n_free] - H[:n_free, n_free:] @ x)
    xf -= Hff_inv @ (Af.T @ (Af @ xf + Ab @ x - b))  # one refinement on the residual
    r = Af @ xf + Ab @ x - b
    grad = 2 * Ab.T @ r
    return max(0.0, float(r @ r - beta @ np.abs(grad) - grad @ x))


def minmax_floor(*args, tol: float = 0.08) -> float:
    """The largest :func:`pair_cost_floor` over lam (golden-section search; every lam tried is
    a bound of the min-max)."""
    g = (np.sqrt(5) - 1) / 2
    lo, hi = 0.0, 1.0
    seen = {}

    def f(lam):
        if lam not in seen:
            seen[lam] = pair_cost_floor(*args, lam)
        return seen[lam]

    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    while hi - lo > tol:
        if f(a) >= f(b):
            hi, b = b, a
            a = hi - g * (hi - lo)
        else:
            lo, a = a, b
            b = lo + g * (hi - lo)
    return max(seen.values())


class _LoggedGestures(_Gestures):
    """The generator's gestures, each stroke and hold logged (sample index, state before,
    arguments) so that a twin can replay them up to one and go its own way there."""

    def __init__(self, hand, settings, rng):
        super().__init__(hand, settings, rng)
        self.calls = []

    def _stroke(self, p_to, r_to, speed_m_s, engaged=True):
        self.calls.append(("stroke", self.n, self.p.copy(), self.r.copy(),
                           (np.asarray(p_to, float), np.asarray(r_to, float), speed_m_s,
                            engaged)))
        super()._stroke(p_to, r_to, speed_m_s, engaged)

    def _hold(self, seconds, engaged=True):
        self.calls.append(("hold", self.n, self.p.copy(), self.r.copy(), (seconds, engaged)))
        super()._hold(seconds, engaged)


def _in_box(p, settings, inward) -> bool:
    lo, hi = np.array(settings.box_m).T
    return bool(np.all((lo - 1e-12 <= p * [1, inward, 1]) & (p * [1, inward, 1] <= hi + 1e-12)))


def twins(hand: str, seed: int, settings: StreamSettings):
    """The hand's stream of ``seed`` and its twins: (stream, [(label, parting time (s),
    twin stream), ...]), one twin per alternative at each engaged move from a point of the
    gesture box to another (the clutch's and the beyond-reach strokes left out). A twin whose
    past differs from the stream's (the speed stretch) is left out."""
    n = int(settings.duration_s * RATE_HZ) + 1
    rng = np.random.default_rng([int(seed), ("right", "left").index(hand)])
    gestures = _LoggedGestures(hand, settings, rng)
    gestures.build(n)
    state = rng.bit_generator.state

    def finish(offset, rotvec, engaged):
        twin_rng = np.random.default_rng()
        twin_rng.bit_generator.state = state
        return finish_stream(hand, settings, twin_rng, offset, rotvec, engaged)

    def replay(calls, tail):
        g = _Gestures(hand, settings, None)
        for kind, _, _, _, args in calls:
            (g._stroke if kind == "stroke" else g._hold)(*args)
        tail(g)
        g._hold(settings.duration_s)  # rests to the end (pauses one after another)
        p, r, engaged = (np.concatenate(x)[:n] for x in zip(*g.pieces, strict=True))
        return finish(p, r, engaged)

    stream = replay(gestures.calls, lambda g: None)
    out = []
    for k, (kind, start, p0, r0, args) in enumerate(gestures.calls):
        if kind != "stroke" or not args[3] or start >= n - 1:
            continue
        p_to, r_to, speed, _ = args
        if not (_in_box(p0, settings, gestures.inward) and _in_box(p_to, settings,
                                                                    gestures.inward)):
            continue
        alternatives = {"pause": lambda g: None}
        if np.linalg.norm(r_to - r0) > 1e-9:
            alternatives["no-turn"] = lambda g, a=args: g._stroke(a[0], g.r, a[2])
            if np.linalg.norm(p_to - p0) > 1e-9:
                alternatives["no-move"] = lambda g, a=args: g._stroke(g.p, a[1], a[2])
        for label, tail in alternatives.items():
            twin = replay(gestures.calls[:k], tail)
            differs = np.any(np.abs(twin.T_operator_hand - stream.T_operator_hand) > 0,
                             axis=(1, 2))
            if not differs.any() or np.argmax(differs) < start:
                continue  # no parting, or a past that differs (the stretch)
            out.append((label, float(twin.t_s[np.argmax(differs)]), twin))
    return stream, out


def _source(streams: list[HandStream], seed: int, settings: StreamSettings):
    from hubo_cli.input.device import HandPose, RecordedInput

    poses = [HandPose(s.hand, s.T_operator_hand[i], float(s.t_s[i]), engaged=bool(s.engaged[i]))
             for s in streams for i in range(len(s.t_s))]
    return RecordedInput(poses, {"kind": "generated twin", "seed": int(seed),
                                 "max_speed_m_s": settings.max_speed_m_s,
                                 "duration_s": settings.duration_s})


def _window(t, q, ok, jac, lo, hi):
    keep = ok & (t > lo) & (t <= hi)
    return t[keep], jac[keep], q[keep]


def hand_pair_floors(arm, t_part, goals_a, goals_b, n_periods, accel, pre_s=PRE_S,
                     post_s=POST_S) -> dict[str, float]:
    """Per floor (``FLOORS``) the RMS every causal controller reaches or exceeds on A or on B:
    sqrt(the min-max floor / n_periods), in mm for position and the weighted one, deg for
    orientation."""
    limb = get_limb(arm, "hand")
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T, J = np.empty((4, 4)), np.empty((6, 6))

    def jacobians(q):
        out = np.empty((len(q), 6, 6))
        for i, qi in enumerate(q):
            jacobian(np.ascontiguousarray(qi), base, offset, alpha, a, d, end, T, J)
            out[i] = J
        return out

    (ta, qa, oka), (tb, qb, okb) = goals_a, goals_b
    n = min(len(ta), len(tb))
    if not np.allclose(ta[:n], tb[:n]):
        raise ValueError("the stream's and the twin's periods differ")
    shared = ta[:n] <= t_part
    if not (np.allclose(qa[:n][shared], qb[:n][shared], atol=1e-9)
            and np.array_equal(oka[:n][shared], okb[:n][shared])):
        raise ValueError("the twin's goals differ before the parting")
    Ja, Jb = jacobians(qa), jacobians(qb)
    out = {}
    for name, (wp, wr) in FLOORS.items():
        scale = np.r_[np.full(3, wp), np.full(3, wr)]
        rows = scale > 0
        Jwa, Jwb = ((Jx * scale[None, :, None])[:, rows] for Jx in (Ja, Jb))
        pre = _window(ta, qa, oka, Jwa, t_part - pre_s, t_part + 1e-12)
        post_a = _window(ta, qa, oka, Jwa, t_part + 1e-12, t_part + post_s)
        post_b = _window(tb, qb, okb, Jwb, t_part + 1e-12, t_part + post_s)
        floor = minmax_floor((pre[0], post_a[0], post_b[0]), t_part, pre[1], pre[2], post_a[1],
                             post_a[2], post_b[1], post_b[2], accel)
        rms = np.sqrt(floor / n_periods)
        out[name] = float(np.degrees(rms)) if name == "orientation" else 1e3 * float(rms)
    return out


def stream_pair_floors(seed: int, settings: StreamSettings, accel=None) -> list[dict]:
    """Per hand and twin of the stream of ``seed``: the parting, the three floors, and the
    run's (main's) figures on the stream and on the twin."""
    from hubo_cli.model import load_model

    model = load_model(limits="teleop")
    streams = {hand: twins(hand, seed, settings) for hand in ("right", "left")}
    hands_a, goals_a = generated_goals(seed, settings)
    rows = []
    for hand, (_, pairs) in streams.items():
        arm = f"{hand}-arm"
        if arm not in goals_a:
            continue
        a_max = model.limb(arm).acceleration_rad_s2 if accel is None else accel
        for label, t_part, twin in pairs:
            both = [twin if s.hand == hand else streams[s.hand][0]
                    for s in (streams["right"][0], streams["left"][0])]
            hands_b, goals_b = generated_goals(seed, settings, _source(both, seed, settings))
            if arm not in goals_b:
                continue
            n = max(hands_a[arm]["reachable_periods"], hands_b[arm]["reachable_periods"])
            if n == 0:
                continue
            floors = hand_pair_floors(arm, t_part, goals_a[arm], goals_b[arm], n, a_max)
            rows.append({"seed": seed, "arm": arm, "twin": label, "t_part": t_part, **floors,
                         **{f"run_{k}_{x}": hands[arm][f"reachable_{k}_rms_{u}"]
                            for x, hands in (("a", hands_a), ("b", hands_b))
                            for k, u in (("position", "mm"), ("orientation", "deg"))}})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=50,
                        help="the first N of tests/test_teleop_streams.py's draw")
    parser.add_argument("--seeds", default=None,
                        help="RNG:COUNT: instead, COUNT seeds drawn by default_rng(RNG)")
    parser.add_argument("--first", default="",
                        help="comma-separated seeds of the draw to take first (the worst hands)")
    parser.add_argument("--speed", type=float, default=0.25, help="hand speed cap (m/s)")
    parser.add_argument("--duration", type=float, default=1.5, help="stream length (s)")
    args = parser.parse_args()
    from hubo_cli.teleop.stream_runs import GENERATED_SEEDS

    if args.seeds:
        rng, count = (int(x) for x in args.seeds.split(":"))
        seeds = np.random.default_rng(rng).integers(0, 2**31, count).tolist()
    else:
        seeds = GENERATED_SEEDS[:args.streams]
    first = [int(x) for x in args.first.split(",") if x]
    seeds = [x for x in first if x in seeds] + [x for x in seeds if x not in first]
    settings = StreamSettings(duration_s=args.duration, max_speed_m_s=args.speed)
    for seed in seeds:
        for r in stream_pair_floors(seed, settings):
            print(f"seed {r['seed']} {r['arm']} {r['twin']} at {r['t_part']:.3f} s: floor "
                  f"{r['position']:.2f} mm, {r['orientation']:.2f} deg, weighted "
                  f"{r['weighted']:.2f} mm; run A {r['run_position_a']:.2f} / "
                  f"{r['run_orientation_a']:.2f}, B {r['run_position_b']:.2f} / "
                  f"{r['run_orientation_b']:.2f}", flush=True)


if __name__ == "__main__":
    main()
