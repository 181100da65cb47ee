"""Compiled pieces of the per-period log row (:mod:`hubo_cli.control.log`): the torso's and
the hands' world poses as the log's columns in one call.

The poses go to the CSV with 12 significant digits, far coarser than the last bits in which
this compiled arithmetic may differ from numpy's matrix products.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, chain_fk


@nb.njit(inline="always", **JIT)
def _pose_into(T, out, at):
    """``out[at:at + 6]`` = x, y, z, roll, pitch, yaw (URDF convention) of the pose T (4x4)."""
    out[at] = T[0, 3]
    out[at + 1] = T[1, 3]
    out[at + 2] = T[2, 3]
    cos_pitch = math.hypot(T[0, 0], T[1, 0])
    pitch = math.atan2(-T[2, 0], cos_pitch)
    if cos_pitch < 1e-12:  # gimbal lock: put everything in yaw
        out[at + 3] = 0.0
        out[at + 4] = pitch
        out[at + 5] = math.atan2(-T[0, 1], T[1, 1])
    else:
        out[at + 3] = math.atan2(T[2, 1], T[2, 2])
        out[at + 4] = pitch
        out[at + 5] = math.atan2(T[1, 0], T[0, 0])


@nb.njit(**JIT)
def pose_row(T_world_torso, q, index, base, offset, alpha, a, d, end, out, at):
    """The torso's world pose, then each hand's (forward kinematics of its arm's joints
    ``q[index[h]]`` through the chain ``base[h] ... end[h]``, then through the torso pose), as
    six columns each (:func:`_pose_into`) from ``out[at]`` on."""
    _pose_into(T_world_torso, out, at)
    T_N_E = np.empty((4, 4))
    T = np.empty((4, 4))
    q_arm = np.empty(index.shape[1])
    for h in range(index.shape[0]):
        for j in range(index.shape[1]):
            q_arm[j] = q[index[h, j]]
        chain_fk(q_arm, base[h], offset[h], alpha[h], a[h], d[h], end[h], T_N_E)
        for r in range(4):
            for c in range(4):
                s = 0.0
                for k in range(4):
                    s += T_world_torso[r, k] * T_N_E[k, c]
                T[r, c] = s
        _pose_into(T, out, at + 6 * (h + 1))
