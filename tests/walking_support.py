"""Helpers shared by the walking tests: the estimate of the walking posture standing still, and
a walk's target played offline from it (no simulator)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
    ZMP_WORLD,
)
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel, load_model
from hubo_cli.state import FT_SENSORS
from hubo_cli.walking.body import WalkingBody, walking_posture
from hubo_cli.walking.params import DEFAULT_GAIT, walking_params
from hubo_cli.walking.stabilizer import StabilizerGains
from hubo_cli.walking.target import WalkTarget


def wrench_at(px, py, fz=380.0):
    """The ground's wrench on a sole whose centre of pressure is (px, py) in the sole frame."""
    return np.array([0.0, 0.0, fz, fz * py, -fz * px, 0.0])


def standing_store(model, q_rad, T_world_neck, right_yaw_rad=0.0, pitch_rad=0.0,
                   fz_n=190.0) -> Store:
    """The estimate of the walking posture standing still: the soles where the legs put them
    (the right one turned by ``right_yaw_rad`` about its vertical), both in contact carrying
    ``fz_n`` at their middles, and the CoM of the torso pitched by ``pitch_rad`` about the
    soles (as the IMU would read it)."""
    store = Store()
    soles = []
    for name in ("right-leg", "left-leg"):
        soles.append(T_world_neck @ Limb(model, name).fk(q_rad[model.limb_slice(name)]))
    c, s = np.cos(right_yaw_rad), np.sin(right_yaw_rad)
    turn = np.eye(4)
    turn[:2, :2] = ((c, -s), (s, c))
    soles[0] = soles[0] @ turn
    body = WalkingBody(model, q_rad, T_world_neck)
    com_in_neck = body.com_in_neck(q_rad)
    R = quat_wxyz_to_matrix(np.array([np.cos(pitch_rad / 2), 0.0, np.sin(pitch_rad / 2), 0.0]))
    ground = np.mean([T[:3, 3] for T in soles], axis=0)
    store[T_WORLD_SOLES] = np.array(soles)
    store[T_WORLD_TORSO] = T_world_neck
    store[CONTACT] = (True, True)
    store[COM_WORLD] = ground + R @ (T_world_neck[:3, :3] @ com_in_neck + T_world_neck[:3, 3]
                                     - ground)
    store[WRENCHES] = {name: np.zeros(6) for name in FT_SENSORS} | {
        "right-ankle": wrench_at(0.0, 0.0, fz_n), "left-ankle": wrench_at(0.0, 0.0, fz_n)}
    store[ZMP_WORLD] = ground[:2]
    store[CAPTURE_POINT_WORLD] = store[COM_WORLD][:2].copy()  # standing still
    return store


class StandingWalk(NamedTuple):
    """A walk's target attached to the estimate of its start posture (:func:`standing_walk`)."""

    model: RobotModel  # the as-built model with the walking limits
    q_start_rad: np.ndarray  # the walking posture
    T_world_neck: np.ndarray  # the torso's pose in it
    target: WalkTarget
    store: Store


def standing_walk(goal_m, stabilizer: StabilizerGains | None, gait: str = DEFAULT_GAIT,
                  **store_options) -> StandingWalk:
    """The target of a walk to ``goal_m`` (forward, left, turn) without corrections, with
    ``stabilizer``'s gains (None: none), on the as-built model with the walking limits and its
    ``gait``'s walking parameters, attached to the estimate of its start posture standing
    still (:func:`standing_store` with ``store_options``), not yet run."""
    model = load_model("as-built", "walking")
    params = walking_params(model, gait)
    q_start, T_world_neck = walking_posture(model, params.step_width_m, params.crouch_m)
    target = WalkTarget(model, params, goal_m, q_start, T_world_neck, corrections=0,
                        stabilizer=stabilizer)
    store = standing_store(model, q_start, T_world_neck, **store_options)
    target.attach(None, [], store)
    return StandingWalk(model, q_start, T_world_neck, target, store)
