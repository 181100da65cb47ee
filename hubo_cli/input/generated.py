"""A generated operator stream (:mod:`.operator_stream`) as an input device, and as a pose log.

The device delivers both hands' poses on the record rate's grid, released by the caller's clock
like a recording. Written as a FASTRAK pose-log CSV (station 1 the right hand, 2 the left, in
the tracker's axes), a stream can be shared and replayed with ``hubo teleop --replay``; a pose
log has no clutch, so the poses taken while the clutch is held are left out: a replay holds the
hand over the gap and re-centres on the first pose after it, which is what the clutch does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hubo_cli.input.device import HandPose, RecordedInput
from hubo_cli.input.operator_stream import StreamSettings, operator_stream

STATION_OF_HAND = {"right": 1, "left": 2}  # as the FASTRAK default map (1 right, 2 left)


def generated_input(seed: int, settings: StreamSettings | None = None,
                    hands=("right", "left")) -> RecordedInput:
    """The stream of ``seed`` as an input device."""
    settings = settings or StreamSettings()
    poses = [HandPose(s.hand, s.T_operator_hand[i], float(s.t_s[i]),
                      engaged=bool(s.engaged[i]))
             for s in operator_stream(seed, settings, hands) for i in range(len(s.t_s))]
    return RecordedInput(poses, {"kind": "generated", "seed": int(seed),
                                 "max_speed_m_s": settings.max_speed_m_s,
                                 "duration_s": settings.duration_s})


def write_stream_pose_log(path: str | Path, seed: int,
                          settings: StreamSettings | None = None) -> Path:
    """Write the stream of ``seed`` as a FASTRAK pose-log CSV (see the module docstring).

    Raises:
        InputError: the file cannot be written.
    """
    from hubo_cli.fastrak.capture import write_pose_log
    from hubo_cli.fastrak.records import RecordBatch
    from hubo_cli.geometry import matrix_to_quat_wxyz
    from hubo_cli.input.fastrak import tracker_pose

    streams = operator_stream(seed, settings)
    t, station, position, quat = [], [], [], []
    for s in streams:
        keep = s.engaged
        T_K = np.array([tracker_pose(T) for T in s.T_operator_hand[keep]])
        t.append(s.t_s[keep])
        station.append(np.full(int(keep.sum()), STATION_OF_HAND[s.hand]))
        position.append(T_K[:, :3, 3])
        quat.append(matrix_to_quat_wxyz(T_K[:, :3, :3]))
    t_all = np.concatenate(t)
    order = np.argsort(t_all, kind="stable")
    n = len(t_all)
    batch = RecordBatch(t_s=t_all[order], station=np.concatenate(station)[order],
                        position_m=np.concatenate(position)[order],
                        quat_wxyz=np.concatenate(quat)[order],
                        status=np.full(n, 0x20, dtype=np.uint8),
                        stylus=np.full(n, -1, dtype=np.int8), offset=np.zeros(n, np.int64))
    return write_pose_log(path, batch)
