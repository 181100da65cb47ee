"""Compiled CSV number reading and writing for ``hubo ik --batch`` (numba).

Reading: one pass over the bytes; every field must be a decimal number (optional sign, digits,
point, exponent; ``nan``/``inf`` are read as such and rejected later). The value is the decimal
mantissa scaled by a power of ten: within two ulp of the correctly rounded value for magnitudes
1e-20 .. 1e15 (powers of ten beyond 1e22 are themselves inexact, so far outside that range the
error grows; poses in metres never go there). A row with the
wrong number of fields or a field that is not a number gets an error code instead of values.

Writing: numbers as ``d.ddddddddddde+XX`` (12 significant digits), rows joined by commas.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT

OK = 0
FIELD_COUNT = 1
NOT_A_NUMBER = 2
ERROR_TEXT = ("", "wrong number of fields", "a field is not a number")

_COMMA, _NL, _CR, _SP = 44, 10, 13, 32
_POW10 = np.array([10.0 ** k for k in range(23)])


@nb.njit(**JIT)
def _scale(mantissa, exp10, pow10):
    if exp10 == 0:
        return mantissa
    if 0 < exp10 <= 22:
        return mantissa * pow10[exp10]
    if -22 <= exp10 < 0:
        return mantissa / pow10[-exp10]
    return mantissa * 10.0 ** exp10


@nb.njit(**JIT)
def _field(buf, i, end, pow10):
    """Parse one number at buf[i:end]; returns (value, ok)."""
    while i < end and buf[i] == _SP:
        i += 1
    while end > i and buf[end - 1] == _SP:
        end -= 1
    if i >= end:
        return np.nan, False
    neg = False
    if buf[i] == 45 or buf[i] == 43:  # - +
        neg = buf[i] == 45
        i += 1
    if end - i == 3:  # nan / inf, any case
        a, b, c = buf[i] | 32, buf[i + 1] | 32, buf[i + 2] | 32
        if a == 110 and b == 97 and c == 110:
            return np.nan, True
        if a == 105 and b == 110 and c == 102:
            return -np.inf if neg else np.inf, True
    mantissa = 0
    digits = 0
    exp10 = 0
    seen_point = False
    while i < end:
        c = buf[i]
        if 48 <= c <= 57:
            if digits < 18:
                mantissa = mantissa * 10 + (c - 48)
                digits += 1 if (mantissa > 0) else 0
                if seen_point:
                    exp10 -= 1
            elif not seen_point:
                exp10 += 1
        elif c == 46 and not seen_point:  # .
            seen_point = True
        else:
            break
        i += 1
    if i < end:
        if (buf[i] | 32) != 101:  # e
            return np.nan, False
        i += 1
        eneg = False
        if i < end and (buf[i] == 45 or buf[i] == 43):
            eneg = buf[i] == 45
            i += 1
        if i >= end:
            return np.nan, False
        e = 0
        while i < end:
            c = buf[i]
            if not (48 <= c <= 57):
                return np.nan, False
            e = e * 10 + (c - 48)
            i += 1
        exp10 += -e if eneg else e
    value = _scale(float(mantissa), exp10, pow10)
    return (-value if neg else value), True


@nb.njit(**JIT)
def _parse_row(buf, start, end, n_cols, pow10, values_row):
    """Parse one line buf[start:end] into values_row; returns its error code."""
    col = 0
    i = start
    while True:
        j = i
        while j < end and buf[j] != _COMMA:
            j += 1
        stop = j
        if stop > i and buf[stop - 1] == _CR:
            stop -= 1
        if col < n_cols:
            v, ok = _field(buf, i, stop, pow10)
            if not ok:
                return NOT_A_NUMBER
            values_row[col] = v
        col += 1
        if j >= end:
            break
        i = j + 1
    return OK if col == n_cols else FIELD_COUNT


@nb.njit(parallel=True, **JIT)
def parse_rows(buf, line_starts, line_ends, n_cols):
    """Parse the lines buf[line_starts[r]:line_ends[r]] (``n_cols`` numbers each) on all cores;
    returns (values, error code per row)."""
    n_rows = line_starts.shape[0]
    values = np.full((n_rows, n_cols), np.nan)
    errors = np.zeros(n_rows, dtype=np.int8)
    for r in nb.prange(n_rows):
        code = _parse_row(buf, line_starts[r], line_ends[r], n_cols, _POW10, values[r])
        if code != OK:
            errors[r] = code
            values[r, :] = np.nan
    return values, errors


def line_bounds(buf: np.ndarray, start: int) -> tuple[np.ndarray, np.ndarray]:
    """Start and end offsets of the lines of buf[start:] (trailing empty lines dropped)."""
    newlines = np.flatnonzero(buf[start:] == _NL) + start
    ends = np.append(newlines, len(buf))
    starts = np.concatenate([[start], newlines + 1])
    keep = ends > starts
    # an empty line in the middle is a (bad) row; only the empty tail after the last newline goes
    while len(keep) and not keep[-1]:
        keep = keep[:-1]
        starts, ends = starts[:-1], ends[:-1]
    return starts.astype(np.int64), ends.astype(np.int64)


@nb.njit(**JIT)
def _put_int(out, pos, value):
    if value < 0:
        out[pos] = 45
        pos += 1
        value = -value
    digits = np.empty(20, dtype=np.uint8)
    k = 0
    while True:
        digits[k] = 48 + value % 10
        value //= 10
        k += 1
        if value == 0:
            break
    for m in range(k - 1, -1, -1):
        out[pos] = digits[m]
        pos += 1
    return pos


@nb.njit(**JIT)
def _put_float(out, pos, x):
    """Write x with 12 significant digits as d.ddddddddddde+XX; nothing for NaN."""
    if x != x:
        return pos
    if x < 0:
        out[pos] = 45
        pos += 1
        x = -x
    if x == 0.0:
        out[pos] = 48
        return pos + 1
    if x == np.inf:
        out[pos] = 105
        out[pos + 1] = 110
        out[pos + 2] = 102
        return pos + 3
    e = int(math.floor(math.log10(x)))
    m = int(round(x / 10.0 ** e * 1e11))
    if m >= 1000000000000:
        m //= 10
        e += 1
    elif m < 100000000000:
        m *= 10
        e -= 1
    digits = np.empty(12, dtype=np.uint8)
    for k in range(11, -1, -1):
        digits[k] = 48 + m % 10
        m //= 10
    out[pos] = digits[0]
    out[pos + 1] = 46
    for k in range(1, 12):
        out[pos + 1 + k] = digits[k]
    pos += 13
    out[pos] = 101
    out[pos + 1] = 45 if e < 0 else 43
    e = -e if e < 0 else e
    out[pos + 2] = 48 + (e // 100) % 10 if e >= 100 else 48 + e // 10
    if e >= 100:
        out[pos + 3] = 48 + (e // 10) % 10
        out[pos + 4] = 48 + e % 10
        return pos + 5
    out[pos + 3] = 48 + e % 10
    return pos + 4


@nb.njit(**JIT)
def format_rows(first_line, q, status, pos_err, rot_err, names):
    """The output CSV body: ``line,q1..q6,status,pos_err_m,rot_err_rad`` per row (bytes).

    ``names`` is (n_names, width) uint8 with zero padding; status indexes its rows.
    """
    n = q.shape[0]
    out = np.empty(n * 200 + 1, dtype=np.uint8)
    pos = 0
    for r in range(n):
        pos = _put_int(out, pos, first_line + r)
        for j in range(6):
            out[pos] = _COMMA
            pos = _put_float(out, pos + 1, q[r, j])
        out[pos] = _COMMA
        pos += 1
        name = names[status[r]]
        for c in range(name.shape[0]):
            if name[c] == 0:
                break
            out[pos] = name[c]
            pos += 1
        out[pos] = _COMMA
        pos = _put_float(out, pos + 1, pos_err[r])
        out[pos] = _COMMA
        pos = _put_float(out, pos + 1, rot_err[r])
        out[pos] = _NL
        pos += 1
    return out[:pos]
