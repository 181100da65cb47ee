"""Camera presets for videos and snapshots, and the projection of world points to pixels.

A camera looks at a focus point (the hole, or the tool's path) from an offset given in the world
frame, mirrored to the working arm's side (the robot faces +x; its right arm is at -y):

* ``shoulder`` (default): three-quarter view from behind and above the working shoulder, so the
  bit, the wall and the body's lean are all in view;
* ``side``: from the working side, square to the robot's forward axis (the lean in profile);
* ``behind``: from straight behind the robot;
* ``top``: from above;
* ``wide``: the whole robot and the wall from behind on the other side.

:func:`fit_camera` keeps a preset's direction and field of view and moves the camera back (or
in) until a bounding box (the robot's links and the hole, :func:`body_bounds_m`) fills the
picture between its caption and legend bars, so that no head or foot is cut off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import InputError, quoted

# preset -> (eye offset from the focus for the right arm (m), vertical field of view (deg))
PRESETS = {
    "shoulder": ((-1.55, -0.95, 0.75), 40.0),
    "side": ((0.05, -1.6, 0.25), 45.0),
    "behind": ((-1.7, 0.0, 0.35), 45.0),
    "top": ((0.0, -0.05, 1.8), 50.0),
    "wide": ((-0.7, 2.6, 0.6), 45.0),
}
DEFAULT_PRESET = "shoulder"
FIT_MARGIN_PX = 6  # the fitted box's corners stay this far inside the picture
# A picture's size: even (H.264's 4:2:0 colour), at least 16 px, at most 8K UHD (review 28: a
# 100000 x 100000 --size grew the renderer's memory by 300 MB/s until the machine ran out,
# with Ctrl-C unheard inside PyBullet's renderer)
IMAGE_MIN_PX, IMAGE_MAX_PX = 16, (7680, 4320)


@dataclass(frozen=True)
class Camera:
    """A pinhole camera (world frame, m).

    Attributes:
        eye_m: camera position.
        target_m: the point it looks at.
        fov_deg: vertical field of view.
        width, height: image size (pixels).
    """

    eye_m: tuple[float, float, float]
    target_m: tuple[float, float, float]
    fov_deg: float
    width: int
    height: int

    def view_matrix(self) -> np.ndarray:
        """World -> camera (4x4, OpenGL convention: the camera looks along -z, y up)."""
        eye, target = np.asarray(self.eye_m), np.asarray(self.target_m)
        forward = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        if np.linalg.norm(right) < 1e-9:  # looking straight down: +x is up in the image
            right = np.cross(forward, [1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        V = np.eye(4)
        V[0, :3], V[1, :3], V[2, :3] = right, up, -forward
        V[:3, 3] = -V[:3, :3] @ eye
        return V

    def projection_matrix(self, near_m: float = 0.05, far_m: float = 20.0) -> np.ndarray:
        """Camera -> clip space (4x4, OpenGL convention)."""
        f = 1.0 / np.tan(np.radians(self.fov_deg) / 2)
        aspect = self.width / self.height
        P = np.zeros((4, 4))
        P[0, 0], P[1, 1] = f / aspect, f
        P[2, 2] = (far_m + near_m) / (near_m - far_m)
        P[2, 3] = 2 * far_m * near_m / (near_m - far_m)
        P[3, 2] = -1.0
        return P

    def gl_matrices(self) -> tuple[list[float], list[float]]:
        """The view and projection matrices as PyBullet takes them (column-major lists)."""
        return (self.view_matrix().T.ravel().tolist(),
                self.projection_matrix().T.ravel().tolist())

    def project(self, points_m) -> np.ndarray:
        """Pixel coordinates (N x 2, x right, y down) of world points; NaN behind the camera."""
        p = np.atleast_2d(np.asarray(points_m, dtype=float))
        clip = (self.projection_matrix() @ self.view_matrix()
                @ np.column_stack([p, np.ones(len(p))]).T).T
        with np.errstate(invalid="ignore", divide="ignore"):
            ndc = clip[:, :2] / clip[:, 3:4]
        pixels = np.column_stack([(ndc[:, 0] + 1) / 2 * self.width,
                                  (1 - ndc[:, 1]) / 2 * self.height])
        pixels[~(clip[:, 3] > 1e-6)] = np.nan
        return pixels


def check_image_size(width: int, height: int) -> None:
    """Refuse a picture size no video or snapshot can be made at (see IMAGE_MAX_PX).

    Raises:
        InputError: odd, below IMAGE_MIN_PX or above IMAGE_MAX_PX.
    """
    most_w, most_h = IMAGE_MAX_PX
    if (width < IMAGE_MIN_PX or height < IMAGE_MIN_PX or width % 2 or height % 2
            or width > most_w or height > most_h):
        raise InputError(f"image size {width} x {height} is not usable",
                         hint=f"give an even width and height from {IMAGE_MIN_PX} to "
                              f"{most_w} x {most_h} pixels")


def camera_for(preset: str, focus_m, working_arm: str = "right-arm", width: int = 640,
               height: int = 480) -> Camera:
    """The camera of a preset looking at ``focus_m`` (see the module docstring).

    Raises:
        InputError: unknown preset or bad image size.
    """
    if preset not in PRESETS:
        raise InputError(f"unknown camera preset {quoted(preset)}",
                         hint=f"use one of {', '.join(PRESETS)}")
    check_image_size(width, height)
    offset, fov = _offset(preset, working_arm)
    focus = np.asarray(focus_m, dtype=float)
    return Camera(tuple(focus + offset), tuple(focus), fov, int(width), int(height))


def _offset(preset: str, working_arm: str) -> tuple[np.ndarray, float]:
    offset, fov = PRESETS[preset]
    offset = np.array(offset, dtype=float)
    if working_arm == "left-arm":
        offset[1] = -offset[1]
    return offset, fov


def fit_camera(preset: str, lower_m, upper_m, working_arm: str = "right-arm", width: int = 640,
               height: int = 480, *, top_px: int = 0, bottom_px: int = 0) -> Camera:
    """A preset's camera (its direction and field of view) looking at the centre of the box
    ``lower_m``..``upper_m`` (world, m) from the distance at which the whole box is in the
    picture, :data:`FIT_MARGIN_PX` inside its edges and clear of ``top_px`` and ``bottom_px``
    (caption and legend bars): as close as that allows.

    Raises:
        InputError: unknown preset, bad image size, or a box that is not finite.
    """
    lower, upper = np.asarray(lower_m, dtype=float), np.asarray(upper_m, dtype=float)
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise InputError("the box to frame is not finite", hint="frame points that are known")
    centre = 0.5 * (lower + upper)
    camera_for(preset, centre, working_arm, width, height)  # checks the preset and the size
    offset, fov = _offset(preset, working_arm)
    direction = offset / np.linalg.norm(offset)
    corners = np.array([[(lower, upper)[i >> k & 1][k] for k in range(3)] for i in range(8)])
    m = FIT_MARGIN_PX
    y_lo, y_hi = top_px + m, height - bottom_px - m

    def camera_at(distance_m: float) -> Camera:
        return Camera(tuple(centre + direction * distance_m), tuple(centre), fov, int(width),
                      int(height))

    def fits(distance_m: float) -> bool:
        px = camera_at(distance_m).project(corners)
        return bool(np.all(np.isfinite(px)) and np.all((px[:, 0] >= m) & (px[:, 0] <= width - m)
                                                       & (px[:, 1] >= y_lo) & (px[:, 1] <= y_hi)))

    near, far = 0.05, 0.05 + 2.0 * float(np.linalg.norm(upper - lower)) + 1.0
    while not fits(far) and far < 1e4:
        far *= 2.0
    for _ in range(40):
        mid = 0.5 * (near + far)
        near, far = (near, mid) if fits(mid) else (mid, far)
    return camera_at(far)


def body_bounds_m(p, body: int, client: int) -> tuple[np.ndarray, np.ndarray]:
    """The world bounding box (lower, upper corners, m) of every link of a PyBullet body."""
    boxes = [p.getAABB(body, link, physicsClientId=client)
             for link in range(-1, p.getNumJoints(body, physicsClientId=client))]
    corners = np.array([corner for box in boxes for corner in box], dtype=float)
    return corners.min(axis=0), corners.max(axis=0)
