"""Kinematics figures: closed-form IK per call and batched, against pinocchio's DLS IK."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.arm_reach import ArmReach

DLS_TOL = 1e-6      # pinocchio baseline converged when the 6-D log error is below this
DLS_MAX_ITERS = 1000


def _dls_solver(limb):
    """Damped-least-squares IK with pinocchio on the URDF, reduced to the limb's joints."""
    import pinocchio as pin

    full = pin.buildModelFromUrdf(str(limb.model.urdf_path()))
    keep = set(limb.spec.joints)
    lock = [full.getJointId(n) for n in full.names[1:] if n not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full))
    data = model.createData()
    frame = model.getFrameId({"drill": "right_drill_bit", "hand": "right_hand"}[limb.tool])
    idx = [model.joints[model.getJointId(n)].idx_q for n in limb.spec.joints]

    def solve(T_goal: np.ndarray, q0: np.ndarray) -> tuple[bool, int]:
        oMdes = pin.SE3(T_goal[:3, :3], T_goal[:3, 3])
        q = np.zeros(model.nq)
        q[idx] = q0
        for it in range(DLS_MAX_ITERS):
            pin.framesForwardKinematics(model, data, q)
            iMd = data.oMf[frame].actInv(oMdes)
            err = pin.log(iMd).vector
            if np.linalg.norm(err) < DLS_TOL:
                return True, it
            J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
            J = -pin.Jlog6(iMd.inverse()) @ J
            v = -J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), err)
            q = pin.integrate(model, q, v * 0.5)
        return False, DLS_MAX_ITERS

    return solve


def _bench_batch_csv(report, limb) -> None:
    rng = np.random.default_rng(2)
    header = ",".join(f"T{i}{j}" for i in range(4) for j in range(4))
    with tempfile.TemporaryDirectory() as tmp:
        for n in (1_000, 200_000, 1_000_000):  # the first run only fills the compile cache
            T = limb.fk_batch(limb.random_q(rng, n)).reshape(n, 16)
            src, out = Path(tmp) / f"in-{n}.csv", Path(tmp) / f"out-{n}.csv"  # new files
            np.savetxt(src, T, delimiter=",", header=header, comments="", fmt="%.12g")
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "hubo_cli.cli.main", "ik", limb.name,
                            "--tool", limb.tool, "--batch", str(src), "--out", str(out)],
                           check=True, capture_output=True)
            seconds = time.perf_counter() - t0
            if n > 1_000:
                report(f"hubo ik --batch, {n:,} rows end to end", n / seconds, "rows/s",
                       f"{seconds:.2f} s incl. ~0.4 s start-up; target >= 200,000")


def _bench_reach(report, rng) -> None:
    """One teleop IK call on the arm's branch: exact, or the nearest-pose fallback (median)."""
    limb = get_limb("right-arm", "hand")
    reach = ArmReach(limb)
    q_ready = np.array([0.0, -0.15, 0.0, -1.4, 0.0, 0.0])
    reach.start(q_ready)
    T0 = limb.fk(q_ready)
    goals = []
    for offset in rng.uniform(-0.25, 0.25, size=(2000, 3)):  # about half out of reach
        T = T0.copy()
        T[:3, 3] += offset
        goals.append(T)
    reach.solve(goals[0], q_ready)  # compile / load the numba cache outside the timing
    times = {"exact": [], "nearest": []}
    for T in goals:
        t0 = time.perf_counter()
        result = reach.solve(T, q_ready)
        times[result.status].append(time.perf_counter() - t0)
    for status, label in (("exact", "exact on the branch"), ("nearest", "nearest-pose fallback")):
        if times[status]:
            report(f"teleop IK, one call, {label} (median)", np.median(times[status]) * 1e6,
                   "us/call", f"target <= 25; {len(times[status])} of {len(goals)} goals")


def run(report) -> None:
    limb = get_limb("right-arm", "drill")
    rng = np.random.default_rng(1)
    limb.solve(limb.fk(np.zeros(6)))  # compile / load the numba cache outside the timing

    Q = limb.random_q(rng, 20_000)
    T = limb.fk_batch(Q)
    q_seed = np.clip(Q + rng.normal(0, 0.05, Q.shape), limb.lower_rad, limb.upper_rad)
    exact = 0
    t0 = time.perf_counter()
    for i in range(len(Q)):
        exact += limb.solve(T[i], q_seed[i]).exact
    per_call_us = (time.perf_counter() - t0) / len(Q) * 1e6
    report("closed-form IK, one call (8 candidates + choice)", per_call_us, "us/call",
           "target <= 25")

    _bench_reach(report, rng)

    n = 1_000_000
    Qb = limb.random_q(rng, n)
    Tb = limb.fk_batch(Qb)
    limb.solve_batch(Tb[:1000])
    t0 = time.perf_counter()
    batch = limb.solve_batch(Tb)
    per_pose_ns = (time.perf_counter() - t0) / n * 1e9
    failures = int(np.sum(batch.status != 0))
    report("closed-form IK, batched over 1,000,000 poses", per_pose_ns, "ns/pose",
           f"target <= 1,000; {failures} not exact (all reachable)")

    solve_dls = _dls_solver(limb)
    m = 300
    for label, seeds in (("seeded near (teleop)", q_seed[:m]), ("from zero", np.zeros((m, 6)))):
        ok = 0
        t0 = time.perf_counter()
        for i in range(m):
            ok += solve_dls(T[i], seeds[i])[0]
        dls_us = (time.perf_counter() - t0) / m * 1e6
        report(f"pinocchio DLS IK to {DLS_TOL:g}, {label}", dls_us, "us/call",
               f"success {ok / m:.1%}")
        target = 3 if "seeded" in label else 10
        report(f"  closed form faster than DLS {label}", dls_us / per_call_us, "x",
               f"target >= {target}x; closed form exact on {exact}/{len(Q)}")
    _bench_batch_csv(report, limb)

