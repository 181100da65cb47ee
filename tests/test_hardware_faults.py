"""The simulated daemon's motors (currents, heat, temperatures from the simulated torques) and
the faults it plays on request (hubo_cli/drivers/hubo_ach_motors.py, hubo_ach_faults.py), and
the hardware driver's guards against them through real ach channels: a frozen joint trips the
servo-error stop within 0.1 s, a heating motor is slowed and then stopped. The tests that need
libach skip with the reason without it; their channels are uniquely named and removed.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
import uuid

import numpy as np
import pytest
from click.testing import CliRunner
from realtime_support import needs_libach

from hubo_cli.cli.main import main
from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.ach import load_libach
from hubo_cli.drivers.hardware import HardwareDriver, hubo_ach_vector
from hubo_cli.drivers.hubo_ach_daemon import EchoBody, HuboDaemon
from hubo_cli.drivers.hubo_ach_faults import parse_fault
from hubo_cli.drivers.hubo_ach_motors import MotorModel, motor_parameters
from hubo_cli.drivers.hubo_ach_sim_body import PhysicsBody
from hubo_cli.drivers.servo_guard import MotorTooHot, ServoError
from hubo_cli.errors import ConfigError, InputError
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from tests.test_hardware_cli import _wait_published

MODEL = load_model()
NAMES = MODEL.joint_names
INDEX = MODEL.hubo_ach["index"]
HOME42 = hubo_ach_vector(MODEL, home_posture(MODEL))
PERIOD_S = hubo_ach.LOOP_PERIOD_S
GUARDS = MODEL.hardware_guards
REB = NAMES.index("REB")


# ---------------------------------------------------------------- the motors
def test_currents_follow_the_torques_through_hubo_achs_gear_ratios():
    """i = tau / (N k_t), N = harm x driven / drive of hubo-ach's huboplus joint table: the
    shoulder pitch 100 x 16 / 11, the hip roll 160 x 1024 / 324, the knee 160."""
    params, ratio = motor_parameters(MODEL)
    assert ratio[NAMES.index("RSP")] == pytest.approx(100 * 16 / 11)
    assert ratio[NAMES.index("LHR")] == pytest.approx(160 * 1024 / 324)
    assert ratio[NAMES.index("RKN")] == pytest.approx(160)
    motors = MotorModel(MODEL)
    rng = np.random.default_rng(35)
    for tau in rng.normal(0, 30, size=(20, len(NAMES))):
        motors.advance(tau, PERIOD_S)
        limb = motors.cur_a[[INDEX[n] for n in NAMES]]
        assert np.allclose(limb * ratio * params["torque_constant_nm_a"], tau)
        others = np.delete(motors.cur_a, [INDEX[n] for n in NAMES])
        assert not others.any()  # neck, waist, fingers: no load


def test_the_temperature_is_a_first_order_lag_of_the_copper_loss():
    """A constant torque: after one time constant the rise is 63.2 % of R_th R i^2, the heat
    is R i^2 t; a hot-motor fault adds its rate; tempError past the board's limit; a NaN
    torque heats nothing."""
    params, ratio = motor_parameters(MODEL)
    motors = MotorModel(MODEL)
    knee = NAMES.index("RKN")
    tau = np.zeros(len(NAMES))
    tau[knee] = 20.0
    i_a = 20.0 / (ratio[knee] * params["torque_constant_nm_a"])
    loss_w = params["winding_resistance_ohm"] * i_a ** 2
    step_s = params["thermal_time_constant_s"] / 1000  # the step is exact for any period
    for _ in range(1000):
        motors.advance(tau, step_s)
    rise = motors.tmp_c[INDEX["RKN"]] - params["ambient_temperature_c"]
    assert rise == pytest.approx((1 - np.exp(-1)) * params["thermal_resistance_k_w"] * loss_w,
                                 rel=1e-6)
    assert motors.heat_j[INDEX["RKN"]] == pytest.approx(
        loss_w * params["thermal_time_constant_s"], rel=1e-9)
    assert motors.tmp_c[INDEX["LKN"]] == params["ambient_temperature_c"]
    assert not motors.temp_error.any()
    motors.heat(INDEX["LKN"], 20.0)
    tau[knee] = np.nan
    for _ in range(40):
        motors.advance(tau, 0.1)
    assert motors.tmp_c[INDEX["LKN"]] == pytest.approx(params["ambient_temperature_c"] + 80.0,
                                                       rel=0.01)
    assert motors.cur_a[INDEX["RKN"]] == 0.0
    hot = motors.tmp_c > params["board_temperature_error_c"]
    assert np.array_equal(motors.temp_error.astype(bool), hot) and hot[INDEX["LKN"]]


@pytest.mark.parametrize("change", [
    {"motors": {}},
    {"drop": "torque_constant_nm_a"},
    {"set": ("winding_resistance_ohm", -0.6)},
    {"set": ("thermal_time_constant_s", float("nan"))},
    {"set": ("board_temperature_error_c", 20.0)},
    {"set": ("thermal_resistance_k_w", "hot")},
    {"gears": {"SP": [11, 16, 100]}},
    {"gears": {**MODEL.motors["drive_driven_harmonic"], "KN": [0, 16, 160]}},
    {"gears": {**MODEL.motors["drive_driven_harmonic"], "KN": [16, 160]}},
])
def test_impossible_motor_constants_are_refused(change):
    motors = dict(MODEL.motors)
    if "motors" in change:
        motors = change["motors"]
    if "drop" in change:
        del motors[change["drop"]]
    if "set" in change:
        motors[change["set"][0]] = change["set"][1]
    if "gears" in change:
        motors["drive_driven_harmonic"] = change["gears"]
    with pytest.raises(ConfigError) as info:
        MotorModel(dataclasses.replace(MODEL, motors=motors))
    assert "[motors]" in info.value.message and "\n" not in info.value.message


# ---------------------------------------------------------------- fault specs
@pytest.mark.parametrize("spec, expected", [
    ("frozen,joint=REB,at=2", dict(kind="frozen", joint="REB", at_s=2.0)),
    (" hot , joint=LKN , at=0 , rate=12.5 ", dict(kind="hot", joint="LKN", rate_k_s=12.5)),
    ("missing,at=3", dict(kind="missing", at_s=3.0, for_s=None)),
    ("late,by=0.05,at=1,for=0.5", dict(kind="late", by_s=0.05, for_s=0.5)),
])
def test_fault_specs_are_read(spec, expected):
    fault = parse_fault(spec, NAMES)
    for key, value in expected.items():
        assert getattr(fault, key) == value
    assert parse_fault(fault.describe(), NAMES) == fault


def _hostile_specs(seed: int, n: int) -> list[str]:
    """Valid specs broken one way each: a field dropped, doubled, renamed or given a bad value,
    an unknown kind or joint, garbage."""
    rng = np.random.default_rng(seed)
    valid = ["frozen,joint=REB,at=2", "hot,joint=RKN,at=1,rate=10", "missing,at=3,for=0.3",
             "late,at=3,for=1,by=0.05"]
    bad_values = ["nan", "inf", "-1", "", "1e99", "two", "0x10", "1,", "--2"]
    out = []
    for _ in range(n):
        kind, *fields = rng.choice(valid).split(",")
        how = rng.integers(6)
        k = int(rng.integers(len(fields)))
        if how == 0:
            del fields[k]
        elif how == 1:
            fields.append(fields[k])
        elif how == 2:
            fields[k] = "x" + fields[k]
        elif how == 3:
            key = fields[k].split("=")[0]
            value = "NOPE" if key == "joint" else bad_values[rng.integers(len(bad_values))]
            if key != "at" and value == "":
                value = "0"  # for, by, rate must be > 0
            fields[k] = f"{key}={value}"
        elif how == 4:
            kind = "".join(rng.choice(list("abcxyz=,"), size=int(rng.integers(1, 8))))
        else:
            fields[k] = fields[k].replace("=", "")
        out.append(",".join([kind, *fields]))
    return out


def test_hostile_fault_specs_are_refused_in_one_line():
    refused = 0
    for spec in _hostile_specs(35, 300):
        try:
            fault = parse_fault(spec, NAMES)
        except InputError as exc:
            assert exc.exit_code == 2 and "\n" not in exc.message and "--fault" in exc.message
            refused += 1
            continue
        # what was accepted is a whole, sensible fault
        assert fault.at_s >= 0 and (fault.joint is None or fault.joint in NAMES), spec
    assert refused > 250  # only a dropped optional field leaves a valid spec


@pytest.mark.parametrize("args, message", [
    (["--fault", "frozen,joint=NKY,at=1"], "not a limb joint"),
    (["--fault", "hot,joint=REB,at=1"], "needs rate"),
    (["--fault", "late,at=1,by=nan"], "is not a number"),
    (["--fault", "stuck,at=1"], "unknown kind"),
    (["--fault", "late,at=1,by=11"], "in (0, 10]"),  # the daemon would keep every state
    (["--fault", "hot,joint=REB,at=1,rate=1e4"], "kelvin per second"),
    (["--tool-log", "{tmp}/missing/tool.csv"], "--tool-log"),  # its folder is not there
    (["--wall", "10"], "--wall"),  # inside the robot
    (["--wall", "500", "--wall-at", "-1"], "--wall-at"),
    (["--wall-at", "3"], "there is none"),
])
def test_the_sim_daemon_refuses_bad_options_before_anything_starts(tmp_path, args, message):
    args = [a.format(tmp=tmp_path) for a in args]
    result = CliRunner().invoke(main, ["hardware", "sim-daemon", *args],
                                env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output


# ---------------------------------------------------------------- the body's faults
def test_the_body_publishes_its_motors_and_plays_their_faults():
    """Standing: every limb motor near ambient, the knees drawing the most current. Frozen
    REB: its encoder stays while its reference goes on, ``jam`` set in the packed state; hot
    RKN: ``tmp`` climbs by the rate. The fake daemon's ideal motors cannot play either."""
    body = PhysicsBody(MODEL, HOME42)
    try:
        mode = np.full(hubo_ach.JOINT_COUNT, hubo_ach.MODE_REF, dtype=np.int16)
        for _ in range(40):
            body.advance(HOME42, mode, PERIOD_S)
        frame = body.state(1.0)
        limb = [INDEX[n] for n in NAMES]
        ambient = MODEL.motors["ambient_temperature_c"]
        assert np.all(np.abs(frame.tmp_c[limb] - ambient) < 0.1)
        # measured standing: the knees 1.7-2.3 A, every other limb motor under 1 A
        knees = np.abs(frame.cur_a[[INDEX["RKN"], INDEX["LKN"]]])
        assert np.all(knees > 0.5) and np.max(np.abs(frame.cur_a)) == pytest.approx(knees.max())
        body.begin_fault(parse_fault("frozen,joint=REB,at=0", NAMES))
        body.begin_fault(parse_fault("hot,joint=RKN,at=0,rate=20", NAMES))
        ref = HOME42.copy()
        for _ in range(100):  # 0.5 s, REB's reference 0.5 rad on
            ref[INDEX["REB"]] -= 0.005
            body.advance(ref, mode, PERIOD_S)
        raw = np.frombuffer(hubo_ach.encode_state(body.state(1.5)), hubo_ach.STATE_DTYPE)[0]
        packed = hubo_ach.decode_state(raw.tobytes())
        assert abs(packed.pos_rad[INDEX["REB"]] - HOME42[INDEX["REB"]]) < 0.01
        assert raw["joint"]["ref"][INDEX["REB"]] == pytest.approx(ref[INDEX["REB"]])
        assert raw["status"]["jam"][INDEX["REB"]] == 1 and raw["status"]["jam"].sum() == 1
        assert packed.tmp_c[INDEX["RKN"]] == pytest.approx(ambient + 20 * 0.5, abs=0.2)
        assert raw["joint"]["heat"][INDEX["RKN"]] > 0
    finally:
        body.close()
    with pytest.raises(ValueError, match="no motors to play frozen"):
        HuboDaemon(None, EchoBody(HOME42), faults=[parse_fault("frozen,joint=REB,at=0",
                                                               NAMES)])


# ---------------------------------------------------------------- through real ach channels
def _names() -> tuple[str, str]:
    tag = f"hubotest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    return f"{tag}-ref", f"{tag}-state"


@needs_libach
def test_a_missing_and_a_late_state_show_in_the_drivers_timing():
    """The daemon withholds its state for 0.05 s (under the driver's 0.1 s stale limit), then
    publishes states 0.05 s old for 0.3 s: the driver counts the periods without a fresh
    state, its state age rises to the delay and no check trips."""
    ref, state = _names()
    lib = load_libach()
    faults = [parse_fault("missing,at=0.3,for=0.05", NAMES),
              parse_fault("late,at=0.6,for=0.3,by=0.05", NAMES)]
    with HuboDaemon(lib, EchoBody(HOME42), ref, state, faults=faults) as daemon:
        daemon.start()
        with HardwareDriver(MODEL, armed=True, ach_ref=ref, ach_state=state) as driver:
            hold = driver.start().q_rad.copy()
            ages, gaps, flags = [], [], []
            for _ in range(int(1.2 / PERIOD_S)):
                driver.send(hold)
                flags.append(driver.step().flags)
                values = driver.log_values()
                ages.append(values["hw_state_age_ms"])
                gaps.append(values["hw_state_age_periods"])
        stats = daemon.stats.summary()
    # 10 and 60 periods; fewer when a loaded machine makes the daemon's periods late
    assert 5 <= stats["states_withheld"] <= 11 and 30 <= stats["states_late"] <= 61
    assert max(gaps) >= 5 and not any("stale-state" in f for f in flags)
    # the late window's ages: 50 ms plus the bus (measured 50.1-51 ms median)
    assert 45 <= float(np.median(sorted(ages)[-40:])) <= 95
    assert all(began is not None for began in stats["faults"].values())


def _sim_daemon(ref: str, state: str, *faults: str) -> subprocess.Popen:
    args = [sys.executable, "-m", "hubo_cli.cli.main", "hardware", "sim-daemon", "--ach-ref",
            ref, "--ach-state", state, "--json"]
    for spec in faults:
        args += ["--fault", spec]
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _end(process: subprocess.Popen, lib, *names: str) -> dict:
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=30)
    for name in names:
        lib.unlink(name)
    assert process.returncode == 0, err
    return json.loads(out)


@needs_libach
def test_a_frozen_joint_in_the_simulated_robot_trips_the_servo_error_within_0_1_s():
    """The simulated daemon freezes REB 0.3 s after the driver's first reference while the
    driver moves REB at 0.8 rad/s (direct references): the run ends with the servo error on
    REB within 0.1 s (wall time) of the reference put passing 0.2 rad from where the joint
    stuck, and the daemon reports the fault. Measured: 17-22 ms at load 2."""
    ref, state = _names()
    lib = load_libach()
    process = _sim_daemon(ref, state, "frozen,joint=REB,at=0.3")
    try:
        _wait_published(lib, state)
        with HardwareDriver(MODEL, armed=True, ach_ref=ref, ach_state=state) as driver:
            q = driver.start().q_rad.copy()
            put_s, refs, trip = [], [], None
            for _ in range(int(3.0 / PERIOD_S)):
                q[REB] -= 0.8 * PERIOD_S
                refs.append(driver.send(q)[REB])
                put_s.append(time.monotonic())
                try:
                    driver.step()
                except ServoError as exc:
                    trip, tripped_s = exc, time.monotonic()
                    break
            stuck_rad = driver.read().q_rad[REB]
            summary = driver.summary_values()
    finally:
        stats = _end(process, lib, ref, state)
    assert isinstance(trip, ServoError) and trip.joint == "REB", trip
    assert "servo error: REB" in trip.message and "\n" not in trip.message
    # the first reference past the limit from where the joint stuck (it moved through there)
    crossed = 1 + max(k for k, r in enumerate(refs)
                      if abs(r - stuck_rad) <= GUARDS["servo_error_limit_rad"])
    delay_s = tripped_s - put_s[crossed]
    print(f"frozen REB: tripped {1e3 * delay_s:.1f} ms after the reference passed the limit")
    assert 0 <= delay_s <= 0.1
    assert summary["hw_trip"] == "ServoError"
    assert stats["faults"]["frozen,joint=REB,at=0.3"] is not None


@needs_libach
def test_a_heating_motor_in_the_simulated_robot_is_slowed_then_stopped():
    """The simulated daemon heats REB's motor 40 K/s faster from 0.2 s after the driver's
    first reference while the driver asks REB for 0.8 rad/s: below the warning temperature the
    joint gets its full speed; between the warning and the maximum its speed is at most the
    thermal scale times its limit and falls to a stop; at the maximum the run ends with one
    line naming the motor, and the summary names it as the run's hottest."""
    ref, state = _names()
    lib = load_libach()
    process = _sim_daemon(ref, state, "hot,joint=REB,at=0.2,rate=40")
    warn, hot = GUARDS["motor_warning_temperature_c"], GUARDS["motor_max_temperature_c"]
    v_max = MODEL.velocity_rad_s[REB]
    try:
        _wait_published(lib, state)
        with HardwareDriver(MODEL, armed=True, ach_ref=ref, ach_state=state) as driver:
            q = driver.start().q_rad.copy()
            last = q[REB]
            temps, speeds, scales, trip = [], [], [], None
            for _ in range(int(4.0 / PERIOD_S)):
                q[REB] -= 0.8 * PERIOD_S
                temps.append(driver.thermal.temperature_c[REB])
                scales.append(driver.thermal.scale[REB])
                sent = driver.send(q)[REB]
                speeds.append(abs(sent - last) / PERIOD_S)
                last = sent
                q[REB] = sent  # the operator's target waits for the slowed joint
                try:
                    driver.step()
                except MotorTooHot as exc:
                    trip = exc
                    break
            summary = driver.summary_values()
    finally:
        stats = _end(process, lib, ref, state)
    assert isinstance(trip, MotorTooHot) and trip.joint == "REB", trip
    assert "motor too hot: REB" in trip.message and "\n" not in trip.message
    temps, speeds, scales = np.array(temps), np.array(speeds), np.array(scales)
    print(f"hot REB: {int(np.sum(temps >= warn))} periods slowed, from "
          f"{temps[temps >= warn][0]:.1f} C to {trip.temperature_c:.1f} C; {trip.message}")
    cool = temps < warn
    assert np.all(speeds[cool] == pytest.approx(0.8, abs=1e-6))
    warm = ~cool
    assert np.all(speeds[warm] <= scales[warm] * v_max + 1e-9)
    assert warm.sum() > 40 and speeds[-1] < 0.1  # slowed over 0.2 s or more, to a stop
    assert summary["hw_thermal_limited_periods"] >= warm.sum() - 2
    assert summary["hw_hottest_motor"]["joint"] == "REB"
    assert summary["hw_hottest_motor"]["temperature_c"] >= hot
    assert stats["hottest_motor"]["joint"] == "REB"


# ---------------------------------------------------------------- what estimation reads
def test_the_imu_and_the_wrenches_reach_the_driver_in_hubo_achs_conventions():
    """A 60 N forward push for 0.2 s on the standing simulated robot: the body IMU's tilt
    angles and rates (``imu[2]``: a_x roll, a_y pitch about the torso's axes, w in rad/s) and
    the soles' m_x, m_y, f_z (``ft[2..3]``), packed and decoded as the hardware driver reads
    them, give back the simulator's own orientation, gyro and wrenches; the robot leans
    forward as positive pitch (a_y > 0, w_y > 0 while it tips)."""
    from hubo_cli.geometry import roll_pitch_of_quat_wxyz
    from hubo_cli.state import FT_SENSORS

    body = PhysicsBody(MODEL, HOME42)
    try:
        mode = np.full(hubo_ach.JOINT_COUNT, hubo_ach.MODE_REF, dtype=np.int16)
        body.sim.push_torso([60.0, 0.0, 0.0], 0.2)
        pitch, rate = [], []
        for k in range(60):
            body.advance(HOME42, mode, PERIOD_S)
            packed = hubo_ach.decode_state(hubo_ach.encode_state(body.state(float(k))))
            truth = body._state
            assert packed.imu_tilt_rad[2] == 0.0  # a_z: no heading, the true yaw not sent
            quat = hubo_ach.body_imu_quat(packed.imu_tilt_rad)
            assert np.allclose(roll_pitch_of_quat_wxyz(quat),
                               roll_pitch_of_quat_wxyz(truth.imu_quat_wxyz), atol=1e-9)
            assert np.allclose(packed.imu_rate_rad_s, truth.imu_gyro_rad_s, atol=1e-12)
            for row, sensor in enumerate(FT_SENSORS):
                wrench = truth.ft[sensor]
                assert np.allclose(packed.ft_mx_my_fz[row], [wrench[3], wrench[4], wrench[2]])
            pitch.append(packed.imu_tilt_rad[1])
            rate.append(packed.imu_rate_rad_s[1])
        print(f"push: pitch {np.degrees(max(pitch)):.3f} deg, rate {max(rate):.4f} rad/s")
        # measured: 1.8 deg of forward pitch at its largest, the rate up to 0.19 rad/s
        assert max(pitch) > np.radians(0.5) and max(rate) > 0.05
        assert max(pitch) > -min(pitch)
    finally:
        body.close()


def test_the_daemons_world_can_hold_the_tasks_wall_and_track_the_bit():
    """``--wall``, ``--drill``, ``--tool-log``: the shipped tasks' wall at the distance asked,
    the drill in the right hand, and one row of the bit's true world position per state
    published, with that state's time."""
    from hubo_cli.tasks.spec import Scene
    from hubo_cli.urdf import DRILL_FRAME

    track = []
    body = PhysicsBody(MODEL, HOME42, drill=True,
                       track_tool=lambda t_s, xyz_m: track.append((t_s, *xyz_m)))
    try:
        assert not body.sim.walls
        body.place_wall(0.485)
        (wall,) = body.sim.walls
        assert wall.distance_m == 0.485 and wall.thickness_m == Scene().wall_thickness_m
        mode = np.full(hubo_ach.JOINT_COUNT, hubo_ach.MODE_REF, dtype=np.int16)
        for k in range(3):
            body.advance(HOME42, mode, PERIOD_S)
            body.state(10.0 + k)
        assert [row[0] for row in track] == [10.0, 11.0, 12.0]
        bit = body.sim.frame_pose(DRILL_FRAME)[:3, 3]
        assert np.allclose(track[-1][1:], bit) and bit[0] < wall.distance_m
    finally:
        body.close()
