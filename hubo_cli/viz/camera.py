"""Camera presets for videos and snapshots, and the projection of world points to pixels.

A camera looks at a focus point (the hole, or the tool's path) from an offset given in the world
frame, mirrored to the working arm's side (the robot faces +x; its right arm is at -y):

* ``shoulder`` (default): three-quarter view from behind and above the working shoulder, so the
  bit, the wall and the body's lean are all in view;
* ``side``: from the working side, square to the robot's forward axis (the lean in profile);
* ``behind``: from straight behind the robot;
* ``top``: from above;
* ``wide``: the whole robot and the wall from behind on the other side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import InputError

# preset -> (eye offset from the focus for the right arm (m), vertical field of view (deg))
PRESETS = {
    "shoulder": ((-1.55, -0.95, 0.75), 40.0),
    "side": ((0.05, -1.6, 0.25), 45.0),
    "behind": ((-1.7, 0.0, 0.35), 45.0),
    "top": ((0.0, -0.05, 1.8), 50.0),
    "wide": ((-0.7, 2.6, 0.6), 45.0),
}
DEFAULT_PRESET = "shoulder"


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


def camera_for(preset: str, focus_m, working_arm: str = "right-arm", width: int = 640,
               height: int = 480) -> Camera:
    """The camera of a preset looking at ``focus_m`` (see the module docstring).

    Raises:
        InputError: unknown preset or bad image size.
    """
    if preset not in PRESETS:
        raise InputError(f"unknown camera preset {preset!r}",
                         hint=f"use one of {', '.join(PRESETS)}")
    if width < 16 or height < 16 or width % 2 or height % 2:
        raise InputError(f"image size {width} x {height} is not usable",
                         hint="give an even width and height of at least 16 pixels")
    offset, fov = PRESETS[preset]
    offset = np.array(offset)
    if working_arm == "left-arm":
        offset[1] = -offset[1]
    focus = np.asarray(focus_m, dtype=float)
    return Camera(tuple(focus + offset), tuple(focus), fov, int(width), int(height))
