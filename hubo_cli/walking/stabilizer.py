"""The walking stabilizer: keeps the soles flat and the centre of mass on the pattern while the
robot walks (hrpsys-base's Stabilizer, reduced to what a position-controlled Hubo needs).

Two feedbacks act on the pattern's joints every period:

* **Foot damping control** (hrpsys EEFM, Kajita 2010), per loaded sole: the ankle's pitch and
  roll comply with the measured ground moment so that the centre of pressure stays inside a
  safe region of the sole (the sole shrunk by ``edge_margin_m``). With the reference moment
  ``m_ref`` the measured one's centre of pressure clipped to that region, the sole rotates at

      d(delta)/dt = (m - m_ref) / D - delta / T

  about its x (roll) and y (pitch) axes: a sole pressed onto its toe turns its toe up, one on
  its inner edge turns that edge up, so the foot lands back flat instead of rocking; the
  ``- delta / T`` leak returns it to the pattern. An unloaded sole (swinging) returns to the
  pattern with ``swing_time_constant_s`` and lands flat. A swing foot that touches down early
  is loaded, so the same law absorbs its landing.
* **CoM feedback** (TPCC, Sugihara 2009 / Choi 2007 as hrpsys runs it): the torso moves
  horizontally by ``offset`` with

      d(offset)/dt = k_zmp (p - p_ref) - k_com (c - c_ref)

  (p the ZMP from the ankles' force/torque, c the whole-body CoM from the measured joints and
  torso pose), bounded to ``max_offset_m`` and ``max_offset_speed_m_s``: the measured CoM is
  pulled onto the pattern's.
* **Touchdown** (landing-impact handling): a swing sole that meets the floor before the pattern
  lands it (loaded while still planned in the air, the last ``touchdown_height_m`` of its
  descent) stops descending where it touched; the difference to the pattern then fades with
  ``touchdown_time_constant_s`` once the pattern has it on the ground. Driving a position-
  controlled foot on into a stiff floor is what throws the robot up and makes it hop.

The torso offset is realised by solving the legs' IK again for the shifted torso; the sole
rotations are added to the ankle joints (ankle pitch turns the sole about its y axis, ankle
roll about its x axis, one for one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.control.lip_feedback import LipFeedback, lip_ground_force
from hubo_cli.control.wrench_distribution import UNLOADED_N, Contact, WrenchDistributor
from hubo_cli.errors import ConfigError
from hubo_cli.model import EstimationConfig


@dataclass(frozen=True)
class StabilizerGains:
    """The stabilizer's gains (SI units).

    Attributes:
        damping_roll_nm_s_rad, damping_pitch_nm_s_rad: D of the foot damping control about the
            sole's x and y axes (N m s/rad). 60 / 120: walking 0.3 m sideways the ZMP stayed
            inside the soles in contact in every period, against 98.9 % with the former
            300 / 600 (one run each; 1 m forward and the turning walk: 100 % with both).
        reference_damping_roll_nm_s_rad, reference_damping_pitch_nm_s_rad: D while the sole
            tracks a reference CoP (the LIP feedback's force distribution, :class:`LipStabilizer`;
            the damper then acts everywhere on the sole, not only near its edges). 300 / 600:
            with 60 / 120 the two soles of a double support rocked the weight between them
            (one sole 430 N, the other -10 N, and back, every 0.15 s) on perturbed robots
            (sensor noise, command delay), and 22 of 40 random perturbed walks stopped at a
            lift-off wait, one fell; with 300 / 600 2 of 60 stopped (standing), none fell
            (docs/history/stabilizer.md, round 27).
        time_constant_s: T, the leak back to the pattern of a loaded sole (s).
        swing_time_constant_s: the same for an unloaded sole (s).
        max_sole_rad: bound on each sole rotation (rad).
        edge_margin_m: the centre of pressure may come this close to the sole's edges before
            the sole complies (m).
        k_zmp: TPCC gain on the ZMP error (1/s).
        k_com: TPCC gain on the CoM error (1/s).
        max_offset_m: bound on the torso's horizontal offset (m).
        max_offset_speed_m_s: bound on its speed (m/s).
        touchdown_n: a swing sole pressing harder than this has touched down (N).
        touchdown_height_m: touchdowns count only this close to the landing height (m).
        touchdown_time_constant_s: the held height fades to the pattern's with this (s).
    """

    damping_roll_nm_s_rad: float = 60.0
    damping_pitch_nm_s_rad: float = 120.0
    reference_damping_roll_nm_s_rad: float = 300.0
    reference_damping_pitch_nm_s_rad: float = 600.0
    time_constant_s: float = 1.5
    swing_time_constant_s: float = 0.1
    max_sole_rad: float = 0.1
    edge_margin_m: float = 0.025
    k_zmp: float = 0.2
    k_com: float = 4.0
    max_offset_m: float = 0.03
    max_offset_speed_m_s: float = 0.1
    touchdown_n: float = 40.0
    touchdown_height_m: float = 0.006
    touchdown_time_constant_s: float = 0.1

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"stabilizer gain {name} must be a finite number >= 0, got "
                                  f"{value!r}", hint="see hubo_cli/walking/stabilizer.py")


class SoleDamper:
    """Foot damping control of one sole (see the module docstring).

    Args:
        gains: the stabilizer's gains.
        sole_box_m: (x_min, x_max, y_min, y_max) of the sole in its own frame (m).
        dt_s: the control period (s).
        min_fz_n: the sole complies while it carries more than this (N; the robot file's
            ``estimation.sole_damping_min_fz_n``); lighter, it returns to the pattern.

    Attributes:
        delta_rad: the sole's rotation (about x, about y) added to the pattern (rad).
    """

    def __init__(self, gains: StabilizerGains, sole_box_m: tuple[float, float, float, float],
                 dt_s: float,
                 min_fz_n: float = EstimationConfig.sole_damping_min_fz_n) -> None:
        self.gains = gains
        self.min_fz_n = float(min_fz_n)
        x0, x1, y0, y1 = sole_box_m
        m = gains.edge_margin_m
        if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
            raise ConfigError("the stabilizer's edge margin leaves no safe region on the sole",
                              hint="lower edge_margin_m")
        self.safe = (x0 + m, x1 - m, y0 + m, y1 - m)
        self.dt_s = float(dt_s)
        # (roll, pitch) D: without a reference CoP, with one
        self._damping = ((float(gains.damping_roll_nm_s_rad),
                          float(gains.damping_pitch_nm_s_rad)),
                         (float(gains.reference_damping_roll_nm_s_rad),
                          float(gains.reference_damping_pitch_nm_s_rad)))
        self.delta_rad = np.zeros(2)

    def reset(self) -> None:
        self.delta_rad[:] = 0.0

    def update(self, wrench: np.ndarray,
               cop_ref_m: tuple[float, float] | None = None) -> np.ndarray:
        """One period with the sole's measured wrench [fx, fy, fz, mx, my, mz] (about the sole
        frame's origin, sole axes); returns ``delta_rad``. ``cop_ref_m`` (x, y in the sole
        frame; the force distribution's, :class:`LipStabilizer`) is the CoP the reference
        moment puts the measured normal force at; None: the measured CoP clipped to the safe
        region."""
        g = self.gains
        fx, fy, fz, mx, my, mz = np.asarray(wrench, dtype=float).tolist()  # plain floats
        roll, pitch = float(self.delta_rad[0]), float(self.delta_rad[1])
        if fz > self.min_fz_n and math.isfinite(mx + my + fx + fy + mz):
            if cop_ref_m is None:
                x0, x1, y0, y1 = self.safe
                px = min(max(-my / fz, x0), x1)
                py = min(max(mx / fz, y0), y1)
            else:
                px, py = cop_ref_m
            d_roll, d_pitch = self._damping[cop_ref_m is not None]
            rate_roll = (mx - fz * py) / max(d_roll, 1e-9) - roll / g.time_constant_s
            rate_pitch = (my + fz * px) / max(d_pitch, 1e-9) - pitch / g.time_constant_s
        else:
            leak = max(g.swing_time_constant_s, self.dt_s)
            rate_roll, rate_pitch = -roll / leak, -pitch / leak
        bound = g.max_sole_rad
        self.delta_rad[0] = min(max(roll + rate_roll * self.dt_s, -bound), bound)
        self.delta_rad[1] = min(max(pitch + rate_pitch * self.dt_s, -bound), bound)
        return self.delta_rad


class TorsoOffset:
    """The CoM feedback's horizontal torso offset (see the module docstring).

    Attributes:
        offset_m: (x, y) in the world (m).
    """

    def __init__(self, gains: StabilizerGains, dt_s: float) -> None:
        self.gains = gains
        self.dt_s = float(dt_s)
        self.offset_m = np.zeros(2)

    def reset(self) -> None:
        self.offset_m[:] = 0.0

    def update(self, zmp_m: np.ndarray | None, zmp_ref_m: np.ndarray, com_m: np.ndarray,
               com_ref_m: np.ndarray) -> np.ndarray:
        """One period; ``zmp_m`` None (no sole loaded) leaves the ZMP term out."""
        g = self.gains
        rate_x = -g.k_com * (float(com_m[0]) - float(com_ref_m[0]))
        rate_y = -g.k_com * (float(com_m[1]) - float(com_ref_m[1]))
        if zmp_m is not None:
            rate_x += g.k_zmp * (float(zmp_m[0]) - float(zmp_ref_m[0]))
            rate_y += g.k_zmp * (float(zmp_m[1]) - float(zmp_ref_m[1]))
        speed = math.hypot(rate_x, rate_y)
        if not math.isfinite(speed):
            return self.offset_m
        if speed > g.max_offset_speed_m_s:
            rate_x, rate_y = (v * (g.max_offset_speed_m_s / speed) for v in (rate_x, rate_y))
        x = float(self.offset_m[0]) + rate_x * self.dt_s
        y = float(self.offset_m[1]) + rate_y * self.dt_s
        size = math.hypot(x, y)
        if size > g.max_offset_m:
            x, y = x * (g.max_offset_m / size), y * (g.max_offset_m / size)
        self.offset_m = np.array((x, y))
        return self.offset_m


class Touchdown:
    """Landing-impact handling for one sole (see the module docstring).

    Attributes:
        lift_m: the sole is held this much above the pattern (m, >= 0).
    """

    def __init__(self, gains: StabilizerGains, dt_s: float) -> None:
        self.gains = gains
        self.decay = math.exp(-float(dt_s) / max(gains.touchdown_time_constant_s, dt_s))
        self.lift_m = 0.0
        self._held_z_m: float | None = None

    def reset(self) -> None:
        self.lift_m = 0.0
        self._held_z_m = None

    def update(self, swinging: bool, height_m: float, fz_n: float) -> float:
        """One period: whether the pattern has the sole in the air, its planned height above
        the landing place (m) and its measured normal force (N); returns ``lift_m``."""
        g = self.gains
        if swinging and height_m < g.touchdown_height_m and fz_n > g.touchdown_n:
            if self._held_z_m is None:  # touched: stay at the height of the last command
                self._held_z_m = height_m + self.lift_m
            self.lift_m = max(self._held_z_m - height_m, 0.0)
        else:
            if not swinging:
                self._held_z_m = None
            self.lift_m *= self.decay
        return self.lift_m


class LipStabilizer:
    """The multi-layer paper's Stabilizer for walking (III-D, eq. 7-14): each period the LIP
    state feedback (:class:`~hubo_cli.control.lip_feedback.LipFeedback`, eq. 8) turns the
    pattern's CoM, CoM velocity and ZMP and the estimated ones into a ZMP command; the
    pendulum's ground force at that command is split between the soles the pattern has on the
    ground by the QP of eq. 9-14 (:class:`~hubo_cli.control.wrench_distribution.
    WrenchDistributor`; a sole rolling on its toe or heel touches along that edge); each
    sole's CoP in the split becomes its :class:`SoleDamper`'s reference (the foot damping
    control of III-D.3). The TPCC torso offset (:class:`TorsoOffset`) still moves the CoM:
    on a position-controlled robot the dampers alone, compliant enough to absorb a landing,
    realise the command too slowly (the LIP feedback without it fell on the first 0.8 s
    steps of a 2 m walk).

    Args:
        feedback: eq. 8 at the pattern's CoM height.
        distributor: eq. 9-14 for the robot's soles.
        mass_kg: the robot's mass (the pendulum's).

    Attributes:
        zmp_command_m: the last ZMP command u (x, y; m), after the distribution made it
            feasible; NaN before the first or when no distribution was found.
    """

    def __init__(self, feedback: LipFeedback, distributor: WrenchDistributor,
                 mass_kg: float) -> None:
        self.feedback = feedback
        self.distributor = distributor
        self.mass_kg = float(mass_kg)
        self.zmp_command_m = np.full(2, math.nan)

    def cop_references(self, com_ref_m, com_velocity_ref_m_s, zmp_ref_m, com_m,
                       com_velocity_m_s, zmp_m, contacts: tuple[Contact | None, Contact | None]
                       ) -> list[tuple[float, float] | None]:
        """Each sole's reference CoP in its own frame (x, y; m), right then left; None for a
        sole in the air or when no distribution was found (its damper then keeps the measured
        CoP inside its safe region). Positions are (x, y) in one frame (the pattern's)."""
        u = self.feedback.zmp_command(com_ref_m, com_velocity_ref_m_s, zmp_ref_m, com_m,
                                      com_velocity_m_s, zmp_m)
        force = lip_ground_force(com_m if np.all(np.isfinite(com_m[:2])) else com_ref_m, u,
                                 self.mass_kg, self.feedback.omega_1_s)
        split = self.distributor.distribute(force, u, *contacts)
        if not split.found:
            self.zmp_command_m[:] = math.nan
            return [None, None]
        self.zmp_command_m[:] = split.zmp_m
        references: list[tuple[float, float] | None] = []
        for foot, contact in enumerate(contacts):
            if contact is None or split.force_n[foot, 2] <= UNLOADED_N:
                references.append(None)
                continue
            c, s = math.cos(contact.yaw_rad), math.sin(contact.yaw_rad)
            dx = float(split.cop_m[foot, 0]) - contact.position_m[0]
            dy = float(split.cop_m[foot, 1]) - contact.position_m[1]
            references.append((c * dx + s * dy, -s * dx + c * dy))
        return references
