"""The Stabilizer's LIP state feedback (multi-layer paper, III-D.1, eq. 7-8; Kajita et al.,
IROS 2010, the paper's [18]; hrpsys-base ``Stabilizer.cpp``, eefm_k1..k3).

Per horizontal axis the state is X = [x_G, x_G', p]: the CoM (m), its velocity (m/s) and the
ZMP (m). The CoM is a linear inverted pendulum of height z_c, and the real ZMP follows the
commanded one u with a first-order lag T_p (the sole's compliance and the foot force control
between them)::

    d/dt X = A X + B u,   A = [[0, 1, 0], [w^2, 0, -w^2], [0, 0, -1/T_p]],   B = [0, 0, 1/T_p]
                                                                                   (eq. 7)
    u = p_ref + K (X_ref - X)                                                      (eq. 8)

with w = sqrt(g / z_c). The gain K = [k1, k2, k3] is computed by **pole placement** (as Kajita
2010 does; hrpsys ships its result as eefm_k1..k3): A - B K has the poles asked for. Matching
det(sI - A + B K) = s^3 + ((1 + k3)/T_p) s^2 - w^2 (1 + k2/T_p) s - w^2 (1 + k1 + k3)/T_p
with the polynomial s^3 + c2 s^2 + c1 s + c0 of the poles gives, in closed form,

    k3 = T_p c2 - 1,   k2 = -T_p (1 + c1 / w^2),   k1 = -T_p (c2 + c0 / w^2).

The poles are the robot file's ``[lip_feedback] poles_per_omega`` times w, so the gains follow
the CoM height. k1, k2 < 0: a CoM ahead of its reference moves the ZMP further ahead, which
pushes it back.

The command u is not clipped here: the force distribution (:mod:`~hubo_cli.control.
wrench_distribution`) moves it into the support polygon and says so. The total force that goes
with it is the pendulum's, :func:`lip_ground_force`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import RobotModel
from hubo_cli.state import GRAVITY_M_S2


@dataclass(frozen=True)
class LipFeedbackParams:
    """The robot file's ``[lip_feedback]`` table.

    Attributes:
        zmp_time_constant_s: T_p, the real ZMP's lag behind the command (s).
        poles_per_omega: the three closed-loop poles divided by w (real, negative).
    """

    zmp_time_constant_s: float
    poles_per_omega: tuple[float, float, float]

    def __post_init__(self) -> None:
        t = self.zmp_time_constant_s
        if isinstance(t, bool) or not isinstance(t, int | float) or not (
                math.isfinite(t) and t > 0):
            raise ConfigError(f"zmp_time_constant_s must be a positive number, got {quoted(t)}",
                              field="lip_feedback.zmp_time_constant_s")
        poles = self.poles_per_omega
        if len(poles) != 3 or not all(
                isinstance(p, int | float) and not isinstance(p, bool) and math.isfinite(p)
                and p < 0 for p in poles):
            raise ConfigError(f"poles_per_omega must be three negative numbers, got "
                              f"{quoted(poles)}",
                              field="lip_feedback.poles_per_omega",
                              hint="a pole >= 0 would leave the pendulum unstable")

    @classmethod
    def from_model(cls, model: RobotModel) -> LipFeedbackParams:
        raw = model.raw_table("lip_feedback")
        try:
            return cls(raw.get("zmp_time_constant_s"), tuple(raw.get("poles_per_omega", ())))
        except ConfigError as exc:
            raise ConfigError(exc.message, path=str(model.source), hint=exc.hint) from None
        except TypeError:
            raise ConfigError("poles_per_omega must be a list of three numbers",
                              path=str(model.source), field="lip_feedback") from None


def lip_matrices(omega_1_s: float, zmp_time_constant_s: float) -> tuple[np.ndarray, np.ndarray]:
    """A (3x3) and B (3,) of eq. 7 for one axis."""
    w2, tp = omega_1_s ** 2, zmp_time_constant_s
    A = np.array([[0.0, 1.0, 0.0], [w2, 0.0, -w2], [0.0, 0.0, -1.0 / tp]])
    return A, np.array([0.0, 0.0, 1.0 / tp])


def lip_gains(omega_1_s: float, zmp_time_constant_s: float, poles_1_s) -> np.ndarray:
    """K = [k1, k2, k3] of eq. 8 placing the poles of A - B K at ``poles_1_s`` (real, or
    complex in conjugate pairs), in the closed form of the module docstring."""
    _, c2, c1, c0 = np.real(np.poly(np.asarray(poles_1_s)))
    w2, tp = omega_1_s ** 2, zmp_time_constant_s
    return np.array([-tp * (c2 + c0 / w2), -tp * (1.0 + c1 / w2), tp * c2 - 1.0])


def lip_ground_force(com_m, zmp_m, mass_kg: float, omega_1_s: float) -> np.ndarray:
    """The total ground reaction (F_x, F_y, F_z) (N) that holds the pendulum on its plane with
    its ZMP at ``zmp_m``: horizontal m w^2 (c - p), vertical m g."""
    d = np.asarray(com_m, dtype=float)[:2] - np.asarray(zmp_m, dtype=float)[:2]
    return np.array([*(mass_kg * omega_1_s ** 2 * d), mass_kg * GRAVITY_M_S2])


class LipFeedback:
    """Eq. 8 on both horizontal axes (the same gains on x and y).

    Args:
        com_height_m: z_c, the CoM's height above the soles (m).
        params: the lag and the poles.

    Attributes:
        omega_1_s: w = sqrt(g / z_c).
        gains: K = [k1, k2, k3].
    """

    def __init__(self, com_height_m: float, params: LipFeedbackParams) -> None:
        if not (math.isfinite(com_height_m) and com_height_m > 0):
            raise ConfigError(f"the LIP needs a positive CoM height, got {quoted(com_height_m)}",
                              hint="the walking pattern's com_height_m (m)")
        self.params = params
        self.omega_1_s = math.sqrt(GRAVITY_M_S2 / com_height_m)
        poles = np.asarray(params.poles_per_omega) * self.omega_1_s
        self.gains = lip_gains(self.omega_1_s, params.zmp_time_constant_s, poles)

    @classmethod
    def from_model(cls, model: RobotModel, com_height_m: float) -> LipFeedback:
        return cls(com_height_m, LipFeedbackParams.from_model(model))

    def zmp_command(self, com_ref_m, com_velocity_ref_m_s, zmp_ref_m, com_m, com_velocity_m_s,
                    zmp_m, zmp_velocity_ref_m_s=(0.0, 0.0)) -> np.ndarray:
        """u (x, y) (m) of eq. 8 from the reference and the estimated state, each (x, y).

        ``zmp_velocity_ref_m_s`` adds T_p p_ref' to the feedforward, the lag's inverse (hrpsys
        has it, switched off): with it a moving reference is consistent with eq. 7 and is
        tracked without offset; without it (eq. 8 as printed) a reference ZMP moving at v
        leaves the CoM a constant offset behind, -(A - B K)^-1 [0, 0, -v] (tests).

        A non-finite estimate leaves its term out (the reference ZMP alone, hrpsys's fallback
        when the feedback is off). A non-finite reference ZMP gives a non-finite u, which the
        force distribution refuses (``found`` False)."""
        k1, k2, k3 = self.gains
        lead = self.params.zmp_time_constant_s * np.asarray(zmp_velocity_ref_m_s, dtype=float)
        u = np.asarray(zmp_ref_m, dtype=float)[:2] + np.where(np.isfinite(lead), lead, 0.0)[:2]
        for k, ref, est in ((k1, com_ref_m, com_m), (k2, com_velocity_ref_m_s, com_velocity_m_s),
                            (k3, zmp_ref_m, zmp_m)):
            error = np.asarray(ref, dtype=float)[:2] - np.asarray(est, dtype=float)[:2]
            u += np.where(np.isfinite(error), k * error, 0.0)
        return u
