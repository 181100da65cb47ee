"""The compiled CSV number reader/writer used by ``hubo ik --batch``."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hubo_cli.kinematics import csv_codec

# poses and joints: metres and radians, never near the subnormal range
magnitude = st.floats(min_value=1e-20, max_value=1e15)
finite = st.one_of(st.just(0.0), magnitude, magnitude.map(lambda v: -v))


def parse(text, rows, cols):
    buf = np.frombuffer(text.encode(), dtype=np.uint8)
    starts, ends = csv_codec.line_bounds(buf, 0)
    assert len(starts) == rows
    return csv_codec.parse_rows(buf, starts, ends, cols)


@settings(max_examples=300, deadline=None)
@given(st.lists(finite, min_size=3, max_size=3))
def test_repr_is_read_within_one_ulp(values):
    parsed, errors = parse(",".join(repr(v) for v in values) + "\n", 1, 3)
    assert errors[0] == csv_codec.OK
    assert np.all(np.abs(parsed[0] - values) <= 2 * np.spacing(np.abs(values)) + 1e-300)


@settings(max_examples=300, deadline=None)
@given(st.lists(finite, min_size=6, max_size=6))
def test_written_numbers_read_back_to_twelve_digits(values):
    q = np.array([values])
    names = np.zeros((1, 12), dtype=np.uint8)
    names[0, :5] = np.frombuffer(b"exact", dtype=np.uint8)
    text = bytes(csv_codec.format_rows(2, q, np.zeros(1, dtype=np.int64), np.zeros(1),
                                       np.zeros(1), names)).decode()
    fields = text.strip().split(",")
    assert fields[0] == "2" and fields[7] == "exact"
    back = np.array([float(f) for f in fields[1:7]])
    assert np.allclose(back, q[0], rtol=1e-11, atol=0)


def test_formats_and_errors():
    text = "1,-2.5e3, +.5\n nan ,INF,1E-2\n1,2\n1,x,3\n1,2e,3\n"
    values, errors = parse(text, 5, 3)
    assert list(errors) == [0, 0, csv_codec.FIELD_COUNT, csv_codec.NOT_A_NUMBER,
                            csv_codec.NOT_A_NUMBER]
    assert np.allclose(values[0], [1, -2500, 0.5])
    assert np.isnan(values[1, 0]) and values[1, 1] == np.inf and values[1, 2] == 0.01


def test_crlf_lines():
    values, errors = parse("1,2\r\n3,4\r\n", 2, 2)
    assert list(errors) == [0, 0] and np.array_equal(values, [[1, 2], [3, 4]])
