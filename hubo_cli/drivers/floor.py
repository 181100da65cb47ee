"""The floor's reaction on a robot standing still: what the ideal driver's ankle sensors add to
the weight of the foot beyond them.

The ideal driver has no physics: its lower sole is flat on the floor (first leg on a tie, as its
IMU has it) and nothing accelerates. A robot standing still in that posture carries its whole
weight M g (the URDF's masses, the drill's when held) on the soles on the floor, and their total
centre of pressure lies under its centre of mass. A sole is on the floor when its origin is
within FLOOR_BAND_M of the lower sole's height; otherwise it is in the air and its sensor reads
the foot's weight alone.

With both soles down the split is not unique (statics fixes the total force and the total
CoP, not each sole's). The rule taken, in the horizontal plane, each sole's centre c_k the
middle of its polygon (``feet.forward_m`` ahead of the sole frame's origin):

* the lever rule along the line between the centres: s = the CoM's projection on it, clipped to
  [0, 1] (0 at the right sole's centre); the left sole carries s M g, the right (1 - s) M g;
* what the line leaves, d = CoM - (c_r + s (c_l - c_r)), is carried by both soles alike: each
  sole's CoP is c_k + d. That is the split whose worse sole's CoP is nearest its centre: the
  total CoP is the force-weighted mean of the two, so one of them is at least |d| from its
  centre whatever the split, and here both are exactly |d|.

It is continuous in the posture while both soles stay down, and it gives the pure vertical
loads (no moment) of a CoM on the line between the centres. The total CoP is under the CoM
even when the CoM is beyond the soles (then a CoP off a sole's polygon, which a real robot
cannot hold: it would tip; the ideal driver has no physics, and the estimate reads it).

The floor pushes straight up (no friction: nothing moves) at each sole's CoP; the sensor reads
that push about its origin in its own axes (N, N m; the sole frame, tilted only for a sole down
but not flat), its f_z, m_x and m_y as Hubo's sensors measure them.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.estimation.centre_of_mass import centre_of_mass, configure, tree_arrays
from hubo_cli.estimation.wrenches import hanging_readings
from hubo_cli.geometry import quat_to_matrix_into
from hubo_cli.kinematics.dh import JIT, chain_fk
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import ANKLE_SENSORS, FT_SENSORS

# [chosen] a sole whose origin is within this of the lower sole's height is on the floor too
# (the rubber under a Hubo sole and a floor's unevenness are of this order; the ideal driver's
# double support holds both soles at the same height to the IK's precision, 1e-9 m)
FLOOR_BAND_M = 0.005


def floor_arrays(model: RobotModel, drill: bool) -> tuple:
    """The arguments of :func:`standing_readings` after the hanging readings': pinocchio's
    floating configuration (a scratch array), where each joint sits in it, the tree of
    :func:`~hubo_cli.estimation.centre_of_mass.tree_arrays` (the drill's URDF when held), the
    two ankle sensors' rows in FT_SENSORS (right, left) and the sole's centre in its frame
    (m)."""
    robot = load_pin_robot(model, floating=True, urdf_path=model.urdf_path(drill))
    q_pin = robot.configuration(np.zeros(len(model.joint_names)))
    ankles = np.array([FT_SENSORS.index(s) for s in ANKLE_SENSORS], dtype=np.int64)
    centre = np.array([model.feet.forward_m, 0.0, 0.0])
    return (q_pin, np.asarray(robot.q_index, dtype=np.int64), *tree_arrays(robot.model), ankles,
            centre)


@nb.njit(**JIT)
def standing_readings(q, quat_wxyz, index, base, offset, alpha, a, d, end, mass, com, gravity,
                      measured, q_pin, q_index, parent, axis, q_at, R_place, p_place,
                      tree_mass, lever, ankles, centre, band_m, out):
    """What the sensors of a robot standing still read (``out``, n x 6, FT_SENSORS order) in
    the joints ``q`` (rad), torso attitude ``quat_wxyz``: the weight beyond each
    (:func:`~hubo_cli.estimation.wrenches.hanging_readings`, its arguments ``index`` ...
    ``measured``) and at the ankles the floor's push (see the module docstring; the rest
    :func:`floor_arrays`). One compiled call: the driver's period pays one dispatch."""
    hanging_readings(q, quat_wxyz, index, base, offset, alpha, a, d, end, mass, com, gravity,
                     measured, out)
    R = np.empty((3, 3))
    quat_to_matrix_into(quat_wxyz, R)
    T_world_torso = np.eye(4)
    for i in range(3):
        for j in range(3):
            T_world_torso[i, j] = R[i, j]
    com_w = np.empty(3)  # the centre of mass from the torso's origin, world axes
    configure(q_pin, q_index, q, T_world_torso)
    centre_of_mass(q_pin, parent, axis, q_at, R_place, p_place, tree_mass, lever, com_w)
    weight = gravity * tree_mass.sum()
    T = np.empty((2, 4, 4))  # the soles in the torso
    qk = np.empty(6)
    for f in range(2):
        k = ankles[f]
        for j in range(6):
            qk[j] = q[index[k, j]]
        chain_fk(qk, base[k], offset[k], alpha[k], a[k], d[k], end[k], T[f])
    R_ws = np.empty((2, 3, 3))  # the soles' axes, origins and centres in the world's
    origin = np.empty((2, 3))
    mid = np.empty((2, 3))
    for f in range(2):
        for i in range(3):
            for j in range(3):
                R_ws[f, i, j] = R[i, 0] * T[f, 0, j] + R[i, 1] * T[f, 1, j] + R[i, 2] * T[f, 2, j]
            origin[f, i] = R[i, 0] * T[f, 0, 3] + R[i, 1] * T[f, 1, 3] + R[i, 2] * T[f, 2, 3]
        for i in range(3):
            mid[f, i] = origin[f, i] + R_ws[f, i, 0] * centre[0] + R_ws[f, i, 1] * centre[1] \
                + R_ws[f, i, 2] * centre[2]
    flat = 1 if T[1, 2, 3] < T[0, 2, 3] else 0  # the driver's lower sole (first on a tie)
    other = 1 - flat
    load = np.zeros(2)
    cop = np.empty((2, 2))
    if abs(origin[other, 2] - origin[flat, 2]) <= band_m:
        ux, uy = mid[1, 0] - mid[0, 0], mid[1, 1] - mid[0, 1]  # right centre -> left centre
        span2 = ux * ux + uy * uy
        s = 0.5
        if span2 > 1e-12:
            s = ((com_w[0] - mid[0, 0]) * ux + (com_w[1] - mid[0, 1]) * uy) / span2
            s = min(max(s, 0.0), 1.0)
        dx = com_w[0] - (mid[0, 0] + s * ux)
        dy = com_w[1] - (mid[0, 1] + s * uy)
        load[0], load[1] = (1.0 - s) * weight, s * weight
        for f in range(2):
            cop[f, 0], cop[f, 1] = mid[f, 0] + dx, mid[f, 1] + dy
    else:
        load[flat] = weight
        cop[flat, 0], cop[flat, 1] = com_w[0], com_w[1]
    for f in range(2):
        if load[f] == 0.0:
            continue
        fz = load[f]
        rx, ry = cop[f, 0] - origin[f, 0], cop[f, 1] - origin[f, 1]
        mw0, mw1 = ry * fz, -rx * fz  # (r x (0, 0, fz)) about the origin, world axes
        k = ankles[f]
        for i in range(3):  # in the sole's axes: R_ws^T
            out[k, i] += R_ws[f, 2, i] * fz * measured[i]
            out[k, 3 + i] += (R_ws[f, 0, i] * mw0 + R_ws[f, 1, i] * mw1) * measured[3 + i]
