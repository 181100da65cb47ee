"""The standing experiment: the simulated robot holds its home posture, optionally with the
ankle balancer (paper III-C) and one push on the torso, and we watch tilt, feet and falls.

Until the pipeline loop drives modules, this runs its own small loop: command = home posture,
passed through the balancer (:func:`~hubo_cli.control.balance.make_balancer`) when balance is
on.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.control.balance import make_balancer
from hubo_cli.control.module import Cycle
from hubo_cli.errors import InputError
from hubo_cli.model import RobotModel
from hubo_cli.posture import home_posture

FLAT_TOLERANCE_DEG = 1.0  # a sole tilted more than this (or without contact) is not flat
FALL_TILT_DEG = 30.0      # torso tilt beyond which the robot has fallen
FALL_DROP_M = 0.2         # ... or torso lower than its start by this much


@dataclass
class StandingResult:
    """What a standing run showed (angles in degrees, times in seconds).

    Attributes:
        max_tilt_deg: largest torso tilt from upright (IMU) over the run.
        feet_flat: both soles flat on the floor (within FLAT_TOLERANCE_DEG, in contact) in
            every period.
        fell: the torso tilted past FALL_TILT_DEG or dropped FALL_DROP_M (the run then ends).
        realtime_factor: simulated seconds per wall-clock second of the loop.
        max_sole_tilt_deg: largest tilt of either sole.
        final_tilt_deg: torso tilt at the end.
        physics_share: fraction of the loop's wall time spent in PyBullet's stepSimulation.
        max_feet_moment_difference_nm: largest |M_right - M_left| of the ankle moments (x, y),
            how unevenly the two feet are loaded (the balancer's compliance evens them out).
        times_s, tilts_deg, feet_moment_difference_nm: traces, one sample per control period.
    """

    duration_s: float
    push_n: float
    balance: bool
    max_tilt_deg: float
    feet_flat: bool
    fell: bool
    realtime_factor: float
    max_sole_tilt_deg: float
    final_tilt_deg: float
    physics_share: float
    simulated_s: float
    max_feet_moment_difference_nm: float = 0.0
    snapshot: Path | None = None
    times_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    tilts_deg: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    feet_moment_difference_nm: np.ndarray = field(default_factory=lambda: np.zeros(0),
                                                  repr=False)

    def summary(self) -> dict:
        """The headline numbers as a plain dict (for JSON)."""
        return {"max_tilt_deg": self.max_tilt_deg, "feet_flat": self.feet_flat,
                "fell": self.fell, "realtime_factor": self.realtime_factor,
                "duration_s": self.duration_s, "simulated_s": self.simulated_s,
                "push_n": self.push_n, "balance": self.balance,
                "max_sole_tilt_deg": self.max_sole_tilt_deg,
                "final_tilt_deg": self.final_tilt_deg, "physics_share": self.physics_share,
                "max_feet_moment_difference_nm": self.max_feet_moment_difference_nm,
                "snapshot": str(self.snapshot) if self.snapshot else None}


def _tilt_deg(R: np.ndarray) -> float:
    """Angle between a frame's z axis and the world's z axis (deg)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, float(R[2, 2])))))


def check_standing_args(duration_s: float, push_n: float) -> None:
    """Raise InputError unless 0 < duration_s <= 3600 (s) and push_n >= 0 (N)."""
    if not (math.isfinite(duration_s) and 0 < duration_s <= 3600):
        raise InputError(f"duration must be in (0, 3600] s, got {duration_s}",
                         hint="e.g. --duration 5")
    if not (math.isfinite(push_n) and push_n >= 0):
        raise InputError(f"push must be a force >= 0 N, got {push_n}", hint="e.g. --push 30")


def stand(model: RobotModel, duration_s: float = 5.0, push_n: float = 0.0,
          balance: bool = True, *, push_at_s: float = 1.0, push_duration_s: float = 0.2,
          push_direction=(1.0, 0.0, 0.0), gui: bool = False, snapshot: str | Path | None = None,
          realtime: bool | None = None, sim_options: dict | None = None,
          balance_mode: str = "default") -> StandingResult:
    """Stand the simulated robot for ``duration_s`` and measure how it copes.

    Args:
        model: robot model.
        duration_s: simulated time (s).
        push_n: force (N) of one push on the torso's centre of mass, 0 for none.
        balance: run the ankle balancer on the command.
        push_at_s, push_duration_s: when the push starts and how long it lasts (s).
        push_direction: world direction of the push (normalised; default forward, +x).
        gui: open the PyBullet window.
        snapshot: if given, write a PNG of the final scene there.
        realtime: pace the loop to wall-clock time (default: only with the window).
        sim_options: extra options for the sim driver.
        balance_mode: ``default`` or ``paper`` (eq. 11-12 as published), when balance is on.
    """
    from hubo_cli.drivers.sim import SimDriver

    check_standing_args(duration_s, push_n)
    direction = np.asarray(push_direction, dtype=float)
    direction = direction / np.linalg.norm(direction)
    realtime = gui if realtime is None else realtime
    q_home = home_posture(model)
    balancer = make_balancer(model, balance_mode) if balance else None
    n_periods = int(round(duration_s / model.control_period_s))
    times, tilts, differences = np.zeros(n_periods), np.zeros(n_periods), np.zeros(n_periods)
    with SimDriver(model, gui=gui, **(sim_options or {})) as robot:
        state = robot.start(q_home)
        torso_z0 = state.T_world_torso[2, 3]
        if balancer is not None:
            balancer.reset(q_home, state)
        feet_flat, fell, max_sole, max_moment_difference = True, False, 0.0, 0.0
        robot.physics_wall_s = 0.0
        t_wall0 = time.perf_counter()
        k = 0
        for k in range(n_periods):
            t = k * model.control_period_s
            if push_n > 0 and abs(t - push_at_s) < model.control_period_s / 2:
                robot.push_torso(push_n * direction, push_duration_s)
            q_cmd = q_home
            if balancer is not None:
                q_cmd = balancer.update(q_home, state, Cycle(t, model.control_period_s))
            robot.send(q_cmd)
            state = robot.step()
            times[k] = state.time_s
            tilts[k] = _tilt_deg(state.T_world_torso[:3, :3])
            difference = state.ft["right-ankle"][3:5] - state.ft["left-ankle"][3:5]
            differences[k] = float(np.linalg.norm(difference))
            max_moment_difference = max(max_moment_difference, differences[k])
            for sole, touching in zip(("right_sole", "left_sole"), state.feet_contact,
                                      strict=True):
                sole_tilt = _tilt_deg(robot.frame_pose(sole)[:3, :3])
                max_sole = max(max_sole, sole_tilt)
                feet_flat &= bool(touching) and sole_tilt <= FLAT_TOLERANCE_DEG
            if tilts[k] > FALL_TILT_DEG or state.T_world_torso[2, 3] < torso_z0 - FALL_DROP_M:
                fell = True
                break
            if realtime:
                lag = t_wall0 + state.time_s - time.perf_counter()
                if lag > 0:
                    time.sleep(lag)
        wall = time.perf_counter() - t_wall0
        done = k + 1
        image = robot.snapshot_png(snapshot) if snapshot is not None else None
        physics_share = robot.physics_wall_s / wall if wall > 0 else 0.0
    simulated = done * model.control_period_s
    return StandingResult(
        duration_s=duration_s, push_n=push_n, balance=balance,
        max_tilt_deg=float(tilts[:done].max()), feet_flat=bool(feet_flat and not fell), fell=fell,
        realtime_factor=simulated / wall if wall > 0 else float("inf"),
        max_sole_tilt_deg=max_sole, final_tilt_deg=float(tilts[done - 1]),
        physics_share=physics_share, simulated_s=simulated,
        max_feet_moment_difference_nm=max_moment_difference, snapshot=image,
        times_s=times[:done], tilts_deg=tilts[:done],
        feet_moment_difference_nm=differences[:done])
