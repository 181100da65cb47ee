"""Is the robot following its commands, and are its measurements a robot's? The checks that end
a run as device trouble (a :class:`~hubo_cli.errors.DeviceError`, exit 3; the control loop
brakes the command to rest from the last one), in one place:

- held at the band: a joint held at the soft error limiter's tracking band
  (:mod:`hubo_cli.control.limiter`) without a break for longer than :data:`NOT_FOLLOWING_S`,
  its measured position moving less than :data:`NOT_FOLLOWING_PROGRESS_RAD` meanwhile (a frozen
  or unpowered joint, a daemon not applying references): :class:`NotFollowing`;
- still: a joint whose command has gone :data:`STILL_COMMAND_RAD` away from where it was when
  the measured joint last moved, while the measured joint has not moved
  :data:`STILL_MOVED_RAD` since, for :data:`STILL_S` at least (a joint that stopped while its
  plan moves less than the band: the band cannot catch it): :class:`NotFollowing`;
- jumps: a measured joint that moves faster than :data:`MEASURED_SPEED_FACTOR` times its
  velocity limit between two states (an encoder's noise or glitch: no joint can; the state
  estimate built on it runs away): :class:`ImplausibleMeasurement`;
- the estimate: a torso estimated more than :data:`TORSO_HEIGHT_MARGIN_M` beyond the heights a
  robot on the floor can hold (under the floor, or above its straight legs' reach):
  :class:`ImplausibleMeasurement`, raised before any module acts on it. (The checks on the
  sensors' readings are :mod:`hubo_cli.estimation.plausibility`'s: measured drivers only, and a
  walk steps into its stance; its docstring says why the two are not one.)

The bounds are healthy runs' figures with a margin (docs/history/safety.md, rounds 16 and 17).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.errors import DeviceError
from hubo_cli.state import RobotState

# A joint held at the tracking band this long without a break does not follow. Healthy runs
# held it 0.005 s at most (round 16: 321 sim walks on both code paths, sim and hardware dry-run
# cuts, teleop replays; docs/history/safety.md), 1.58 s in hubo-daemon's filtered mode while
# moving 0.9 rad a second; a frozen robot on a cut holds it from 0.56 s on, for as long as the
# plan moves
NOT_FOLLOWING_S = 1.0
# ... while its measured position moved less than this (rad): a joint that follows slowly (the
# daemon's reference filter, mode 0: its 0.2 s lag holds a long fast move at the band for
# seconds) gains 0.18 rad every 0.2 s or so there; a frozen one gains nothing (half the band)
NOT_FOLLOWING_PROGRESS_RAD = 0.09
# A measured joint that moved less than this has not moved (rad): 2 perturbed encoders' noise
# standard deviations (0.5 mrad), 100 of Hubo's encoder counts at the joint
STILL_MOVED_RAD = 0.001
# ... for at least this long (s): a joint that lags its command is still for a moment (a sim
# walk's knee 10 ms while its command went 9.4 mrad; hubo-daemon's reference filter 0.11 s
# while it went 17.5 mrad), a frozen one for good
STILL_S = 0.5
# ... while its command went this far (rad) from where it was when the joint last moved: it
# does not follow. Healthy runs went 5.1 mrad at most so (round 17: a hardware dry-run cut in
# filtered mode; 322 sim walks, cuts and teleop runs 2.4 mrad); the frozen elbow of the
# review's cut reaches it 0.9 s after it stopped
STILL_COMMAND_RAD = 0.015
# A measured joint faster than this times its velocity limit between two states is not a
# joint moving (round 17: healthy runs measured 1.46 times the limit at most, an arm in a
# perturbed sim cut; pushed walks 1.26 times the walking set's 2.6 rad/s)
MEASURED_SPEED_FACTOR = 4.0
# The estimated torso's height (the neck frame over the floor the run started on) may leave
# [0, the straight legs' reach: 1.07 m] by this much (m); healthy runs held 0.926-1.039 m
# (round 17), the review's noisy encoders carried it to 9.16 m
TORSO_HEIGHT_MARGIN_M = 0.3
# A driver that says it holds the robot by itself (servo-off, the stale-state brake and hold, its
# final hold, a fault, hubo-daemon's refWait) does not follow the pipeline's commands: its own
# check ends the run, and a joint standing still then is no news
DRIVER_HOLDS = frozenset({"servo-off", "stale-state", "stale-hold", "stopped", "fault",
                          "ref-wait"})
HINT = ("check the joint (powered, not blocked) and its encoder, and hubo-daemon "
        "(hubo-console), then start the run again")


JUMPED, STILL = 1, 2  # what _measured_kernel found


@nb.njit(cache=True, nogil=True)
def _measured_kernel(q, last_q, dt, speed_max, cmd, still_q, still_cmd, still_t, t_s,
                     judge_still, out) -> int:
    """One state's jump and still checks (numba: 2.5 us of CPU a period; in numpy 37 us).

    Updates ``last_q`` (where ``dt`` != 0: a fresh state; NaN joints keep theirs) and the
    still anchors ``still_q``, ``still_cmd``, ``still_t`` (where ``judge_still``). Writes
    ``out``: the joint found and its figure (rad/s for a jump, rad away for a still joint).
    Returns 0, JUMPED or STILL.
    """
    found, k_found, figure = 0, 0, 0.0
    for k in range(q.shape[0]):
        qk = q[k]
        if not np.isfinite(qk):  # the driver and the limiter hold it; judge the others
            continue
        if dt > 0.0 and np.isfinite(last_q[k]):  # a fresh state (a daemon may repeat one)
            speed = abs(qk - last_q[k]) / dt
            if speed > speed_max[k] and found == 0:
                found, k_found, figure = JUMPED, k, speed
        if dt != 0.0:
            last_q[k] = qk
        if judge_still:
            if not abs(qk - still_q[k]) < STILL_MOVED_RAD:  # moved (NaN: the first state)
                still_q[k], still_cmd[k], still_t[k] = qk, cmd[k], t_s
            elif t_s - still_t[k] >= STILL_S:
                away = abs(cmd[k] - still_cmd[k])
                if away > STILL_COMMAND_RAD and found == 0:
                    found, k_found, figure = STILL, k, away
    out[0], out[1] = k_found, figure
    return found


class NotFollowing(DeviceError):
    """A joint does not follow its commands (held at the band too long, or not moving)."""

    def __init__(self, joint: str, what: str, t_s: float) -> None:
        super().__init__(f"the robot does not follow: {joint} {what} at t = {t_s:.2f} s; "
                         "braked to a stop", hint=HINT)
        self.joint = joint


class ImplausibleMeasurement(DeviceError):
    """A measured joint, or the estimate built on the measurements, does what no robot can."""

    def __init__(self, what: str, t_s: float) -> None:
        super().__init__(f"implausible measurement: {what} at t = {t_s:.2f} s; braked to a stop",
                         hint=HINT)


class FollowingChecks:
    """The per-joint checks of one run (see the module's docstring); the limiter runs them.

    Args:
        joint_names: the joints, in command order.
        dt_s: the control period (s).
        velocity_rad_s: each joint's velocity limit (rad/s).
        band_rad: the limiter's tracking band (rad), for the message.

    """

    def __init__(self, joint_names, dt_s: float, velocity_rad_s: np.ndarray,
                 band_rad: float) -> None:
        self.joint_names = tuple(joint_names)
        self.dt_s = float(dt_s)
        self.speed_max_rad_s = MEASURED_SPEED_FACTOR * np.asarray(velocity_rad_s, dtype=float)
        self.band_rad = float(band_rad)
        n = len(self.joint_names)
        self._held = np.zeros(n, dtype=np.int64)  # periods each joint is held at the band
        self._held_from = np.zeros(n)  # ... measured where (rad) the count began
        self._still_q = np.full(n, np.nan)  # measured where each joint last moved (rad)
        self._still_cmd = np.full(n, np.nan)  # ... its command then (rad)
        self._still_t = np.zeros(n)  # ... when (s)
        self._last_q = np.full(n, np.nan)  # the last fresh state's joints (rad)
        self._last_t = np.nan
        self._out = np.zeros(2)  # the kernel's joint and figure

    def reset(self) -> None:
        """Start afresh (a new run)."""
        self._held[:] = 0
        self._still_q[:] = np.nan
        self._last_q[:] = np.nan
        self._last_t = np.nan

    def measured(self, state: RobotState, cmd_rad: np.ndarray, t_s: float) -> None:
        """Check a state against the last one (jumps) and the command it followed (still).

        Args:
            state: the state the driver returned after ``cmd_rad`` was sent.
            cmd_rad: the command sent before it (rad).
            t_s: loop time (s), for the message.

        Raises:
            ImplausibleMeasurement: a joint jumped. NotFollowing: a joint stood still.
        """
        q = np.asarray(state.q_rad, dtype=float)
        dt = state.time_s - self._last_t
        judge_still = DRIVER_HOLDS.isdisjoint(state.flags)
        if not judge_still:  # judged afresh once the driver follows again
            self._still_q[:] = np.nan
        out = self._out
        kind = _measured_kernel(q, self._last_q, dt, self.speed_max_rad_s,
                                np.asarray(cmd_rad, dtype=float), self._still_q, self._still_cmd,
                                self._still_t, t_s, judge_still, out)
        if dt != 0.0:  # (NaN: the first state; < 0: a driver started again)
            self._last_t = float(state.time_s)
        k = int(out[0])
        if kind == JUMPED:
            raise ImplausibleMeasurement(
                f"{self.joint_names[k]} jumped {out[1] * dt:.3f} rad in {dt * 1e3:.0f} ms "
                f"({out[1]:.1f} rad/s; a joint does at most {self.speed_max_rad_s[k]:.1f})", t_s)
        if kind == STILL:
            raise NotFollowing(self.joint_names[k],
                               f"has not moved (within {STILL_MOVED_RAD * 1e3:.0f} mrad) "
                               f"since t = {self._still_t[k]:.2f} s while commanded "
                               f"{out[1]:.3f} rad away", t_s)

    def held(self, at_band: np.ndarray, q_meas: np.ndarray, t_s: float) -> None:
        """Count each joint's periods held at the band (``at_band``), from where it was
        measured when the count began (again once it has moved NOT_FOLLOWING_PROGRESS_RAD from
        there); raise NotFollowing past NOT_FOLLOWING_S."""
        held = self._held
        begin = (held == 0) | (np.abs(q_meas - self._held_from) > NOT_FOLLOWING_PROGRESS_RAD)
        self._held_from = np.where(at_band & begin, q_meas, self._held_from)
        held[:] = np.where(at_band, np.where(begin, 1, held + 1), 0)
        k = int(np.argmax(held))
        if held[k] * self.dt_s > NOT_FOLLOWING_S + 1e-9:
            raise NotFollowing(self.joint_names[k],
                               f"held {self.band_rad} rad from its measured position for "
                               f"{held[k] * self.dt_s:.2f} s", t_s)

    def clear_held(self) -> None:
        """No joint at the band this period."""
        self._held[:] = 0


def torso_height_bounds_m(model) -> tuple[float, float]:
    """The estimated torso's allowed heights over the floor (m): from TORSO_HEIGHT_MARGIN_M
    under it to that much above the straight legs' reach (the neck frame over the sole)."""
    from hubo_cli.kinematics.limb import Limb

    leg = Limb(model, "right-leg")
    reach_m = float(np.linalg.norm(leg.fk(np.zeros(6))[:3, 3]))
    return -TORSO_HEIGHT_MARGIN_M, reach_m + TORSO_HEIGHT_MARGIN_M


def check_torso_height(T_world_torso, bounds_m: tuple[float, float], t_s: float) -> None:
    """Raise ImplausibleMeasurement when the estimated torso's height leaves ``bounds_m``."""
    if T_world_torso is None:
        return
    z = float(np.asarray(T_world_torso)[2, 3])
    if not bounds_m[0] <= z <= bounds_m[1]:
        raise ImplausibleMeasurement(
            f"the torso is estimated {z:.2f} m over the floor (a robot on it can hold "
            f"{max(bounds_m[0], 0.0):.2f}-{bounds_m[1] - TORSO_HEIGHT_MARGIN_M:.2f} m); the "
            "joints or the IMU read wrong", t_s)
