"""The legs' goal in the raised neck frame for :meth:`hubo_cli.kinematics.wholebody.WholeBody.
legs_at`, compiled: numpy's 4x4 product with its Python wrapper and the lift's transform was
most of a leg solve's time outside :func:`~hubo_cli.kinematics.choice.solve_limb`.
"""

from __future__ import annotations

import numba as nb

from hubo_cli.kinematics.dh import JIT


@nb.njit(**JIT)
def neck_from_stance(T_S, shift_m, lift_m, out):
    """out = T_N_S @ T_S, T_N_S the identity with (-shift_m, 0, -lift_m) as its translation:
    numpy's product term by term (each entry the sum of its four products: at most one of them
    neither zero nor exact, so it is ``@``'s to the last bit and sign, in any order)."""
    for i in range(4):
        for j in range(4):
            t0 = 1.0 * T_S[0, j] if i == 0 else 0.0 * T_S[0, j]
            t1 = 1.0 * T_S[1, j] if i == 1 else 0.0 * T_S[1, j]
            t2 = 1.0 * T_S[2, j] if i == 2 else 0.0 * T_S[2, j]
            if i == 0:
                m3 = -shift_m
            elif i == 2:
                m3 = -lift_m
            elif i == 3:
                m3 = 1.0
            else:
                m3 = 0.0
            out[i, j] = t0 + t1 + t2 + m3 * T_S[3, j]
