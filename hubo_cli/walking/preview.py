"""ZMP preview control on the cart-table model (Kajita et al., ICRA 2003).

The centre of mass moves on a horizontal plane at height ``z_c`` above the ground (the linear
inverted pendulum); per axis the state is x = (c, c', c'') and the input the CoM jerk u. With
period T:

    x[k+1] = A x[k] + B u[k],   p[k] = C x[k]        (p: the ZMP, the cart-table's output)
    A = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],  B = [T^3/6, T^2/2, T],  C = [1, 0, -z_c/g]

The controller minimises sum Q_e e^2 + R u^2 with e = p - p_ref over an infinite horizon,
seeing the reference ``preview_s`` ahead (Katayama's servo form, as Kajita 2003 eq. 10-12):

    u[k] = -G_i sum_{j<=k} e[j] - G_x x[k] - sum_{j=1}^{N} G_p(j) p_ref[k+j]

The gains come from the discrete algebraic Riccati equation of the system augmented with the
error integral (:func:`scipy.linalg.solve_discrete_are`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numba as nb
import numpy as np
from scipy.linalg import solve_discrete_are

from hubo_cli.errors import ConfigError
from hubo_cli.state import GRAVITY_M_S2


@dataclass(frozen=True)
class PreviewGains:
    """The preview controller's gains for one period, CoM height and horizon.

    Attributes:
        A, B, C: the cart-table model (3x3, 3, 3).
        integral: G_i, gain on the summed ZMP error.
        state: G_x (3,), gain on (c, c', c'').
        preview: G_p(1..N) (N,), gains on the future ZMP reference.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    integral: float
    state: np.ndarray
    preview: np.ndarray


def cart_table(period_s: float, com_height_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cart-table model's (A, B, C) for one axis (see the module docstring)."""
    T = float(period_s)
    A = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    B = np.array([T**3 / 6, T * T / 2, T])
    C = np.array([1.0, 0.0, -com_height_m / GRAVITY_M_S2])
    return A, B, C


def preview_gains(period_s: float, com_height_m: float, preview_s: float = 1.6,
                  q_error: float = 1.0, r_jerk: float = 1e-6) -> PreviewGains:
    """Solve the Riccati equation of the augmented system and return the gains (kept for
    the same arguments: a walk's re-plans reuse them).

    Args:
        period_s: control period T (s).
        com_height_m: CoM height above the ground z_c (m).
        preview_s: how far ahead the reference is seen (s); N = round(preview_s / T).
        q_error: weight Q_e on the ZMP error.
        r_jerk: weight R on the jerk (Kajita 2003 uses Q_e = 1, R = 1e-6).
    """
    return _preview_gains(*(float(v) for v in (period_s, com_height_m, preview_s, q_error,
                                               r_jerk)))


@lru_cache(maxsize=64)
def _preview_gains(period_s: float, com_height_m: float, preview_s: float, q_error: float,
                   r_jerk: float) -> PreviewGains:
    values = (period_s, com_height_m, preview_s, q_error, r_jerk)
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise ConfigError("preview control needs a positive period, CoM height, horizon and "
                          "weights", hint="e.g. period 0.005 s, height 0.6 m, horizon 1.6 s")
    A, B, C = cart_table(period_s, com_height_m)
    n_preview = max(1, int(round(preview_s / period_s)))
    # augmented state (sum of ZMP errors, x): e[k+1] = e[k] + C A x + C B u - p_ref[k+1]
    A_aug = np.zeros((4, 4))
    A_aug[0, 0] = 1.0
    A_aug[0, 1:] = C @ A
    A_aug[1:, 1:] = A
    B_aug = np.concatenate([[C @ B], B])[:, None]
    Q_aug = np.zeros((4, 4))
    Q_aug[0, 0] = q_error
    R = np.array([[r_jerk]])
    P = solve_discrete_are(A_aug, B_aug, Q_aug, R)
    scale = 1.0 / float(R[0, 0] + (B_aug.T @ P @ B_aug)[0, 0])
    K = scale * (B_aug.T @ P @ A_aug)[0]
    closed = A_aug - B_aug @ K[None, :]
    X = -closed.T @ P @ np.array([1.0, 0.0, 0.0, 0.0])
    preview = np.empty(n_preview)
    preview[0] = -K[0]
    for j in range(1, n_preview):
        preview[j] = scale * float(B_aug[:, 0] @ X)
        X = closed.T @ X
    for array in (A, B, C, preview):
        array.flags.writeable = False  # shared by every caller with these arguments
    state = K[1:].copy()
    state.flags.writeable = False
    return PreviewGains(A, B, C, float(K[0]), state, preview)


@dataclass(frozen=True)
class CoMPath:
    """A CoM path and the ZMP it produces, one row per period.

    Attributes:
        com_m: CoM position (n, 2), x and y in the ground frame (m).
        com_velocity_m_s: (n, 2).
        com_acceleration_m_s2: (n, 2).
        zmp_m: the cart-table ZMP of this motion (n, 2), p = c - z_c / g c''.
    """

    com_m: np.ndarray
    com_velocity_m_s: np.ndarray
    com_acceleration_m_s2: np.ndarray
    zmp_m: np.ndarray


def com_from_zmp(zmp_ref_m: np.ndarray, gains: PreviewGains,
                 com_start_m: np.ndarray | None = None,
                 com_motion_start: tuple[np.ndarray, np.ndarray] | None = None,
                 rows: int | None = None) -> CoMPath:
    """The CoM path whose ZMP follows ``zmp_ref_m`` (n x 2, m), one sample per period (its
    first ``rows`` only, when given: the rest of the reference is only previewed).

    The reference past its end is held at its last value (the robot stands there). The CoM
    starts at ``com_start_m`` (2,) (default: the first reference point), at rest unless
    ``com_motion_start`` gives its velocity and acceleration (2, each; a pattern re-planned in
    motion continues from its own state).
    """
    ref = np.asarray(zmp_ref_m, dtype=float)
    if ref.ndim != 2 or ref.shape[1] != 2 or len(ref) == 0 or not np.all(np.isfinite(ref)):
        raise ConfigError("the ZMP reference must be a finite n x 2 array of metres")
    n, n_preview = len(ref), len(gains.preview)
    out = n if rows is None else max(1, min(int(rows), n))
    padded = np.vstack([ref, np.repeat(ref[-1:], n_preview, axis=0)])
    x = np.zeros((3, 2))  # rows: c, c', c''; columns: x, y
    x[0] = ref[0] if com_start_m is None else np.asarray(com_start_m, dtype=float)
    if com_motion_start is not None:
        x[1], x[2] = (np.asarray(v, dtype=float) for v in com_motion_start)
    com, velocity, acceleration, zmp = (np.empty((out, 2)) for _ in range(4))
    _preview_run(ref, padded, x, gains.A, gains.B, gains.C, gains.integral, gains.state,
                 gains.preview, com, velocity, acceleration, zmp)
    return CoMPath(com, velocity, acceleration, zmp)


@nb.njit(cache=True, nogil=True)
def _preview_run(ref, padded, x, A, B, C, integral, state, preview, com, velocity,
                 acceleration, zmp):
    """:func:`com_from_zmp`'s loop, compiled: the state ``x`` (3 x 2) driven through the
    rows of ``ref`` the four outputs hold (their length)."""
    n, n_preview = com.shape[0], preview.shape[0]
    error_sum = np.zeros(2)
    future = np.empty(2)
    u = np.empty(2)
    nxt = np.empty(3)
    for k in range(n):
        for axis in range(2):
            p = C[0] * x[0, axis] + C[1] * x[1, axis] + C[2] * x[2, axis]
            com[k, axis], velocity[k, axis], acceleration[k, axis] = x[0, axis], x[1, axis], \
                x[2, axis]
            zmp[k, axis] = p
            error_sum[axis] += p - ref[k, axis]
            future[axis] = 0.0
            for j in range(n_preview):
                future[axis] += preview[j] * padded[k + 1 + j, axis]
            u[axis] = (-integral * error_sum[axis] - (state[0] * x[0, axis]
                       + state[1] * x[1, axis] + state[2] * x[2, axis]) - future[axis])
        for axis in range(2):  # x = A x + B u
            for r in range(3):
                nxt[r] = (A[r, 0] * x[0, axis] + A[r, 1] * x[1, axis] + A[r, 2] * x[2, axis]
                          + B[r] * u[axis])
            for r in range(3):
                x[r, axis] = nxt[r]
