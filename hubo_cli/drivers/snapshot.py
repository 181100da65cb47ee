"""Simulation snapshots: the scene from the video's camera with the bit and the hole marked, and
PNG writing (no imaging library needed for the file itself)."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

HOLE_RGB = (38, 26, 13)
MARK_RGB = (255, 255, 255)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def png_bytes(image: np.ndarray) -> bytes:
    """Encode an H x W x 3 uint8 RGB image as PNG bytes (8-bit truecolour, no filter)."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an H x W x 3 image, got shape {image.shape}")
    height, width, _ = image.shape
    rows = np.zeros((height, 1 + 3 * width), dtype=np.uint8)  # filter byte 0 per row
    rows[:, 1:] = image.reshape(height, 3 * width)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header)
            + _chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _chunk(b"IEND", b""))


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an H x W x 3 uint8 RGB image to ``path`` as PNG and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png_bytes(image))
    return path


def mark_points(image: np.ndarray, camera, hole_world_m, tool_world_m,
                tool: str = "tool") -> np.ndarray:
    """The image with the hole's points (dots), the tool (a ring; ``tool`` names it) and a
    legend bar saying what they are drawn over it."""
    from PIL import Image, ImageDraw

    from hubo_cli.viz.legend import Entry, draw_legend, draw_ring, mark_hole

    picture = Image.fromarray(np.ascontiguousarray(image, dtype=np.uint8))
    draw = ImageDraw.Draw(picture)
    hole = np.asarray(hole_world_m, dtype=float).reshape(-1, 3)
    entries = [Entry("ring", MARK_RGB, tool)]
    if len(hole):
        mark_hole(draw, camera.project(hole), HOLE_RGB)
        entries.insert(0, Entry("dot", HOLE_RGB, "hole cut in the wall"))
    x, y = camera.project(tool_world_m)[0]
    if np.isfinite(x):
        draw_ring(draw, x, y, max(3.0, camera.height / 80))
    draw_legend(picture, entries)
    return np.asarray(picture)


def snapshot_camera(p, client: int, scene: dict, tool_world_m, robot: int, width: int = 640,
                    height: int = 480, preset: str = "shoulder"):
    """The camera of a snapshot: the preset's, fitted to the robot's links, the hole and the
    tool, clear of the legend bar (see :func:`hubo_cli.viz.camera.fit_camera`)."""
    from hubo_cli.viz.camera import body_bounds_m, fit_camera
    from hubo_cli.viz.legend import bar_height_px

    lower, upper = body_bounds_m(p, robot, client)
    hole = np.asarray(scene.get("hole_world_m", []), dtype=float).reshape(-1, 3)
    for points in (hole, np.asarray(tool_world_m, dtype=float).reshape(-1, 3)):
        if len(points) and np.all(np.isfinite(points)):
            lower = np.minimum(lower, points.min(axis=0))
            upper = np.maximum(upper, points.max(axis=0))
    arm = next((a for a, t in scene.get("tools", {}).items() if t == "drill"), "right-arm")
    return fit_camera(preset, lower, upper, arm, width, height, bottom_px=bar_height_px(height))


def scene_snapshot(p, client: int, path: str | Path, scene: dict, tool_world_m, robot: int,
                   width: int = 640, height: int = 480, preset: str = "shoulder") -> Path:
    """Render a live PyBullet scene headless (TinyRenderer) from the video camera's preset,
    framing the whole robot and the hole (:func:`snapshot_camera`), mark the hole and the
    tool, and write it as PNG.

    Args:
        p, client: the pybullet module and the physics client id.
        path: the PNG to write.
        scene: the simulator's scene description (``walls``, ``tools``, ``hole_world_m``).
        tool_world_m: the working tool's point in the world (m).
        robot: the robot's body id (its links are framed).
        width, height: image size (pixels, even).
        preset: a camera preset of :mod:`hubo_cli.viz.camera`.
    """
    camera = snapshot_camera(p, client, scene, tool_world_m, robot, width, height, preset)
    view, proj = camera.gl_matrices()
    _, _, rgba, _, _ = p.getCameraImage(width, height, view, proj, renderer=p.ER_TINY_RENDERER,
                                        shadow=0, physicsClientId=client)
    image = np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3]
    hole = np.asarray(scene.get("hole_world_m", []), dtype=float).reshape(-1, 3)
    tool = "drill bit" if "drill" in scene.get("tools", {}).values() else "hand"
    return write_png(path, mark_points(image, camera, hole, np.asarray(tool_world_m, float),
                                       tool))
