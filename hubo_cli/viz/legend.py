"""The legend bar under videos and snapshots: what each colour and marker drawn over the scene
means (Pillow)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BAR_RGB = (236, 236, 236)
TEXT_RGB = (20, 20, 24)
RING_RGB = (255, 255, 255)
RING_EDGE_RGB = (20, 20, 24)


@dataclass(frozen=True)
class Entry:
    """One legend entry: a ``line``, ``dot`` or ``ring`` sample in ``rgb`` and its words."""

    kind: str
    rgb: tuple[int, int, int]
    label: str


def rgb255(rgb) -> tuple[int, int, int]:
    """An RGB colour of floats in [0, 1] as 0-255 integers."""
    return tuple(int(round(255 * c)) for c in rgb)


def font(height_px: int):
    """The default font sized for a picture ``height_px`` tall."""
    from PIL import ImageFont

    return ImageFont.load_default(size=max(11, height_px // 34))


def bar_height_px(picture_height_px: int) -> int:
    """The height of the caption and legend bars of a picture."""
    return max(11, picture_height_px // 34) + 10


def draw_ring(draw, x: float, y: float, r: float) -> None:
    """The tool's marker: a white ring with a dark edge (seen on a light or a dark ground)."""
    draw.ellipse((x - r - 1, y - r - 1, x + r + 1, y + r + 1), outline=RING_EDGE_RGB, width=1)
    draw.ellipse((x - r, y - r, x + r, y + r), outline=RING_RGB, width=2)


def draw_legend(picture, entries: list[Entry]) -> None:
    """Draw a light bar along the bottom of a PIL image holding ``entries`` left to right."""
    from PIL import ImageDraw

    draw = ImageDraw.Draw(picture)
    bar = bar_height_px(picture.height)
    top = picture.height - bar
    draw.rectangle((0, top, picture.width, picture.height), fill=BAR_RGB)
    text_font = font(picture.height)
    x, y = 8, top + bar / 2
    for entry in entries:
        if entry.kind == "line":
            draw.line((x, y, x + 18, y), fill=entry.rgb, width=3)
        elif entry.kind == "dot":
            for dx in (3, 9, 15):
                draw.ellipse((x + dx - 2, y - 2, x + dx + 2, y + 2), fill=entry.rgb)
        else:
            draw_ring(draw, x + 9, y, 6)
        draw.text((x + 24, top + 5), entry.label, fill=TEXT_RGB, font=text_font)
        x += 24 + draw.textlength(entry.label, font=text_font) + 16


def mark_hole(draw, pixels: np.ndarray, rgb) -> None:
    """The hole's points as small dots."""
    for x, y in pixels:
        if np.isfinite(x):
            draw.ellipse((x - 1.5, y - 1.5, x + 1.5, y + 1.5), fill=rgb)
