"""Limb.solve's wrapper (arrays passed through when the kernel takes them as they are, the result
built without the dataclass' __init__) against the plain call of the kernel it wraps."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hubo_cli.kinematics import choice, get_limb
from hubo_cli.kinematics.limb import IKResult
from hubo_cli.model import ARMS, LEGS


def _reference(limb, T_N_E, q_prev_rad) -> IKResult:
    has_prev = q_prev_rad is not None
    q_prev = np.array(q_prev_rad, dtype=float) if has_prev else np.zeros(6)
    q = np.empty(6)
    status, pos, rot = choice.solve_limb(
        np.array(T_N_E, dtype=float, order="C"), limb.chain, limb.lengths_m, limb.spec.is_arm,
        limb.lower_rad, limb.upper_rad, q_prev, has_prev, limb.hold_m, True, q)
    return IKResult(q, choice.STATUS_NAMES[status], pos, rot)


def _variants(T: np.ndarray, q: np.ndarray):
    """The same goal and previous joints as the arrays the wrapper meets."""
    read_only_T, read_only_q = T.copy(), q.copy()
    read_only_T.flags.writeable = False
    read_only_q.flags.writeable = False
    yield T, q
    yield read_only_T, read_only_q
    yield np.asfortranarray(T), np.repeat(q, 2)[::2]  # non-contiguous
    yield T.tolist(), q.tolist()
    yield T.astype(">f8"), q.astype(">f8")  # float64, but not native byte order
    yield T, None


@pytest.mark.parametrize("name", ARMS + LEGS)
def test_solve_equals_the_kernel_call_for_every_input_kind(name):
    limb = get_limb(name)
    rng = np.random.default_rng(3)
    _reference(limb, limb.fk(np.zeros(6)), np.zeros(6))
    signatures = set(choice.solve_limb.signatures)  # the wrapper's one, compiled by now
    statuses = set()
    for _ in range(40):
        q_true = limb.random_q(rng)
        T = limb.fk(q_true)
        T[:3, 3] += rng.normal(0.0, 0.08, 3)  # some goals out of reach
        q_prev = q_true + rng.normal(0.0, 0.1, 6)
        for T_in, q_in in _variants(T, q_prev):
            q_before = None if q_in is None else np.array(q_in, dtype=float)
            got = limb.solve(T_in, q_in)
            want = _reference(limb, T, None if q_in is None else q_prev)
            assert type(got) is IKResult
            assert np.array_equal(got.q_rad, want.q_rad)
            assert (got.status, got.position_error_m, got.rotation_error_rad) == (
                want.status, want.position_error_m, want.rotation_error_rad)
            if q_in is not None:  # the caller's previous joints are only read
                assert np.array_equal(np.array(q_in, dtype=float), q_before)
            statuses.add(got.status)
    assert "exact" in statuses and len(statuses) > 1
    assert set(choice.solve_limb.signatures) == signatures  # none compiled it once more


def test_solve_result_is_a_frozen_dataclass_with_its_fields():
    limb = get_limb("right-arm")
    result = limb.solve(limb.fk(np.full(6, 0.2)), np.full(6, 0.2))
    assert result.exact and result.q_rad.shape == (6,)
    assert {f.name for f in dataclasses.fields(result)} == set(vars(result))
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.status = "held"
    assert result == IKResult(result.q_rad, result.status, result.position_error_m,
                              result.rotation_error_rad)
