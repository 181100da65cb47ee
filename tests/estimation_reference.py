"""A recorded sequence of sensor readings and the estimate the estimation layer made of it: the
check that a faster estimation layer still gives the same numbers (tests/test_estimation_
reference.py).

``tests/data/estimation_reference.npz`` holds

* the inputs: the first 421 states of the simulated robot walking 0.2 m forward
  (``hubo walk --to 0.2 0 0 --perturb-seed 3``: the perturbation's IMU noise and biases, two
  single supports, the anchor passed back and forth at the touchdown, a sole rolling on its
  edge); the readings are the sensors' (time, joints, IMU, the four force-torque sensors);
* the outputs: every estimate key of every period, flattened (:func:`estimate_rows`), as the
  estimation layer computed them when the file was written, on those states with the bad
  readings of :func:`states` put in (NaN, out of range, wrong lengths, lists, a clock that
  jumps, a second reset).

When the estimation's logic changes on purpose, write the outputs again from the stored inputs
(``python tests/estimation_reference.py``, from the repository with it on ``PYTHONPATH``) and
say why in the commit; ``--record`` records the inputs again from the simulator (about
two minutes of CPU).
"""

from __future__ import annotations

import copy
import sys
from pathlib import Path

import numpy as np

from hubo_cli.estimation.build import build_estimator
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    ESTIMATE_KEYS,
    GYRO_BIAS,
    IMU_REJECTED,
    OMEGA_TORSO,
    QUAT_WORLD_TORSO,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
    ZMP_WORLD,
)
from hubo_cli.model import load_model
from hubo_cli.state import FT_SENSORS, RobotState

DATA = Path(__file__).parent / "data" / "estimation_reference.npz"
PERIODS = 421
TOOLS = {"right-arm": "drill"}  # the drill's mass beyond the right wrist and in the CoM
RESET_AT = 400  # the estimator starts again from this period's state

# the estimate's keys in the rows' order, each flattened to this many numbers
WIDTHS = {CONTACT: 2, WRENCHES: 6 * len(FT_SENSORS), QUAT_WORLD_TORSO: 4, GYRO_BIAS: 3,
          OMEGA_TORSO: 3, IMU_REJECTED: 2, T_WORLD_TORSO: 16, T_WORLD_SOLES: 32, COM_WORLD: 3,
          COM_VELOCITY_WORLD: 3, CAPTURE_POINT_WORLD: 2, ZMP_WORLD: 2}
assert set(WIDTHS) == set(ESTIMATE_KEYS)


def states(data) -> list[RobotState]:
    """The recorded states with bad readings put in at fixed periods (each a path of the
    layer's input checks)."""
    out = []
    for k in range(len(data["time_s"])):
        out.append(RobotState(
            time_s=float(data["time_s"][k]), q_rad=data["q_rad"][k].copy(),
            dq_rad_s=np.zeros(data["q_rad"].shape[1]), imu_quat_wxyz=data["quat"][k].copy(),
            imu_gyro_rad_s=data["gyro"][k].copy(), imu_accel_m_s2=data["accel"][k].copy(),
            ft={name: data["ft"][k, i].copy() for i, name in enumerate(FT_SENSORS)}))
    out[30].q_rad[3] = np.nan  # a joint not finite: the legs' kinematics hold
    out[31].q_rad = out[31].q_rad.tolist()  # a list: as good as an array
    out[32].q_rad = out[32].q_rad[:-1]  # one joint short
    out[40].imu_gyro_rad_s[1] = np.nan
    out[41].imu_accel_m_s2 = out[41].imu_accel_m_s2 * 50.0  # beyond the sensor's range
    out[42].imu_gyro_rad_s = tuple(out[42].imu_gyro_rad_s.tolist())
    out[43].imu_accel_m_s2 = [1.0, 2.0]  # not three numbers
    out[44].imu_gyro_rad_s = out[44].imu_gyro_rad_s * 1e4  # beyond the sensor's range
    out[50].ft["right-ankle"] = out[50].ft["right-ankle"][:5]  # not six numbers
    del out[51].ft["left-wrist"]
    out[52].ft["left-ankle"] = [int(round(v)) for v in out[52].ft["left-ankle"]]
    out[53].ft["right-wrist"] = np.full(6, np.inf)
    out[54].ft["right-ankle"] = "garbled"
    out[60].time_s = out[59].time_s - 0.5  # the clock runs back
    out[61].time_s = np.nan
    out[62].time_s = "not a time"
    out[90].time_s += 1.0  # a second lost: everything after is shifted
    for state in out[91:]:
        state.time_s += 1.0
    out[330].imu_accel_m_s2 = out[330].imu_accel_m_s2 + np.array([4.0, 0.0, 0.0])  # a jolt
    for state in out[70:74]:  # the right ankle's encoder off: its sole reads tilted 5 deg,
        state.q_rad[16] += 0.08  # beyond what the filter expects (its gate)
    out[RESET_AT].imu_quat_wxyz = np.full(4, np.nan)  # the reset's heading: none
    return out


def estimate_rows(sequence: list[RobotState], model=None) -> np.ndarray:
    """Every period's estimate (reset on the first state and on ``RESET_AT``'s), one row of
    the keys of :data:`WIDTHS` flattened in order."""
    model = model or load_model()
    estimator = build_estimator(model, TOOLS, model.control_period_s)
    rows = np.empty((len(sequence), sum(WIDTHS.values())))
    for k, state in enumerate(sequence):
        store = estimator.reset(state) if k in (0, RESET_AT) else estimator.update(state)
        row = []
        for key in WIDTHS:
            value = store[key]
            if key is WRENCHES:
                value = [value[name] for name in FT_SENSORS]
            row.append(np.asarray(value, dtype=float).reshape(-1))
        rows[k] = np.concatenate(row)
    return rows


def record(model) -> dict[str, np.ndarray]:
    """The inputs: the sensors' readings of the first ``PERIODS`` states of the simulated walk
    (two minutes of CPU)."""
    from hubo_cli.drivers.sim import SimDriver
    from hubo_cli.experiments.walk import walk

    recorded = []
    start, step = SimDriver.start, SimDriver.step

    def recording(method):
        def wrapped(self, *args, **kwargs):
            state = method(self, *args, **kwargs)
            if len(recorded) < PERIODS:
                recorded.append(copy.deepcopy(state))
            return state
        return wrapped

    SimDriver.start, SimDriver.step = recording(start), recording(step)
    try:
        walk(model, (0.2, 0.0, 0.0), perturb_seed=3, out="/tmp/estimation-reference-walk")
    finally:
        SimDriver.start, SimDriver.step = start, step
    return {"time_s": np.array([s.time_s for s in recorded]),
            "q_rad": np.array([s.q_rad for s in recorded]),
            "quat": np.array([s.imu_quat_wxyz for s in recorded]),
            "gyro": np.array([s.imu_gyro_rad_s for s in recorded]),
            "accel": np.array([s.imu_accel_m_s2 for s in recorded]),
            "ft": np.array([[s.ft[name] for name in FT_SENSORS] for s in recorded])}


def main(argv: list[str]) -> None:
    model = load_model()
    if "--record" in argv:
        inputs = record(model)
    else:
        with np.load(DATA) as data:
            inputs = {name: data[name] for name in data.files if name != "expected"}
    expected = estimate_rows(states(inputs), model)
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, expected=expected, **inputs)
    print(f"{DATA}: {len(expected)} periods, {expected.shape[1]} numbers each")


if __name__ == "__main__":
    main(sys.argv[1:])
