"""Regenerate the operator recordings shipped in trajectories/ (deterministic).

    .venv/bin/python tools/make_trajectories.py

Each session is written as a raw FASTRAK capture (the bytes a FASTRAK sends, with receive
times, 120 Hz shared by two stations) and as the pose log decoded from that capture.
"""

from pathlib import Path

from hubo_cli.fastrak.capture import load_recording, write_capture, write_pose_log
from hubo_cli.teleop.samples import free_session, rectangle_session

OUT = Path(__file__).resolve().parents[1] / "trajectories"

SESSIONS = {
    "drill-rectangle": (rectangle_session, {"fmt": "ascii", "output_list": (2, 11, 1)}),
    "two-hand-free": (free_session, {"fmt": "binary", "output_list": (2, 11, 1)}),
}


def main() -> None:
    for name, (make, fmt) in SESSIONS.items():
        capture = write_capture(OUT / f"{name}.fastrak", make(), units="cm",
                                extra={"session": name, "generator": "tools/make_trajectories.py"},
                                **fmt)
        recording = load_recording(capture)
        write_pose_log(OUT / f"{name}.csv", recording.batch)
        print(f"{capture.name}: {len(recording.batch)} records, "
              f"{capture.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
