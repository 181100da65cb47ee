"""The soles' support as the walk sees it: the feet the estimate stands on and their ankles'
wrenches, the soles the pattern has on the floor period by period, and how far a ZMP lies
outside the hull of the soles in contact.

Shared by the walking target (:mod:`hubo_cli.walking.target`) and the standing capture stepper
(:mod:`hubo_cli.walking.capture_step`), which read the same estimate keys the same way.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.control.capture_point import convex_hull, outside_distance
from hubo_cli.control.wrench_distribution import Contact
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import T_WORLD_SOLES, WRENCHES
from hubo_cli.state import ANKLE_SENSORS
from hubo_cli.walking.body import poses_of_rows
from hubo_cli.walking.footsteps import Footstep
from hubo_cli.walking.gait import Gait

SIDES = ("right", "left")  # the estimate's order of the feet (and of ANKLE_SENSORS)


def estimated_feet(store: Store) -> dict[str, Footstep]:
    """The footsteps the estimate's soles stand on (right, left)."""
    poses = store[T_WORLD_SOLES]
    return {side: footstep_of(side, poses[k]) for k, side in enumerate(SIDES)}


def ankle_wrenches(store: Store) -> np.ndarray:
    """The ankles' compensated wrenches (2 x 6: right, left; sole frame, N and N m)."""
    wrenches = store[WRENCHES]
    return np.array([wrenches[sensor] for sensor in ANKLE_SENSORS], dtype=float)


def footstep_of(side: str, T_world_sole: np.ndarray) -> Footstep:
    """The footstep a sole's world pose (4x4) stands on."""
    return Footstep(side, float(T_world_sole[0, 3]), float(T_world_sole[1, 3]),
                    math.atan2(T_world_sole[1, 0], T_world_sole[0, 0]))


def zmp_outside_m(zmp_m: np.ndarray, poses: np.ndarray, corners_m: np.ndarray,
                  contact: tuple[bool, bool]) -> float:
    """How far the ZMP ``zmp_m`` (world x, y) lies outside the convex hull of the soles in
    ``contact`` (m; <= 0 inside; inf with none in contact or a non-finite ZMP)."""
    if not (contact[0] or contact[1]) or not (math.isfinite(zmp_m[0])
                                              and math.isfinite(zmp_m[1])):
        return math.inf
    return _hull_outside(np.ascontiguousarray(poses, dtype=float), corners_m,
                         np.array(contact, dtype=np.bool_),
                         np.ascontiguousarray(zmp_m[:2], dtype=float))


@nb.njit(cache=True, nogil=True)
def _hull_outside(poses, corners, contact, point):
    """How far ``point`` lies outside the hull of the soles in ``contact`` (one sole: its own
    outline, corners in order)."""
    points = np.empty((poses.shape[0] * corners.shape[0], 2))
    n = loaded = 0
    for s in range(poses.shape[0]):
        if not contact[s]:
            continue
        T = poses[s]
        for c in range(corners.shape[0]):
            points[n, 0] = corners[c, 0] * T[0, 0] + corners[c, 1] * T[0, 1] + T[0, 3]
            points[n, 1] = corners[c, 0] * T[1, 0] + corners[c, 1] * T[1, 1] + T[1, 3]
            n += 1
        loaded += 1
    if loaded == 1:
        return outside_distance(points[:n], point)
    return outside_distance(convex_hull(points[:n]), point)


def planned_contacts(gait: Gait) -> list[tuple[Contact | None, Contact | None]]:
    """Per period the soles the pattern has on the ground as the force distribution takes
    them (right, left; None in the air): where the footstep stands, its reference CoP (the
    toe-heel plan's; flat feet: the sole's origin) and, rolling on its toe or heel, that
    edge."""
    plan = gait.toe_heel
    contacts = []
    for k in range(gait.n):
        pair = []
        for column, side in enumerate(SIDES):
            if not gait.support[k, column]:
                pair.append(None)
            elif plan is None:
                x, y, _, yaw = gait.feet[side][k].tolist()
                pair.append(Contact((x, y), yaw))
            else:
                x, y, yaw = plan.foot_pose[k, column].tolist()
                rolling = plan.foot_angle_rad[k, column] != 0.0
                pair.append(Contact((x, y), yaw, tuple(plan.cop_m[k, column].tolist()),
                                    float(plan.pivot_m[k, column]) if rolling else None))
        contacts.append(tuple(pair))
    return contacts


def planned_support(gait: Gait, floor_z_m: float | None = None) -> np.ndarray:
    """Per period the soles that carry the robot in this phase of the step, the swing foot at
    its landing place: (n, 2, 4, 4) world poses (right, left), for the capture-point monitor.

    Every sole lies on the floor at ``floor_z_m`` (the estimated sole height the plan was made
    from; None: each sole's height in the pattern's first row, a pattern that starts standing).
    A pattern re-planned mid-swing starts with the swing foot 15-19 mm up: at that height the
    monitor would drop its landing place as a lifted sole and judge the capture point against
    the stance sole alone."""
    poses = np.empty((gait.n, 2, 4, 4))
    index = np.arange(gait.n)
    for column, side in enumerate(SIDES):
        rows = gait.feet[side].copy()
        # a swing phase ends with the foot down: each swinging period takes the row where the
        # swing ends (the next period on the ground; the last row if none)
        down = np.where(gait.support[:, column], index, gait.n - 1)
        landing = np.minimum.accumulate(down[::-1])[::-1]
        rows = rows[np.where(gait.support[:, column], index, landing)]
        rows[:, 2] = gait.feet[side][0, 2] if floor_z_m is None else floor_z_m
        poses[:, column] = poses_of_rows(rows)
    return poses
