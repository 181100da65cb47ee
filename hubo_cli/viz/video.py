"""Render a run to an H.264 MP4: the replayed robot from a fixed camera, the tool paths, the hole
and a caption, at 30 frames per second.

Frame ``i`` shows the last logged period at or before run time ``t0 + i * speed / fps``; a span
of T seconds of the run gives ``round(T * fps / speed)`` frames. The goal path (green) is drawn
whole, the measured path (red) and the hole (dark) up to the frame's time; a ring marks the tool.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.viz.camera import DEFAULT_PRESET, Camera, camera_for
from hubo_cli.viz.deps import require
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, KinematicReplay
from hubo_cli.viz.scene import RunScene

FPS = 30
LONGEST_AT_REAL_TIME_S = 20.0  # longer runs are sped up to a video of this length by default


def default_speed(scene: RunScene) -> float:
    """Real time, or faster for runs longer than :data:`LONGEST_AT_REAL_TIME_S` so that the
    video lasts that long (a 72 s cut becomes a 20 s video at 3.6x)."""
    run_s = float(scene.t_s[-1] - scene.t_s[0])
    return max(1.0, run_s / LONGEST_AT_REAL_TIME_S)


@dataclass
class VideoResult:
    """What :func:`render_video` wrote.

    Attributes:
        path: the MP4 file.
        frames: frames written.
        width, height: frame size (pixels).
        run_s: run time covered (s).
        wall_s: wall-clock time taken (s).
        renderer: ``egl`` or ``tiny``.
    """

    path: Path
    frames: int
    width: int
    height: int
    speed: float
    run_s: float
    wall_s: float
    renderer: str


def _rgb255(rgb) -> tuple[int, int, int]:
    return tuple(int(round(255 * c)) for c in rgb)


class Overlay:
    """Paths, hole, tool marker and caption drawn over rendered frames (Pillow).

    The goal path is drawn once; the measured path and the hole are added to a kept layer as
    time goes on (frames in time order cost only their new segments).

    Args:
        scene: the run.
        camera: the fixed camera of every frame.
    """

    def __init__(self, scene: RunScene, camera: Camera) -> None:
        from PIL import ImageFont

        self.scene = scene
        self.camera = camera
        self.tool_px = camera.project(scene.tool_world_m)
        self.hole_px = camera.project(scene.hole_world_m) if len(scene.hole_world_m) else None
        hole_t = scene.log.metadata.get("scene", {}).get("hole_t_s", [])
        self.hole_t_s = np.asarray(hole_t, dtype=float)
        if self.hole_px is not None and len(self.hole_t_s) != len(self.hole_px):
            self.hole_t_s = np.full(len(self.hole_px), -np.inf)  # no times: draw it whole
        size = max(11, camera.height // 34)
        self.font = ImageFont.load_default(size=size)
        self.bar_px = size + 10
        self._reset()

    def _reset(self) -> None:
        from PIL import Image, ImageDraw

        self.layer = Image.new("RGBA", (self.camera.width, self.camera.height), (0, 0, 0, 0))
        self._draw = ImageDraw.Draw(self.layer)
        self._polyline(self.camera.project(self.scene.goal_world_m), (*_rgb255(GOAL_RGB), 255), 2)
        self.k_drawn = 0
        self.t_drawn_s = -np.inf

    def _polyline(self, pixels: np.ndarray, rgba, width: int) -> None:
        finite = np.all(np.isfinite(pixels), axis=1)
        # split at unknown points so that no line jumps across a gap
        breaks = np.flatnonzero(np.diff(finite.astype(int)) != 0) + 1
        for part, ok in zip(np.split(pixels, breaks), np.split(finite, breaks), strict=True):
            if ok[0] and len(part) > 1:
                self._draw.line([tuple(p) for p in part], fill=rgba, width=width)

    def _advance(self, k: int) -> None:
        if k < self.k_drawn:
            self._reset()
        self._polyline(self.tool_px[self.k_drawn:k + 1], (*_rgb255(ACTUAL_RGB), 255), 2)
        t_s = self.scene.t_s[k]
        if self.hole_px is not None:
            new = (self.hole_t_s > self.t_drawn_s) & (self.hole_t_s <= t_s + 1e-9)
            for x, y in self.hole_px[new]:
                if np.isfinite(x):
                    self._draw.ellipse((x - 1.5, y - 1.5, x + 1.5, y + 1.5),
                                       fill=(*_rgb255(HOLE_RGB), 255))
        self.k_drawn, self.t_drawn_s = k, t_s

    def draw(self, image: np.ndarray, k: int) -> np.ndarray:
        """The frame of period ``k`` with the overlay (a new array)."""
        from PIL import Image, ImageDraw

        self._advance(k)
        picture = Image.fromarray(image)
        picture.paste(self.layer, (0, 0), self.layer)
        draw = ImageDraw.Draw(picture)
        x, y = self.tool_px[k]
        if np.isfinite(x):
            draw.ellipse((x - 6, y - 6, x + 6, y + 6), outline=(255, 255, 255), width=2)
        draw.rectangle((0, 0, picture.width, self.bar_px), fill=(20, 20, 24))
        draw.text((8, 5), self.scene.caption(k), fill=(240, 240, 240), font=self.font)
        return np.asarray(picture)


def frame_periods(scene: RunScene, speed: float, fps: int = FPS, start_s: float | None = None,
                  end_s: float | None = None) -> np.ndarray:
    """The logged period shown in each video frame, for run times from ``start_s`` (default:
    the first period) to ``end_s`` (default: the end of the last period)."""
    t_s = scene.t_s
    dt = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 0.005
    first = float(t_s[0]) if start_s is None else float(start_s)
    last = float(t_s[-1]) + dt if end_s is None else float(end_s)
    if not t_s[0] - 1e-9 <= first < last:
        raise InputError(f"no run time between {first:g} s and {last:g} s to show",
                         hint=f"the run spans {t_s[0]:g} to {t_s[-1] + dt:g} s")
    frames = max(1, int(round((last - first) * fps / speed)))
    return np.array([scene.index_at(first + i * speed / fps) for i in range(frames)])


def render_video(scene: RunScene, out: str | Path, *, speed: float | None = None,
                 camera: str = DEFAULT_PRESET, width: int = 640, height: int = 480,
                 fps: int = FPS, start_s: float | None = None, end_s: float | None = None,
                 on_frame=None) -> VideoResult:
    """Replay ``scene`` headless into an H.264 MP4 at ``out``.

    Args:
        scene: the run.
        out: the MP4 file to write (its folder is created).
        speed: run seconds per video second (None: :func:`default_speed`).
        camera: a camera preset (:data:`hubo_cli.viz.camera.PRESETS`).
        width, height: frame size (even, pixels).
        fps: frames per second.
        start_s, end_s: the part of the run to show (run time, s; default all of it).
        on_frame: called with (frame index, frames) after each frame (progress).

    Raises:
        InputError: bad speed, size or preset.
        MissingOptionalDependency: imageio-ffmpeg is not installed.
    """
    imageio_ffmpeg = require("imageio_ffmpeg", "the MP4 video")
    speed = default_speed(scene) if speed is None else float(speed)
    if not speed > 0:
        raise InputError(f"speed must be positive, got {speed}", hint="e.g. --speed 2")
    view = camera_for(camera, scene.focus_world_m(), scene.working_arm, width, height)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    periods = frame_periods(scene, speed, fps, start_s, end_s)
    started = time.perf_counter()
    with KinematicReplay(scene) as replay:
        overlay = Overlay(scene, view)
        writer = imageio_ffmpeg.write_frames(
            str(out), (width, height), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
            quality=None, bitrate=None, macro_block_size=2,
            output_params=["-crf", "23", "-preset", "veryfast", "-movflags", "+faststart"],
            ffmpeg_log_level="error")
        writer.send(None)
        try:
            for i, k in enumerate(periods):
                replay.show(int(k))
                writer.send(overlay.draw(replay.render(view), int(k)))
                if on_frame is not None:
                    on_frame(i + 1, len(periods))
        finally:
            writer.close()
        renderer = "egl" if replay.egl else "tiny"
    return VideoResult(out, len(periods), width, height, speed,
                       float(scene.t_s[periods[-1]] - scene.t_s[0]),
                       time.perf_counter() - started, renderer)


def render_still(scene: RunScene, out: str | Path, k: int | None = None, *,
                 camera: str = DEFAULT_PRESET, width: int = 640, height: int = 480) -> Path:
    """One replayed frame (period ``k``, the last by default) with the overlay, as PNG."""
    from hubo_cli.drivers.snapshot import write_png

    k = len(scene) - 1 if k is None else int(k)
    view = camera_for(camera, scene.focus_world_m(), scene.working_arm, width, height)
    with KinematicReplay(scene) as replay:
        replay.show(k)
        image = Overlay(scene, view).draw(replay.render(view), k)
    return write_png(out, image)
