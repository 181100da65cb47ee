"""Render a run to an H.264 MP4: the replayed robot from a fixed camera, the tool paths, the hole
and a caption, at 30 frames per second.

Frame ``i`` shows the last logged period at or before run time ``t0 + i * speed / fps``; a span
of T seconds of the run gives ``round(T * fps / speed)`` frames. The goal path (green) is drawn
whole, the measured path (red) and the hole (dark) up to the frame's time, both only while
cutting where the log says so (elsewhere the bit leaves a short light-red trail); a ring marks
the tool. A caption bar on top gives the time, step, error, wrist torque, lean and status (red
while the status is a warning: an e-stop, a collision, stale input...), a legend bar below
says what the colours mean, the camera frames the whole robot and the hole
(:func:`framing_camera`), and an inset shows the cut magnified (:class:`CutInset`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.outputs import writer_failure
from hubo_cli.pace import check_speed
from hubo_cli.viz.camera import DEFAULT_PRESET, Camera, fit_camera
from hubo_cli.viz.deps import require
from hubo_cli.viz.legend import (
    RING_RGB,
    Entry,
    bar_height_px,
    draw_legend,
    draw_ring,
    font,
    mark_hole,
    rgb255,
)
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, KinematicReplay
from hubo_cli.viz.scene import QUIET_STATUSES, RunScene, first_column

FPS = 30
LONGEST_AT_REAL_TIME_S = 20.0  # longer runs are sped up to a video of this length by default
TRAIL_S = 1.0  # outside the cut the bit leaves a trail this long (s), not a lasting path
TRAIL_RGB = (240, 150, 140)
ALARM_BAR_RGB = (150, 20, 30)  # the caption bar while the status is a warning (an e-stop...)
FRAMING_SAMPLES = 12  # postures of the run whose links the camera frames
INSET_FRACTION = 0.36  # the cut's inset is this part of the picture's height, square
INSET_MIN_SPAN_M = 0.02  # ... and shows at least this much of the wall
INSET_EVERY = 4  # the inset's paths through every 4th period
INSET_SMALLEST_PX = 60  # no inset in pictures too small for one this wide


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


def legend_entries(trail: bool) -> list[Entry]:
    """What the overlay's colours and markers mean (the legend bar's entries)."""
    entries = [Entry("line", rgb255(GOAL_RGB), "goal path"),
               Entry("line", rgb255(ACTUAL_RGB), "bit measured"),
               Entry("dot", rgb255(HOLE_RGB), "hole cut"),
               Entry("ring", RING_RGB, "bit now")]
    if trail:
        entries.insert(2, Entry("line", TRAIL_RGB, f"bit, last {TRAIL_S:g} s"))
    return entries


def drawn_periods(scene: RunScene) -> np.ndarray:
    """The periods whose goal and measured tool paths stay drawn: while cutting where the log
    says (a task's ``cutting`` column), else all (N, bool). Elsewhere (the raise, the way back)
    only a trail of the last :data:`TRAIL_S` seconds follows the bit."""
    cutting = first_column(scene.log, ("cutting",))
    if cutting is None or not np.any(cutting == 1):
        return np.ones(len(scene), dtype=bool)
    return cutting == 1


def step_names(scene: RunScene) -> list[str]:
    """The task's step names from the run folder's ``task.toml`` ([] without a readable one:
    captions then give the step's number only)."""
    import tomllib

    try:
        steps = tomllib.loads((scene.run_dir / "task.toml").read_text(encoding="utf-8"))["steps"]
        return [str(step["name"]) for step in steps]
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, KeyError, TypeError):
        return []


def framing_camera(scene: RunScene, replay: KinematicReplay, preset: str, width: int,
                   height: int) -> Camera:
    """The preset's camera fitted to the robot's links over the run (sampled at
    :data:`FRAMING_SAMPLES` periods) and the hole, clear of the caption and legend bars."""
    periods = np.unique(np.linspace(0, len(scene) - 1, FRAMING_SAMPLES).round().astype(int))
    lower, upper = replay.robot_bounds_m(periods)
    hole = scene.hole_world_m
    if len(hole):
        lower, upper = np.minimum(lower, hole.min(axis=0)), np.maximum(upper, hole.max(axis=0))
    bar = bar_height_px(height)
    return fit_camera(preset, lower, upper, scene.working_arm, width, height, top_px=bar,
                      bottom_px=bar)


class CutInset:
    """The cut magnified in the picture's top-right corner, seen square-on from behind the robot
    (world y mirrored, so that its left is on the left, and z up): the kept goal path, the
    measured path and the hole up to the frame's time, the tool's ring and a scale bar.

    Args:
        scene: the run.
        kept: the periods whose paths are drawn (:func:`drawn_periods`).
        hole_t_s: the hole points' times (s).
        camera: the picture's camera (its size).
        top_px: the inset's top edge (below the caption bar).
    """

    def __init__(self, scene: RunScene, kept: np.ndarray, hole_t_s: np.ndarray, camera: Camera,
                 top_px: int) -> None:
        self.size = int(camera.height * INSET_FRACTION)
        self.left, self.top = camera.width - self.size - 6, top_px + 6
        points = [scene.goal_world_m[kept], scene.tool_world_m[kept], scene.hole_world_m]
        every = np.vstack([p for p in points if len(p)])
        every = self._uv(every[np.all(np.isfinite(every), axis=1)])
        self.panel = None  # the kept drawing, made on the first frame
        self.shown = len(every) > 1 and self.size >= INSET_SMALLEST_PX
        if not self.shown:
            return
        lo, hi = every.min(axis=0), every.max(axis=0)
        span = max(float(np.max(hi - lo)) * 1.15, INSET_MIN_SPAN_M)
        self.scale = (self.size - 20) / span  # px per m
        self.centre = 0.5 * (lo + hi)
        self.goal = self._px(np.where(kept[:, None], scene.goal_world_m, np.nan))
        self.tool = self._px(scene.tool_world_m)
        self.kept = kept
        self.hole = self._px(scene.hole_world_m) if len(scene.hole_world_m) else np.zeros((0, 2))
        self.hole_t_s = hole_t_s
        self.t_s = scene.t_s
        bar_m = next((b for b in (0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)
                      if b * self.scale <= (self.size - 20) / 2), 0.001)
        self.bar_m, self.bar_px = bar_m, bar_m * self.scale

    @staticmethod
    def _uv(points: np.ndarray) -> np.ndarray:
        return np.column_stack([-points[:, 1], points[:, 2]])

    def _px(self, points: np.ndarray) -> np.ndarray:
        uv = (self._uv(points) - self.centre) * self.scale
        return np.column_stack([self.left + self.size / 2 + uv[:, 0],
                                self.top + self.size / 2 - uv[:, 1]])

    def _reset(self, text_font) -> None:
        from PIL import Image, ImageDraw

        n = self.size
        self.panel = Image.new("RGB", (n + 1, n + 1), (248, 248, 248))
        self._draw = ImageDraw.Draw(self.panel)
        self._draw.rectangle((0, 0, n, n), outline=(20, 20, 24))
        offset = np.array([self.left, self.top])
        _polyline(self._draw, self.goal[::INSET_EVERY] - offset, rgb255(GOAL_RGB), 2)
        self._draw.text((4, 2), "cut, magnified", fill=(20, 20, 24), font=text_font)
        by = n - 8
        self._draw.line((6, by, 6 + self.bar_px, by), fill=(20, 20, 24), width=2)
        self._draw.text((10 + self.bar_px, by - 12), f"{self.bar_m * 1000:g} mm",
                        fill=(20, 20, 24), font=text_font)
        self.k_drawn, self.t_drawn_s = 0, -np.inf

    def draw(self, picture, k: int, text_font) -> None:
        """Paste the inset for period ``k`` into a PIL image (the paths and the hole added to a
        kept panel as time goes on, as the overlay's layer)."""
        from PIL import ImageDraw

        if not self.shown:
            return
        if self.panel is None or k < self.k_drawn:
            self._reset(text_font)
        offset = np.array([self.left, self.top])
        t_s = self.t_s[k]
        new = (self.hole_t_s > self.t_drawn_s) & (self.hole_t_s <= t_s + 1e-9)
        mark_hole(self._draw, self.hole[new] - offset, rgb255(HOLE_RGB))
        start = max(self.k_drawn - self.k_drawn % INSET_EVERY, 0)
        part = np.where(self.kept[start:k + 1, None], self.tool[start:k + 1], np.nan)
        _polyline(self._draw, part[::INSET_EVERY] - offset, rgb255(ACTUAL_RGB), 1)
        self.k_drawn, self.t_drawn_s = k, t_s
        picture.paste(self.panel, (self.left, self.top))
        x, y = self.tool[k]
        if self.left <= x <= self.left + self.size and self.top <= y <= self.top + self.size:
            draw_ring(ImageDraw.Draw(picture), x, y, 4)


class Overlay:
    """Paths, hole, tool marker, caption and legend drawn over rendered frames (Pillow).

    The goal path is drawn once; the measured path and the hole are added to a kept layer as
    time goes on (frames in time order cost only their new segments). Both paths are kept only
    where :func:`drawn_periods` says; elsewhere the bit leaves a short trail.

    Args:
        scene: the run.
        camera: the fixed camera of every frame.
    """

    def __init__(self, scene: RunScene, camera: Camera) -> None:
        self.scene = scene
        self.camera = camera
        self.tool_px = camera.project(scene.tool_world_m)
        self.hole_px = camera.project(scene.hole_world_m) if len(scene.hole_world_m) else None
        hole_t = scene.log.metadata.get("scene", {}).get("hole_t_s", [])
        self.hole_t_s = np.asarray(hole_t, dtype=float)
        if self.hole_px is not None and len(self.hole_t_s) != len(self.hole_px):
            self.hole_t_s = np.full(len(self.hole_px), -np.inf)  # no times: draw it whole
        self.kept = drawn_periods(scene)
        self.step_names = step_names(scene)
        self.entries = legend_entries(trail=not self.kept.all())
        self.font = font(camera.height)
        self.small_font = font(int(camera.height * 0.8))
        self.bar_px = bar_height_px(camera.height)
        self.inset = CutInset(scene, self.kept, self.hole_t_s if self.hole_px is not None
                              else np.zeros(0), camera, self.bar_px)
        self._reset()

    def _kept_only(self, pixels: np.ndarray, start: int = 0) -> np.ndarray:
        """``pixels`` (of periods start...) with those not kept made unknown (NaN)."""
        return np.where(self.kept[start:start + len(pixels), None], pixels, np.nan)

    def _reset(self) -> None:
        from PIL import Image, ImageDraw

        self.layer = Image.new("RGBA", (self.camera.width, self.camera.height), (0, 0, 0, 0))
        self._draw = ImageDraw.Draw(self.layer)
        goal_px = self._kept_only(self.camera.project(self.scene.goal_world_m))
        _polyline(self._draw, goal_px, (*rgb255(GOAL_RGB), 255), 2)
        self.k_drawn = 0
        self.t_drawn_s = -np.inf

    def _advance(self, k: int) -> None:
        if k < self.k_drawn:
            self._reset()
        part = self._kept_only(self.tool_px[self.k_drawn:k + 1], self.k_drawn)
        _polyline(self._draw, part, (*rgb255(ACTUAL_RGB), 255), 2)
        t_s = self.scene.t_s[k]
        if self.hole_px is not None:
            new = (self.hole_t_s > self.t_drawn_s) & (self.hole_t_s <= t_s + 1e-9)
            mark_hole(self._draw, self.hole_px[new], (*rgb255(HOLE_RGB), 255))
        self.k_drawn, self.t_drawn_s = k, t_s

    def draw(self, image: np.ndarray, k: int) -> np.ndarray:
        """The frame of period ``k`` with the overlay (a new array)."""
        from PIL import Image, ImageDraw

        self._advance(k)
        picture = Image.fromarray(image)
        picture.paste(self.layer, (0, 0), self.layer)
        draw = ImageDraw.Draw(picture)
        if not self.kept[k]:
            first = self.scene.index_at(self.scene.t_s[k] - TRAIL_S)
            _polyline(draw, self.tool_px[first:k + 1], TRAIL_RGB, 2)
        x, y = self.tool_px[k]
        if np.isfinite(x):
            draw_ring(draw, x, y, 6)
        self.inset.draw(picture, k, self.small_font)
        code = int(self.scene.log["status_code"][k])
        alarm = code not in QUIET_STATUSES  # e-stopped, collision, stale input...: red bar
        draw.rectangle((0, 0, picture.width, self.bar_px),
                       fill=ALARM_BAR_RGB if alarm else (20, 20, 24))
        draw.text((8, 5), self.scene.caption(k, self.step_names), fill=(240, 240, 240),
                  font=self.font)
        draw_legend(picture, self.entries)
        return np.asarray(picture)


def _polyline(draw, pixels: np.ndarray, rgba, width: int) -> None:
    """Lines through the pixels, split at unknown (NaN) ones so that no line jumps a gap."""
    finite = np.all(np.isfinite(pixels), axis=1)
    breaks = np.flatnonzero(np.diff(finite.astype(int)) != 0) + 1
    for part, ok in zip(np.split(pixels, breaks), np.split(finite, breaks), strict=True):
        if ok[0] and len(part) > 1:
            draw.line([tuple(p) for p in part], fill=rgba, width=width)


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
    speed = default_speed(scene) if speed is None else check_speed(speed)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    periods = frame_periods(scene, speed, fps, start_s, end_s)
    started = time.perf_counter()
    with KinematicReplay(scene) as replay:
        view = framing_camera(scene, replay, camera, width, height)
        overlay = Overlay(scene, view)
        writer = imageio_ffmpeg.write_frames(
            str(out), (width, height), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
            quality=None, bitrate=None, macro_block_size=2,
            output_params=["-crf", "23", "-preset", "veryfast", "-movflags", "+faststart"],
            ffmpeg_log_level="quiet")  # its failures are ours to say, in one line
        try:
            writer.send(None)
            try:
                for i, k in enumerate(periods):
                    replay.show(int(k))
                    writer.send(overlay.draw(replay.render(view), int(k)))
                    if on_frame is not None:
                        on_frame(i + 1, len(periods))
            finally:
                writer.close()
            # ffmpeg that fails at the end (its index, the trailer, on a full disk) exits with
            # an error the writer does not raise: the file itself says whether it is whole
            check_mp4(out)
        except OSError as exc:  # ffmpeg stopped (a full disk: a broken pipe, pages of text)
            raise writer_failure(out, "ffmpeg", exc) from None
        renderer = "egl" if replay.egl else "tiny"
    return VideoResult(out, len(periods), width, height, speed,
                       float(scene.t_s[periods[-1]] - scene.t_s[0]),
                       time.perf_counter() - started, renderer)


def check_mp4(path: str | Path) -> None:
    """The MP4 file at ``path`` is whole: its top-level boxes (ISO 14496-12: a 32-bit size,
    or 1 and a 64-bit one, then the type) cover the file exactly, and the index (``moov``) and
    the frames (``mdat``) are among them. A file ffmpeg left when it failed at the end (a full
    disk while it wrote the index or moved it to the front for ``+faststart``) is cut short
    or has no index: no player opens it.

    Raises:
        OSError: it is not (or cannot be read).
    """
    import struct

    found, offset = set(), 0
    with open(path, "rb") as f:
        size_bytes = f.seek(0, 2)
        while offset < size_bytes:
            f.seek(offset)
            header = f.read(16)
            if len(header) < 8:
                break
            size, kind = struct.unpack(">I4s", header[:8])
            if size == 1 and len(header) == 16:
                size = struct.unpack(">Q", header[8:])[0]
            elif size == 0:  # the last box runs to the end of the file
                size = size_bytes - offset
            if size < 8 or offset + size > size_bytes:
                break
            found.add(kind)
            offset += size
    if offset != size_bytes or not {b"moov", b"mdat"} <= found:
        raise OSError(f"the MP4 is incomplete ({size_bytes:,} bytes, "
                      f"{'no index' if b'moov' not in found else 'cut short'})")


def render_still(scene: RunScene, out: str | Path, k: int | None = None, *,
                 camera: str = DEFAULT_PRESET, width: int = 640, height: int = 480) -> Path:
    """One replayed frame (period ``k``, the last by default) with the overlay, as PNG."""
    from hubo_cli.drivers.snapshot import write_png

    k = len(scene) - 1 if k is None else int(k)
    with KinematicReplay(scene) as replay:
        view = framing_camera(scene, replay, camera, width, height)
        replay.show(k)
        image = Overlay(scene, view).draw(replay.render(view), k)
    return write_png(out, image)
