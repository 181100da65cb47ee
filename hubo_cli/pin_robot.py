"""The robot's URDF in pinocchio, for the modules that need mass or geometry (CoM, collision).

Pinocchio orders its joints by the URDF tree, not by :attr:`RobotModel.joint_names`;
:class:`PinRobot` keeps the mapping so callers pass the usual 24-vectors.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import RobotModel
from hubo_cli.state import GRAVITY_M_S2


@dataclass
class PinRobot:
    """A pinocchio model of the URDF and the index of each limb joint in its configuration.

    Attributes:
        model: the pinocchio model (root ``torso`` = neck frame N).
        q_index: where joint i of ``RobotModel.joint_names`` sits in pinocchio's q.
        floating: True when the root is a free flyer (q starts with x y z qx qy qz qw).
        urdf_path: the file it was built from.
    """

    model: pin.Model
    q_index: np.ndarray
    floating: bool
    urdf_path: Path

    def configuration(self, q_rad: np.ndarray, T_world_torso: np.ndarray | None = None,
                      out: np.ndarray | None = None) -> np.ndarray:
        """Pinocchio's q for the limb joints ``q_rad`` (rad) and, for a floating model, the
        torso pose in the world (4x4, m; identity if None)."""
        q = np.zeros(self.model.nq) if out is None else out
        q[self.q_index] = q_rad
        if self.floating:
            if T_world_torso is None:
                q[:7] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
            else:
                q[:3] = T_world_torso[:3, 3]
                q[3:7] = pin.Quaternion(T_world_torso[:3, :3]).coeffs()  # x y z w
        return q

    @property
    def weight_n(self) -> float:
        """The robot's weight (N): its total mass (tools in the URDF included) at standard
        gravity."""
        return float(pin.computeTotalMass(self.model)) * GRAVITY_M_S2

    def frame_id(self, name: str) -> int:
        """The id of a URDF frame (link) by name; the error lists the end frames."""
        if not self.model.existFrame(name):
            raise ConfigError(f"the URDF has no frame {quoted(name)}", path=str(self.urdf_path))
        return self.model.getFrameId(name)


@cache
def _build(urdf_path: Path, floating: bool) -> tuple[pin.Model, tuple[str, ...]]:
    if not urdf_path.exists():
        raise ConfigError("the robot URDF is missing", path=str(urdf_path),
                          hint="regenerate it with tools/make_urdf.py")
    if floating:
        model = pin.buildModelFromUrdf(str(urdf_path), pin.JointModelFreeFlyer())
    else:
        model = pin.buildModelFromUrdf(str(urdf_path))
    return model, tuple(model.names)


def load_pin_robot(model: RobotModel, floating: bool = False,
                   urdf_path: Path | None = None) -> PinRobot:
    """Build (once, then cached) the pinocchio model of the robot's URDF.

    Args:
        model: the robot model (joint names, URDF path).
        floating: add a free-flyer root joint (for the centre of mass in the world).
        urdf_path: another URDF of the same robot (e.g. the drill variant).
    """
    path = Path(urdf_path) if urdf_path is not None else Path(model.urdf_path())
    pmodel, names = _build(path, floating)
    index = []
    for joint in model.joint_names:
        if joint not in names:
            raise ConfigError(f"the URDF has no joint {quoted(joint)}", path=str(path))
        index.append(pmodel.joints[pmodel.getJointId(joint)].idx_q)
    return PinRobot(pmodel, np.array(index, dtype=int), floating, path)
