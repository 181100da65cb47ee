"""``hubo input generate``: an operator-like stream, written as a pose log to replay and share."""

from __future__ import annotations

from pathlib import Path

import click

from hubo_cli.cli.options import force_option
from hubo_cli.cli.output import console, print_json


@click.group("input")
def input_group() -> None:
    """Operator input devices: generated operator streams."""


@input_group.command("generate")
@click.argument("seed", type=click.IntRange(0, 2**32 - 1))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Pose-log CSV to write (an existing file is not overwritten without "
                   "--force).")
@click.option("--max-speed", "max_speed", type=float, default=0.25, show_default=True,
              metavar="M/S", help="The hands' speed cap (0.6 for a swing test).")
@click.option("--duration", type=float, default=30.0, show_default=True, metavar="SECONDS",
              help="Length of the stream.")
@force_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
def generate(seed: int, out: Path, max_speed: float, duration: float, force: bool,
             as_json: bool) -> None:
    """Write the generated operator stream of SEED as a FASTRAK pose log (station 1 the right
    hand, 2 the left): `hubo teleop --replay FILE` replays it as `hubo teleop --generate SEED`
    does (the clutched stretches are left out; the replay re-centres after them).
    """
    import numpy as np

    from hubo_cli.input.generated import write_stream_pose_log
    from hubo_cli.input.operator_stream import StreamSettings, operator_stream
    from hubo_cli.outputs import OutputFile

    settings = StreamSettings(duration_s=duration, max_speed_m_s=max_speed)
    pose_log = OutputFile(out, force=force)
    with pose_log.writing() as temporary:
        write_stream_pose_log(temporary, seed, settings)
    hands = {s.hand: {"peak_speed_m_s": float(s.speed_m_s().max()),
                      "clutched_s": float((~s.engaged).sum() / 120.0),
                      "farthest_mm": float(np.linalg.norm(
                          s.position_m - s.position_m[0], axis=1).max() * 1000)}
             for s in operator_stream(seed, settings)}
    report = {"seed": seed, "pose_log": str(out), "duration_s": duration,
              "max_speed_m_s": max_speed, "hands": hands}
    if as_json:
        print_json(report)
        return
    for hand, h in hands.items():
        console.print(f"{hand} hand: peak speed {h['peak_speed_m_s']:.2f} m/s, up to "
                      f"{h['farthest_mm']:.0f} mm from its start, clutch held "
                      f"{h['clutched_s']:.1f} s")
    console.print(f"wrote {out}", soft_wrap=True)
