"""hubo-ach's structures against include/hubo.h (hubo-ach 0.1.20131101, late-2013 develop).

The expected sizes and offsets below are the header's figures: its packed fields summed by hand
(double 8, int16 2, int8/uint8 1; HUBO_JOINT_COUNT 42, HUBO_JMC_COUNT 0x36, HUBO_IMU_COUNT 3).
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.hardware import HardwareDriver, read_ref_frames
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

MODEL = load_model()

SIZES = {
    hubo_ach.HuboImu: 48, hubo_ach.HuboFt: 24, hubo_ach.HuboJointState: 59,
    hubo_ach.HuboJointStatus: 17, hubo_ach.HuboJmcState: 8, hubo_ach.HuboPower: 24,
    hubo_ach.HuboRef: 462, hubo_ach.HuboState: 3898,
}
OFFSETS = {
    hubo_ach.HuboRef: {"ref": 0, "mode": 336, "comply": 420},
    hubo_ach.HuboState: {"imu": 0, "ft": 144, "joint": 240, "status": 2718, "driver": 3432,
                         "power": 3864, "time": 3888, "refWait": 3896},
    hubo_ach.HuboJointState: {"ref": 0, "comply": 8, "pos": 9, "cur": 17, "vel": 25, "duty": 33,
                              "heat": 41, "tmp": 49, "active": 57, "zeroed": 58},
    hubo_ach.HuboImu: {"a_x": 0, "a_y": 8, "a_z": 16, "w_x": 24, "w_y": 32, "w_z": 40},
    hubo_ach.HuboFt: {"m_x": 0, "m_y": 8, "f_z": 16},
    hubo_ach.HuboJointStatus: {"driverOn": 0, "homeFlag": 4, "jam": 5, "motorFail1": 11,
                               "posMinError": 12, "tempError": 16},
}


@pytest.mark.parametrize("struct", list(SIZES), ids=lambda s: s.__name__)
def test_struct_sizes_equal_the_header(struct):
    assert ctypes.sizeof(struct) == SIZES[struct]
    assert np.dtype(struct).itemsize == SIZES[struct]


@pytest.mark.parametrize("struct", list(OFFSETS), ids=lambda s: s.__name__)
def test_field_offsets_equal_the_header(struct):
    for name, offset in OFFSETS[struct].items():
        assert getattr(struct, name).offset == offset, name


def test_constants_and_joint_indices_equal_the_header():
    assert (hubo_ach.JOINT_COUNT, hubo_ach.JMC_COUNT, hubo_ach.REF_FILTER_LENGTH) == (42, 54, 40)
    assert (hubo_ach.CHAN_REF, hubo_ach.CHAN_STATE) == ("hubo-ref", "hubo-state")
    assert hubo_ach.LOOP_PERIOD_S == MODEL.control_period_s == 0.005
    assert MODEL.hubo_ach["ref_filter_length"] == hubo_ach.REF_FILTER_LENGTH
    index = MODEL.hubo_ach["index"]
    header = {"RSP": 11, "RSR": 12, "RSY": 13, "REB": 14, "RWY": 15, "RWP": 17, "LSP": 4,
              "LEB": 7, "LWP": 10, "RHY": 26, "RKN": 29, "RAR": 31, "LHY": 19, "LKN": 22,
              "LAR": 24}
    assert {n: index[n] for n in header} == header


def test_a_reference_packed_by_the_driver_decodes_field_by_field(tmp_path):
    sink = tmp_path / "hubo-ref.bin"
    q = home_posture(MODEL)
    reb = MODEL.joint_names.index("REB")
    with HardwareDriver(MODEL, armed=True, sink="file", sink_path=sink,
                        ref_mode=hubo_ach.MODE_REF) as driver:
        driver.start(q)
        q[reb] -= 0.003
        driver.send(q)
        driver.step()
    data = sink.read_bytes()
    assert len(data) == 2 * 462  # the step's frame and the final hold
    ref = hubo_ach.HuboRef.from_buffer_copy(data[:462])
    index = MODEL.hubo_ach["index"]
    for i, name in enumerate(MODEL.joint_names):
        assert ref.ref[index[name]] == pytest.approx(q[i], abs=1e-12)
    unused = sorted(set(range(42)) - set(index.values()))
    assert all(ref.ref[k] == 0.0 for k in unused)  # the dry run's start posture has them at 0
    assert list(ref.mode) == [hubo_ach.MODE_REF] * 42
    assert list(ref.comply) == [0] * 42
    frames = read_ref_frames(sink)
    assert np.array_equal(frames[0].ref_rad, np.array(ref.ref))
    assert np.array_equal(frames[1].ref_rad, frames[0].ref_rad)


def test_state_round_trip_field_by_field():
    rng = np.random.default_rng(7)
    frame = hubo_ach.StateFrame(123.456, rng.normal(size=3), rng.normal(size=3),
                                rng.normal(size=(4, 3)), rng.normal(size=42),
                                rng.normal(size=42), True)
    data = hubo_ach.encode_state(frame)
    state = hubo_ach.HuboState.from_buffer_copy(data)
    imu = state.imu[hubo_ach.IMU_BODY]
    assert [imu.a_x, imu.a_y, imu.a_z] == list(frame.imu_tilt_rad)
    assert [imu.w_x, imu.w_y, imu.w_z] == list(frame.imu_rate_rad_s)
    assert state.ft[hubo_ach.FT_L_FOOT].f_z == frame.ft_mx_my_fz[3, 2]
    assert state.ft[hubo_ach.FT_R_HAND].m_y == frame.ft_mx_my_fz[0, 1]
    assert [state.joint[k].pos for k in range(42)] == list(frame.pos_rad)
    assert [state.joint[k].vel for k in range(42)] == list(frame.vel_rad_s)
    assert state.time == 123.456 and state.refWait == 1
    back = hubo_ach.decode_state(data)
    assert np.array_equal(back.pos_rad, frame.pos_rad)
    assert np.array_equal(back.ft_mx_my_fz, frame.ft_mx_my_fz)
    with pytest.raises(ValueError, match="3898"):
        hubo_ach.decode_state(data[:-1])
    with pytest.raises(ValueError, match="462"):
        hubo_ach.decode_ref(bytes(490))


def test_reference_filter_is_hubo_daemons():
    f = np.array([0.0, 0.0, 0.0])
    r = np.array([1.0, 1.0, 1.0])
    mode = np.array([0, 1, 2])
    out = hubo_ach.reference_filter(f, r, mode, 40)
    assert out[0] == pytest.approx(1.0 / 40)  # (f (L - 1) + r) / L
    assert out[1] == 1.0 and out[2] == 0.0
    for _ in range(39):
        out = hubo_ach.reference_filter(out, r, mode, 40)
    assert out[0] == pytest.approx(1 - (39 / 40) ** 40)


@pytest.mark.parametrize("tilt", [(0.0, 0.0, 0.0), (0.1, -0.05, 0.0), (-0.3, 0.2, 0.7)])
def test_imu_tilt_becomes_a_quaternion_with_the_same_roll_and_pitch(tilt):
    from hubo_cli.state import RobotState

    quat = hubo_ach.quat_from_tilt(tilt)
    assert np.linalg.norm(quat) == pytest.approx(1.0, abs=1e-12)
    state = RobotState(0.0, np.zeros(24), np.zeros(24), imu_quat_wxyz=quat)
    assert state.tilt_rad() == pytest.approx(tilt[:2], abs=1e-12)
