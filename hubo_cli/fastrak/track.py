"""One station's timed poses, sampled at any time by interpolation.

The sample writers and the emulator's ``--from FILE`` motion use this to resample operator poses
onto the device's 120 Hz record schedule: positions are interpolated linearly, orientations by
spherical linear interpolation; times before the first or after the last pose hold the end pose.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.geometry import slerp_quat_wxyz, unit_quats


class PoseTrack:
    """Timed poses of one station.

    Args:
        t_s: (N,) increasing times, seconds.
        position_m: (N,3) positions, metres.
        quat_wxyz: (N,4) scalar-first quaternions.
    """

    def __init__(self, t_s, position_m, quat_wxyz) -> None:
        self.t_s = np.asarray(t_s, dtype=np.float64).reshape(-1)
        self.position_m = np.asarray(position_m, dtype=np.float64).reshape(-1, 3)
        q = np.asarray(quat_wxyz, dtype=np.float64).reshape(-1, 4)
        n = self.t_s.shape[0]
        if n == 0 or self.position_m.shape[0] != n or q.shape[0] != n:
            raise InputError("a pose track needs the same number (at least one) of times, "
                             "positions and orientations")
        if not (np.isfinite(self.t_s).all() and np.isfinite(self.position_m).all()
                and np.isfinite(q).all()):
            raise InputError("a pose track holds a NaN or infinite value")
        unit, norms = unit_quats(q)
        if (norms < 1e-9).any():
            raise InputError("a pose track holds a zero quaternion")
        if (np.diff(self.t_s) < 0).any():
            raise InputError("pose times must not decrease",
                             hint="sort the poses of each station by time")
        self.quat_wxyz = unit

    @property
    def start_s(self) -> float:
        """Time of the first pose, seconds."""
        return float(self.t_s[0])

    @property
    def end_s(self) -> float:
        """Time of the last pose, seconds."""
        return float(self.t_s[-1])

    def at(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Poses at times ``t_s`` (scalar or (M,)): (M,3) positions (m) and (M,4) quaternions."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        n = self.t_s.shape[0]
        if n == 1:
            return (np.repeat(self.position_m, t.shape[0], axis=0),
                    np.repeat(self.quat_wxyz, t.shape[0], axis=0))
        i = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, n - 2)
        t0, t1 = self.t_s[i], self.t_s[i + 1]
        span = np.where(t1 > t0, t1 - t0, 1.0)
        u = np.clip((t - t0) / span, 0.0, 1.0)
        u = np.where(t1 > t0, u, 1.0)
        p = self.position_m[i] + u[:, None] * (self.position_m[i + 1] - self.position_m[i])
        q = slerp_quat_wxyz(self.quat_wxyz[i], self.quat_wxyz[i + 1], u)
        return p, q
