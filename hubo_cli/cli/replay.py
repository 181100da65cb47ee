"""``hubo replay RUN``: re-play a run folder in 3-D (PyBullet window) or render it to an MP4."""

from __future__ import annotations

import contextlib
from pathlib import Path

import click

from hubo_cli.cli.options import force_option
from hubo_cli.cli.output import console, err_console, print_json, report_log_warnings
from hubo_cli.viz.camera import DEFAULT_PRESET, PRESETS


def size_option(function):
    """``--size WxH`` (video frame size)."""
    return click.option("--size", default="640x480", show_default=True, metavar="WxH",
                        help="Video frame size in pixels (even numbers).")(function)


def parse_size(text: str) -> tuple[int, int]:
    """``"640x480"`` -> (640, 480); bad text or a size no picture is made at is an input
    error."""
    from hubo_cli.errors import InputError, quoted
    from hubo_cli.viz.camera import check_image_size

    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"bad --size {quoted(text)}",
                         hint="give WIDTHxHEIGHT, e.g. 640x480") from None
    check_image_size(width, height)  # before the run is read
    return width, height


def make_video(run_dir, out=None, *, speed=None, camera=DEFAULT_PRESET, size="640x480",
               start_s=None, end_s=None, quiet=False, scene=None):
    """Render a run's video (``out``, an :class:`~hubo_cli.outputs.OutputFile`, or
    RUN/video.mp4) under a temporary name, renamed when complete, with a progress bar on a
    terminal's stderr (elsewhere a line at the start and at each quarter, unless ``quiet``:
    --json); ``scene``: the run's, if already loaded; returns the
    :class:`~hubo_cli.viz.video.VideoResult`."""
    import dataclasses

    from hubo_cli.outputs import replacing
    from hubo_cli.viz.scene import load_scene
    from hubo_cli.viz.video import render_video

    width, height = parse_size(size)
    scene = scene or load_scene(run_dir)
    path = out.path if out is not None else scene.run_dir / "video.mp4"
    target = out.writing() if out is not None else replacing(path)
    with contextlib.ExitStack() as stack:
        temporary = stack.enter_context(target)
        on_frame = stack.enter_context(frame_progress(f"rendering {path.name}", quiet))
        result = render_video(scene, temporary, speed=speed, camera=camera, width=width,
                              height=height, start_s=start_s, end_s=end_s, on_frame=on_frame)
    return dataclasses.replace(result, path=path)


@contextlib.contextmanager
def frame_progress(what: str, quiet: bool = False):
    """A callback ``(done, total)`` showing progress: a bar with the time left on a terminal's
    stderr, else (unless ``quiet``) a plain line on stderr at the start and at each quarter."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    if err_console.is_terminal and not err_console.is_dumb_terminal:
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                      TimeElapsedColumn(), TimeRemainingColumn(), console=err_console,
                      transient=True) as progress:
            bar = progress.add_task(what, total=None)
            yield lambda done, total: progress.update(bar, completed=done, total=total)
        return
    quarters = [-1]

    def on_frame(done: int, total: int) -> None:
        quarter = 4 * done // max(total, 1)
        if not quiet and (done == 1 or quarter > quarters[0]):
            err_console.print(f"{what}: {done}/{total} frames", soft_wrap=True)
            quarters[0] = quarter
    yield on_frame


def describe_video(result) -> str:
    """One line about a rendered video."""
    return (f"{result.path} ({result.frames} frames at 30 fps, {result.width}x{result.height}, "
            f"{result.speed:g}x real time, rendered in {result.wall_s:.1f} s)")


@click.command("replay")
@click.argument("run", type=click.Path(exists=True))
@click.option("--gui", is_flag=True, help="Show it in the PyBullet window.")
@click.option("--video", type=click.Path(dir_okay=False), default=None, metavar="FILE.mp4",
              help="Render it headless to an H.264 MP4 (needs hubo-cli[viz]).")
@click.option("--speed", type=float, default=None, metavar="X",
              help="Times real time (default: 1 in the window; for a video 1, or faster for "
                   "runs over 20 s so that the video lasts 20 s).")
@click.option("--camera", type=click.Choice(sorted(PRESETS)), default=DEFAULT_PRESET,
              show_default=True, help="Camera preset of the video (and the window's start view).")
@size_option
@click.option("--from", "start_s", type=float, default=None, metavar="S",
              help="Video: start at this run time (s).")
@click.option("--to", "end_s", type=float, default=None, metavar="S",
              help="Video: end at this run time (s).")
@force_option
@click.option("--json", "as_json", is_flag=True, help="Print what was done as JSON.")
def replay(run, gui, video, speed, camera, size, start_s, end_s, force, as_json) -> None:
    """Re-play a run folder (sim or hardware) in 3-D from its log.

    The logged joints and torso pose are set every period, with the walls as placed; the goal
    (green) and measured (red) tool paths and the hole are drawn.

    Examples: hubo replay runs/<run> --video cut.mp4
              hubo replay runs/<run> --gui --speed 2
    """
    from hubo_cli.errors import InputError
    from hubo_cli.outputs import OutputFile
    from hubo_cli.pace import check_speed
    from hubo_cli.viz.scene import load_scene

    if not gui and video is None:
        raise InputError("nothing to do: give --video FILE.mp4 or --gui",
                         hint="e.g. hubo replay RUN --video run.mp4")
    check_speed(speed)  # before any work: the window and the video pace by it
    report: dict = {"run_dir": str(run)}
    out = None
    if video is not None:
        out = OutputFile(video, option="--video", inputs=(run,), force=force)
        if out.path.suffix.lower() != ".mp4":  # ffmpeg picks its format by the name
            raise InputError(f"--video {video}: the video is an MP4 file, its name must end "
                             "in .mp4", hint=f"e.g. --video {out.path.with_suffix('.mp4').name}")
    scene = load_scene(run)
    report["periods"] = len(scene)
    report_log_warnings(scene.log, report, as_json)
    if out is not None:
        result = make_video(run, out, speed=speed, camera=camera, size=size, start_s=start_s,
                            end_s=end_s, quiet=as_json, scene=scene)
        report["video"] = {"path": str(result.path), "frames": result.frames,
                           "width": result.width, "height": result.height,
                           "speed": result.speed, "run_s": result.run_s,
                           "wall_s": result.wall_s, "renderer": result.renderer}
        if not as_json:
            console.print(f"video  {describe_video(result)}", soft_wrap=True)
    if gui:
        from hubo_cli.viz.camera import camera_for
        from hubo_cli.viz.replay import KinematicReplay

        with KinematicReplay(scene, gui=True) as window:
            view = camera_for(camera, scene.focus_world_m(), scene.working_arm)
            report["periods_shown"] = window.play(speed or 1.0, view)
    if as_json:
        print_json(report)


def check_video_support() -> None:
    """Fail before a run that asks for ``--video`` when the encoder is missing (exit 2)."""
    from hubo_cli.viz.deps import require

    require("imageio_ffmpeg", "the MP4 video (--video)")


def add_run_video(run_dir, summary: dict, quiet: bool = False):
    """After a run: render RUN/video.mp4 from its log (default speed and camera), list it in
    the summary (and summary.json); ``quiet``: no progress lines off a terminal (--json);
    returns the :class:`~hubo_cli.viz.video.VideoResult`."""

    from hubo_cli.runs import write_json

    result = make_video(run_dir, quiet=quiet)
    summary.setdefault("files", []).append(result.path.name)
    summary["video"] = {"file": result.path.name, "frames": result.frames,
                        "speed": result.speed, "wall_s": result.wall_s}
    if (Path(run_dir) / "summary.json").exists():
        write_json(Path(run_dir) / "summary.json", summary)
    return result
