"""A limb of the HUBO 2+: forward and inverse kinematics in the neck frame N.

N: origin at the neck (shoulder height on the torso centre line), x forward, y left, z up.
Right limbs sit at -y. Arms end at a tool frame (``none``, ``hand`` or ``drill``); legs end at
the sole frame F, parallel to N when all leg joints are zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from hubo_cli.kinematics import choice
from hubo_cli.kinematics.dh import chain_fk, chain_fk_batch, kernel_array
from hubo_cli.model import LimbSpec, RobotModel, load_model

_HALF_PI = np.pi / 2
ARM_DH = {  # paper Table II: theta offset, alpha; a and d filled from the lengths
    "offset": [_HALF_PI, -_HALF_PI, _HALF_PI, 0.0, 0.0, _HALF_PI],
    "alpha": [_HALF_PI, _HALF_PI, -_HALF_PI, _HALF_PI, -_HALF_PI, 0.0],
}
LEG_DH = {  # paper Table III
    "offset": [0.0, -_HALF_PI, 0.0, 0.0, 0.0, 0.0],
    "alpha": [_HALF_PI, -_HALF_PI, 0.0, 0.0, _HALF_PI, 0.0],
}
T_6_SOLE = np.array([[0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])  # Ry(-pi/2): the sole frame parallel to N at q = 0


@dataclass(frozen=True)
class IKResult:
    """What one IK call did.

    Attributes:
        q_rad: the chosen joints (6,), in the paper's DH order.
        status: ``exact``, ``capped``, ``held`` or ``unreachable`` (see :mod:`.choice`).
        position_error_m: distance between the goal and FK(q_rad).
        rotation_error_rad: angle between the goal's and FK(q_rad)'s orientations.
    """

    q_rad: np.ndarray
    status: str
    position_error_m: float
    rotation_error_rad: float

    @property
    def exact(self) -> bool:
        return self.status == "exact"


@dataclass(frozen=True)
class Candidate:
    """One of the eight IK candidates, checked with FK."""

    q_rad: np.ndarray
    within_limits: bool
    position_error_m: float
    rotation_error_rad: float

    @property
    def exact(self) -> bool:
        return (self.position_error_m <= choice.EXACT_POS_TOL_M
                and self.rotation_error_rad <= choice.EXACT_ROT_TOL_RAD)


@dataclass(frozen=True)
class BatchIKResult:
    """IK over N goals: joints (N x 6), status codes (N,), errors (N,) in m and rad."""

    q_rad: np.ndarray
    status: np.ndarray
    position_error_m: np.ndarray
    rotation_error_rad: np.ndarray

    def status_names(self) -> list[str]:
        return [choice.STATUS_NAMES[s] for s in self.status]


class Limb:
    """Forward and inverse kinematics of one limb with one end frame.

    Args:
        model: the robot model (parameter set and limits).
        name: ``right-arm``, ``left-arm``, ``right-leg`` or ``left-leg``.
        tool: arm end frame, ``none``, ``hand`` or ``drill``; ignored for legs (sole frame).
    """

    def __init__(self, model: RobotModel, name: str, tool: str = "hand") -> None:
        self.model = model
        self.spec: LimbSpec = model.limb(name)
        self.name = self.spec.name
        self.tool = tool if self.spec.is_arm else "sole"
        L = model.lengths_m
        side = self.spec.side
        base = np.eye(4)
        if self.spec.is_arm:  # eq. 2 with the shoulder at side * lA1
            base[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
            base[1, 3] = side * L["lA1"]
            dh = ARM_DH
            a = [0, 0, 0, 0, 0, L["lA4"]]
            d = [0, 0, -L["lA2"], 0, -L["lA3"], 0]
            end = model.tool_transform(tool)
            self.lengths_m = np.array([L["lA2"], L["lA3"], L["lA4"]])
        else:  # eq. 8: Tz(-lT) then the hip at (0, side * lL1, -lL2), rotated +90 deg about z
            base[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
            base[:3, 3] = [0.0, side * L["lL1"], -L["lT"] - L["lL2"]]
            dh = LEG_DH
            a = [0, 0, L["lL3"], L["lL4"], 0, L["lL5"]]
            d = [0.0] * 6
            end = T_6_SOLE
            self.lengths_m = np.array([L["lL3"], L["lL4"], L["lL5"]])
        self.T_N_base = base
        self.T_6_end = np.asarray(end, dtype=float)
        self.chain = (base, np.linalg.inv(base), np.array(dh["offset"], dtype=float),
                      np.array(dh["alpha"], dtype=float), np.array(a, dtype=float),
                      np.array(d, dtype=float), self.T_6_end, np.linalg.inv(self.T_6_end))
        self.lower_rad = self.spec.lower_rad
        self.upper_rad = self.spec.upper_rad
        self.hold_m = float(model.safety["ik_hold_distance_m"])
        self._is_arm = self.spec.is_arm  # read every solve

    @property
    def fk_chain(self) -> tuple:
        """The forward kinematics' part of :attr:`chain`, as the compiled kernels take it:
        base, offset, alpha, a, d, end (derived each time: a subclass that replaces the chain,
        as the workspace's mirrored tool does, changes both)."""
        base, _, offset, alpha, a, d, end, _ = self.chain
        return base, offset, alpha, a, d, end

    def __repr__(self) -> str:
        return f"Limb({self.name!r}, tool={self.tool!r}, params={self.model.params_name!r})"

    # ------------------------------------------------------------------ forward kinematics
    def fk(self, q_rad) -> np.ndarray:
        """T_N_E: the end frame in the neck frame (4x4, m) for joints q (6,) in rad."""
        out = np.empty((4, 4))
        chain_fk(kernel_array(q_rad), *self.fk_chain, out)  # the kernel only reads q
        return out

    def fk_batch(self, Q_rad) -> np.ndarray:
        """T_N_E for N joint vectors (N x 6, rad) -> N x 4 x 4 (m)."""
        Q = np.ascontiguousarray(np.atleast_2d(Q_rad), dtype=float)
        return chain_fk_batch(Q, *self.fk_chain)

    # ------------------------------------------------------------------ inverse kinematics
    def candidates(self, T_N_E, q_prev_rad=None) -> list[Candidate]:
        """All eight closed-form candidates for the goal T_N_E, each checked with FK."""
        q_prev = np.zeros(6) if q_prev_rad is None else np.asarray(q_prev_rad, dtype=float)
        T_goal = np.ascontiguousarray(T_N_E, dtype=float)
        out = np.empty((8, 6))
        exact = np.zeros(8, dtype=np.bool_)
        choice.limb_candidates(T_goal, self.chain, self.lengths_m, self.spec.is_arm, q_prev,
                               out, exact)
        result = []
        for q in out:
            pos, rot = choice.pose_error(self.fk(q), T_goal)
            inside = bool(np.all(q >= self.lower_rad) and np.all(q <= self.upper_rad))
            result.append(Candidate(q, inside, pos, rot))
        return result

    def solve(self, T_N_E, q_prev_rad=None) -> IKResult:
        """Choose one solution for the goal T_N_E (4x4, m) by the rule of :mod:`.choice`."""
        q = np.empty(6)
        status, pos, rot = self.solve_into(T_N_E, q_prev_rad, q)
        return IKResult(q, choice.STATUS_NAMES[status], pos, rot)

    def solve_into(self, T_N_E, q_prev_rad, q_out: np.ndarray) -> tuple[int, float, float]:
        """:meth:`solve`'s joints into ``q_out`` (6,), without the result object: returns
        (status code, position error m, rotation error rad); the status's name is
        ``choice.STATUS_NAMES[code]``."""
        has_prev = q_prev_rad is not None
        # the kernel only reads the goal and q_prev: no copies of arrays it takes as they are
        return choice.solve_limb(
            kernel_array(T_N_E), self.chain, self.lengths_m, self._is_arm, self.lower_rad,
            self.upper_rad, kernel_array(q_prev_rad) if has_prev else np.zeros(6), has_prev,
            self.hold_m, True, q_out)

    def solve_batch(self, T_N_E, q_prev_rad=None, allow_cap: bool = True) -> BatchIKResult:
        """Solve N goals (N x 4 x 4, m) on all cores; q_prev_rad is N x 6 or None.

        With ``allow_cap=False`` unreachable goals are only flagged (faster; for maps).
        """
        T = np.ascontiguousarray(T_N_E, dtype=float).reshape(-1, 4, 4)
        has_prev = q_prev_rad is not None
        if has_prev:
            Q = np.array(np.broadcast_to(q_prev_rad, (len(T), 6)), dtype=float)  # writable
        else:
            Q = np.zeros((len(T), 6))
        q, status, pos, rot = choice.solve_limb_batch(
            T, self.chain, self.lengths_m, self.spec.is_arm, self.lower_rad, self.upper_rad, Q,
            has_prev, self.hold_m, allow_cap)
        return BatchIKResult(q, status, pos, rot)

    def random_q(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """Uniform random joints within the limits ((6,) or (n, 6), rad)."""
        size = None if n is None else (n, 6)
        return rng.uniform(self.lower_rad, self.upper_rad, size=size)


@cache
def get_limb(name: str, tool: str = "hand", params: str = "as-built",
             limits: str = "table4") -> Limb:
    """A cached :class:`Limb` for the shipped model."""
    return Limb(load_model(params, limits), name, tool)
