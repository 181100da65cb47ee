"""FASTRAK record layouts: known byte sequences decode to known poses, and encoding round-trips."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hubo_cli.errors import InputError
from hubo_cli.fastrak.records import Plausibility, encode_record, make_layout, scan
from hubo_cli.geometry import (
    fastrak_euler_deg_to_matrix,
    fastrak_euler_deg_to_quat_wxyz,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
)

IN = 0.0254
CM = 0.01


def Rz(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def Ry(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def Rx(deg):
    a = math.radians(deg)
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def decode_one(record: bytes, fmt: str, output_list: str, units: str, **plaus):
    result = scan(record, make_layout(fmt, output_list), units, final=True,
                  plaus=Plausibility(**plaus) if plaus else Plausibility())
    return result


# the protocol notes' worked ASCII example (default list 2,4,1, inches): "-150.25" touches "10.00"
MANUAL_ASCII = (b"01 " b"  12.34" b"  -5.67" b"   8.90" b"  10.00" b"-150.25" b"   1.25" b"\r\n")
# its worked binary example: list 2,11,0, pos (12.5, -3.25, 8.0), identity quaternion
MANUAL_BINARY = bytes.fromhex("303120" "00004841" "000050c0" "00000041" "0000803f" "00000000"
                              "00000000" "00000000" "20")


def test_manual_ascii_example_is_47_bytes_and_touching_fields_decode():
    assert len(MANUAL_ASCII) == make_layout("ascii", "2,4,1").length == 47
    # elevation -150.25 is outside the device's +-90 range: rejected by default ...
    assert len(decode_one(MANUAL_ASCII, "ascii", "2,4,1", "in").batch) == 0
    # ... and decoded exactly once the limit is widened
    res = decode_one(MANUAL_ASCII, "ascii", "2,4,1", "in", max_elevation_deg=180.0)
    assert len(res.batch) == 1 and res.bad_bytes == 0
    np.testing.assert_allclose(res.batch.position_m[0], np.array([12.34, -5.67, 8.90]) * IN)
    R = quat_wxyz_to_matrix(res.batch.quat_wxyz)[0]
    np.testing.assert_allclose(R, Rz(10.0) @ Ry(-150.25) @ Rx(1.25), atol=1e-12)


def test_ascii_fields_touching_with_valid_angles():
    # azimuth -150.25 touches z, roll -179.99 touches elevation -45.50
    record = b"03x" b"  12.34  -5.67   8.90-150.25 -45.50-179.99" b"\r\n"
    res = decode_one(record, "ascii", "2,4,1", "cm")
    b = res.batch
    assert len(b) == 1 and b.station[0] == 3 and chr(b.status[0]) == "x"
    np.testing.assert_allclose(b.position_m[0], np.array([12.34, -5.67, 8.90]) * CM)
    np.testing.assert_allclose(quat_wxyz_to_matrix(b.quat_wxyz)[0],
                               Rz(-150.25) @ Ry(-45.50) @ Rx(-179.99), atol=1e-12)


def test_manual_binary_example_cm_and_inches():
    for units, scale in (("cm", CM), ("in", IN)):
        for output_list in ("2,11,0", "52,61,50"):
            res = decode_one(MANUAL_BINARY, "binary", output_list, units)
            assert make_layout("binary", output_list).length == 32
            assert len(res.batch) == 1
            np.testing.assert_allclose(res.batch.position_m[0],
                                       np.array([12.5, -3.25, 8.0]) * scale)
            np.testing.assert_allclose(res.batch.quat_wxyz[0], [1, 0, 0, 0])


def test_binary_quaternion_is_scalar_first():
    # 90 degrees about z, as (w, x, y, z) = (cos 45, 0, 0, sin 45)
    c = math.sqrt(0.5)
    rec = (b"02 " + np.array([1, 2, 3, c, 0, 0, c], dtype="<f4").tobytes() + b"\r\n")
    res = decode_one(rec, "binary", "2,11,1", "cm")
    R = quat_wxyz_to_matrix(res.batch.quat_wxyz)[0]
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-6)
    assert res.batch.station[0] == 2


def test_euler_order_azimuth_then_elevation_then_roll():
    # azimuth turns the sensor's x axis toward +Y; elevation 90 points it along -Z
    R = fastrak_euler_deg_to_matrix(np.array([[90.0, 0, 0], [0, 90.0, 0], [0, 0, 90.0],
                                          [30.0, 20.0, 10.0]]))
    np.testing.assert_allclose(R[0] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(R[1] @ [1, 0, 0], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(R[2] @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(R[3], Rz(30) @ Ry(20) @ Rx(10), atol=1e-12)


def test_direction_cosines_are_rows_of_the_rotation():
    R = Rz(30) @ Ry(-20) @ Rx(45)
    rec = b"01 " + b"".join(f"{v:7.2f}".encode() for v in (1, 2, 3))
    for row in R:
        rec += b"".join(f"{v:7.4f}".encode() for v in row)
    rec += b"\r\n"
    res = decode_one(rec, "ascii", "2,5,6,7,1", "cm")
    np.testing.assert_allclose(quat_wxyz_to_matrix(res.batch.quat_wxyz)[0], R, atol=2e-4)


def test_ascii_quaternion_list_is_54_bytes():
    layout = make_layout("ascii", "2,11,1")
    assert layout.length == 54
    rec = b"01 " + b"  10.00 -20.00  30.00" + b" 1.0000 0.0000 0.0000 0.0000" + b"\r\n"
    res = decode_one(rec, "ascii", "2,11,1", "cm")
    np.testing.assert_allclose(res.batch.position_m[0], [0.1, -0.2, 0.3])


def test_ascii_extended_precision():
    layout = make_layout("ascii", "52,61,51")
    assert layout.length == 3 + 7 * 14 + 2
    rec = (b"01 " + b" 1.234567E+01 -5.000000E-01  3.000000E+00 "
           + b" 1.000000E+00  0.000000E+00  0.000000E+00 -0.000000E+00 " + b"\r\n")
    res = decode_one(rec, "ascii", "52,61,51", "cm")
    np.testing.assert_allclose(res.batch.position_m[0], [0.1234567, -0.005, 0.03])


def test_status_letters_are_exposed_and_bad_header_bytes_rejected():
    for letter in "xyjkaD":
        rec = MANUAL_BINARY[:2] + letter.encode() + MANUAL_BINARY[3:]
        res = decode_one(rec, "binary", "2,11,0", "cm")
        assert res.batch.status_chars() == [letter]
    for bad in (b"?", b"\x00", b"5"):
        rec = MANUAL_BINARY[:2] + bad + MANUAL_BINARY[3:]
        assert len(decode_one(rec, "binary", "2,11,0", "cm").batch) == 0
    rec = MANUAL_BINARY[:1] + b"5" + MANUAL_BINARY[2:]  # station 5 does not exist
    assert len(decode_one(rec, "binary", "2,11,0", "cm").batch) == 0


def test_implausible_records_rejected():
    def binary(pos, q):
        return b"01 " + np.array([*pos, *q], dtype="<f4").tobytes() + b" "

    ok = decode_one(binary([10, 20, 30], [1, 0, 0, 0]), "binary", "2,11,0", "cm")
    assert len(ok.batch) == 1
    for pos, q in (([400, 0, 0], [1, 0, 0, 0]),      # 4 m away
                   ([0, 0, 0], [0.5, 0, 0, 0]),      # not a unit quaternion
                   ([np.nan, 0, 0], [1, 0, 0, 0])):
        assert len(decode_one(binary(pos, q), "binary", "2,11,0", "cm").batch) == 0


def test_stylus_item():
    layout = make_layout("binary", "2,11,16,1")
    assert layout.length == 3 + 12 + 16 + 2 + 2
    rec = encode_record(layout, 1, [0.1, 0.2, 0.3], [1, 0, 0, 0], "cm", stylus=1)
    assert rec[-4:] == b" 1\r\n"
    res = scan(rec, layout, "cm", final=True)
    assert res.batch.stylus.tolist() == [1]


@pytest.mark.parametrize("fmt,output_list,message", [
    ("binary", "2,11,99", "unsupported"),
    ("binary", "4,11,1", "no position"),
    ("binary", "2,1", "no orientation"),
    ("binary", "2,11", "terminator"),
    ("hex", "2,11,1", "format"),
    ("ascii", "2,x,1", "comma-separated"),
])
def test_bad_output_lists_are_input_errors(fmt, output_list, message):
    with pytest.raises(InputError, match=message) as info:
        make_layout(fmt, output_list)
    assert info.value.hint


LISTS = [("ascii", "2,4,1"), ("ascii", "2,11,1"), ("ascii", "52,61,51"), ("ascii", "2,5,6,7,1"),
         ("binary", "2,11,0"), ("binary", "2,11,1"), ("binary", "52,61,50"),
         ("binary", "2,4,1"), ("binary", "2,4,16,1")]
coords = st.floats(-1.5, 1.5, allow_nan=False)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.sampled_from(LISTS), st.sampled_from(["cm", "in"]), st.integers(1, 4),
       st.tuples(coords, coords, coords),
       st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 4).filter(
           lambda q: np.linalg.norm(q) > 0.1))
def test_encode_decode_round_trip(fmt_list, units, station, pos, q):
    fmt, output_list = fmt_list
    layout = make_layout(fmt, output_list)
    q = np.array(q) / np.linalg.norm(q)
    rec = encode_record(layout, station, pos, q, units)
    assert len(rec) == layout.length
    res = scan(rec, layout, units, final=True)
    assert len(res.batch) == 1 and res.batch.station[0] == station
    ascii_std = fmt == "ascii" and not output_list.startswith("52")
    pos_tol = 0.006 * (0.0254 if units == "in" else 0.01) if ascii_std else 1e-6
    np.testing.assert_allclose(res.batch.position_m[0], pos, atol=pos_tol)
    R_in = quat_wxyz_to_matrix(q[None])[0]
    R_out = quat_wxyz_to_matrix(res.batch.quat_wxyz)[0]
    # Euler angles with 0.01 degree steps lose a little more near gimbal lock
    np.testing.assert_allclose(R_out, R_in, atol=2e-3 if ascii_std else 1e-5)


def test_quaternion_rotation_round_trip(rng):
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    np.testing.assert_allclose(matrix_to_quat_wxyz(quat_wxyz_to_matrix(q)), q, atol=1e-12)


def test_euler_quaternion_matches_the_euler_matrix(rng):
    angles = np.c_[rng.uniform(-180, 180, 300), rng.uniform(-90, 90, 300),
                   rng.uniform(-180, 180, 300)]
    np.testing.assert_allclose(quat_wxyz_to_matrix(fastrak_euler_deg_to_quat_wxyz(angles)),
                               fastrak_euler_deg_to_matrix(angles), atol=1e-12)
