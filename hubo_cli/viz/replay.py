"""Kinematic replay of a run in PyBullet: the logged joints and torso pose set each period.

Nothing is simulated: the robot (the URDF the run used, with the drill where it held one) is put
in each logged posture, with the walls as placed. Frames are rendered headless (the EGL plugin
where it loads, else PyBullet's TinyRenderer) or shown in the PyBullet window (``gui``), where
the goal and measured tool paths and the hole are drawn as lines.
"""

from __future__ import annotations

import contextlib
import os
import pkgutil
import sys
import time

import numpy as np

from hubo_cli.drivers.sim import FRAME_PARENTS, import_pybullet, quiet_native_output
from hubo_cli.errors import DeviceError, InputError, quoted
from hubo_cli.urdf import link_frames
from hubo_cli.viz.camera import Camera, body_bounds_m
from hubo_cli.viz.scene import RunScene

WALL_RGBA = (0.76, 0.6, 0.42, 1.0)
FLOOR_RGBA = (0.75, 0.78, 0.8, 1.0)
GOAL_RGB = (0.1, 0.7, 0.2)
ACTUAL_RGB = (0.85, 0.15, 0.1)
HOLE_RGB = (0.15, 0.1, 0.05)


def _pose(position, quat_xyzw) -> np.ndarray:
    x, y, z, w = quat_xyzw
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = position
    return T


def quat_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of rotation matrices (3 x 3 or N x 3 x 3), w >= 0."""
    R = np.asarray(R, dtype=float)
    single = R.ndim == 2
    R = R.reshape(-1, 3, 3)
    m00, m11, m22 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    # the four candidates' magnitudes; take the largest for accuracy (Shepperd's method)
    mags = np.stack([1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22,
                     1 + m00 + m11 + m22], axis=1)
    best = np.argmax(mags, axis=1)
    s = 2.0 * np.sqrt(np.maximum(mags[np.arange(len(R)), best], 1e-300))
    a = R[:, 2, 1] - R[:, 1, 2]
    b = R[:, 0, 2] - R[:, 2, 0]
    c = R[:, 1, 0] - R[:, 0, 1]
    xy, xz, yz = R[:, 0, 1] + R[:, 1, 0], R[:, 0, 2] + R[:, 2, 0], R[:, 1, 2] + R[:, 2, 1]
    q = np.empty((len(R), 4))
    for k, row in enumerate(([s / 4, xy / s, xz / s, a / s], [xy / s, s / 4, yz / s, b / s],
                             [xz / s, yz / s, s / 4, c / s], [a / s, b / s, c / s, s / 4])):
        pick = best == k
        q[pick] = np.stack(row, axis=1)[pick]
    q *= np.where(q[:, 3:4] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q[0] if single else q


class KinematicReplay:
    """A PyBullet world that shows one run's logged postures.

    Args:
        scene: the run (see :func:`hubo_cli.viz.scene.load_scene`).
        gui: open the PyBullet window instead of rendering headless.
    """

    def __init__(self, scene: RunScene, gui: bool = False) -> None:
        self.scene = scene
        self.gui = gui
        self._p = import_pybullet()
        self.egl = False
        self._renderer_chosen = False
        self._cid = -1
        self._connect()
        try:
            self._build()
        except Exception:
            self.close()
            raise

    # ------------------------------------------------------------------ set-up
    def _connect(self) -> None:
        p = self._p
        if self.gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            raise DeviceError("no display for the PyBullet window (DISPLAY is not set)",
                              hint="run without --gui (add --video FILE.mp4 to render one)")
        with quiet_native_output():
            self._cid = p.connect(p.GUI if self.gui else p.DIRECT)
        if self._cid < 0:
            raise DeviceError("could not open PyBullet", hint="run without --gui")
        if self.gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=self._cid)
        else:
            self.egl = self._load_egl()

    def _load_egl(self) -> bool:
        """Load PyBullet's EGL renderer plugin; False when it does not load (no EGL)."""
        loader = pkgutil.get_loader("eglRenderer")
        if loader is None:
            return False
        with quiet_native_output():
            plugin = self._p.loadPlugin(loader.get_filename(), "_eglRendererPlugin",
                                        physicsClientId=self._cid)
        return plugin >= 0

    def _build(self) -> None:
        p, cid, scene = self._p, self._cid, self.scene
        floor = p.createVisualShape(p.GEOM_BOX, halfExtents=[5, 5, 0.001],
                                    visualFramePosition=[0, 0, -0.001], rgbaColor=FLOOR_RGBA,
                                    physicsClientId=cid)
        p.createMultiBody(0, -1, floor, physicsClientId=cid)
        urdf = scene.model.urdf_path(scene.drill)
        flags = p.URDF_USE_INERTIA_FROM_FILE | p.URDF_MERGE_FIXED_LINKS
        with quiet_native_output():
            self._robot = p.loadURDF(str(urdf), flags=flags, physicsClientId=cid)
        joints, self._links = {}, {}
        for i in range(p.getNumJoints(self._robot, physicsClientId=cid)):
            info = p.getJointInfo(self._robot, i, physicsClientId=cid)
            joints[info[1].decode()] = i
            self._links[info[12].decode()] = i
        missing = [n for n in scene.log.joint_names if n not in joints]
        if missing:
            raise InputError(f"the URDF has no joint(s) {', '.join(missing)}",
                             hint="replay a run of the HUBO 2+ model")
        self._idx = [joints[n] for n in scene.log.joint_names]
        info = p.getDynamicsInfo(self._robot, -1, physicsClientId=cid)
        self._T_torso_com = _pose(info[3], info[4])  # PyBullet poses the base by its CoM
        self._T_link_frame = {child: origin for (_, kind, _, child, origin, _)
                              in link_frames(scene.model).joints
                              if kind == "fixed" and child in FRAME_PARENTS}
        for wall in scene.walls:
            half = [s / 2 for s in wall["size_m"]]
            w, x, y, z = wall["quat_wxyz"]
            shape = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=WALL_RGBA,
                                        physicsClientId=cid)
            p.createMultiBody(0, -1, shape, wall["centre_world_m"], [x, y, z, w],
                              physicsClientId=cid)
        self._q = self.scene.log.joints("q")
        self.k = -1

    # ------------------------------------------------------------------ replay
    def show(self, k: int) -> None:
        """Put the robot in period ``k``'s logged posture (joints and torso pose)."""
        p, cid = self._p, self._cid
        T_world_com = self.scene.T_world_torso[k] @ self._T_torso_com
        p.resetBasePositionAndOrientation(self._robot, T_world_com[:3, 3].tolist(),
                                          quat_xyzw(T_world_com[:3, :3]).tolist(),
                                          physicsClientId=cid)
        p.resetJointStatesMultiDof(self._robot, self._idx,
                                   [[float(v)] for v in self._q[k]], physicsClientId=cid)
        self.k = k

    def robot_bounds_m(self, periods) -> tuple[np.ndarray, np.ndarray]:
        """The world bounding box (lower, upper, m) of the robot's links over ``periods``
        (shown in turn; the robot is left in the last one's posture)."""
        boxes = []
        for k in periods:
            self.show(int(k))
            boxes.extend(body_bounds_m(self._p, self._robot, self._cid))
        corners = np.array(boxes)
        return corners.min(axis=0), corners.max(axis=0)

    def torso_pose(self) -> np.ndarray:
        """The replayed torso pose in the world (4x4, m), read back from PyBullet."""
        com, orn = self._p.getBasePositionAndOrientation(self._robot, physicsClientId=self._cid)
        return _pose(com, orn) @ np.linalg.inv(self._T_torso_com)

    def frame_pose(self, frame: str) -> np.ndarray:
        """World pose (4x4, m) of an end frame (``right_hand``, ``left_hand``, ``right_sole``,
        ``left_sole``, ``right_drill_bit`` with the drill) in the replayed posture."""
        if frame not in self._T_link_frame:
            raise InputError(f"unknown frame {quoted(frame)}",
                             hint=f"use {', '.join(sorted(self._T_link_frame))}")
        ls = self._p.getLinkState(self._robot, self._links[FRAME_PARENTS[frame]],
                                  computeForwardKinematics=1, physicsClientId=self._cid)
        return _pose(ls[4], ls[5]) @ self._T_link_frame[frame]

    def _grab(self, camera: Camera, renderer: int) -> np.ndarray:
        p = self._p
        view, proj = camera.gl_matrices()
        _, _, rgba, _, _ = p.getCameraImage(camera.width, camera.height, view, proj,
                                            renderer=renderer, shadow=0,
                                            flags=p.ER_NO_SEGMENTATION_MASK,
                                            physicsClientId=self._cid)
        image = np.reshape(np.asarray(rgba, dtype=np.uint8),
                           (camera.height, camera.width, 4))
        return np.ascontiguousarray(image[:, :, :3])

    def _choose_renderer(self, camera: Camera) -> None:
        """With EGL loaded, keep it only if it renders this camera faster than TinyRenderer
        (without a GPU, EGL runs on a software rasteriser that can be slower)."""
        p = self._p
        times = {}
        with quiet_native_output():  # Mesa names itself on the first EGL frame
            for renderer in (p.ER_BULLET_HARDWARE_OPENGL, p.ER_TINY_RENDERER) * 2:
                started = time.perf_counter()
                self._grab(camera, renderer)
                times[renderer] = time.perf_counter() - started
        self.egl = times[p.ER_BULLET_HARDWARE_OPENGL] < times[p.ER_TINY_RENDERER]

    def render(self, camera: Camera) -> np.ndarray:
        """The scene from ``camera`` (H x W x 3 uint8 RGB)."""
        p = self._p
        if self.egl and not self._renderer_chosen:
            self._choose_renderer(camera)
        self._renderer_chosen = True
        return self._grab(camera, p.ER_BULLET_HARDWARE_OPENGL if self.egl else p.ER_TINY_RENDERER)

    # ------------------------------------------------------------------ window
    def draw_paths(self) -> None:
        """Draw the goal and measured tool paths and the hole (on the wall's face, where it is seen)
        as lines (PyBullet window)."""
        scene = self.scene
        for points, rgb, width in ((scene.goal_world_m, GOAL_RGB, 2),
                                   (scene.tool_world_m, ACTUAL_RGB, 2),
                                   (scene.hole_on_face_world_m(), HOLE_RGB, 4)):
            finite = points[np.all(np.isfinite(points), axis=1)][::5]
            for a, b in zip(finite[:-1], finite[1:], strict=True):
                if np.linalg.norm(b - a) > 1e-4:
                    self._p.addUserDebugLine(a.tolist(), b.tolist(), rgb, width,
                                             physicsClientId=self._cid)

    def play(self, speed: float = 1.0, camera: Camera | None = None) -> int:
        """Show the run in the window at ``speed`` times real time; returns periods shown."""
        p, cid = self._p, self._cid
        if camera is not None:
            eye, target = np.asarray(camera.eye_m), np.asarray(camera.target_m)
            d = eye - target
            yaw = float(np.degrees(np.arctan2(d[1], d[0]))) + 90.0
            pitch = float(-np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1]))))
            p.resetDebugVisualizerCamera(float(np.linalg.norm(d)), yaw, pitch,
                                         target.tolist(), physicsClientId=cid)
        self.draw_paths()
        t_s = self.scene.t_s
        start = time.perf_counter()
        shown = 0
        for k in range(len(self.scene)):
            wait = start + (t_s[k] - t_s[0]) / speed - time.perf_counter()
            if wait < 0 and k + 1 < len(self.scene):
                continue  # behind: skip this period
            if wait > 0:
                time.sleep(wait)
            self.show(k)
            shown += 1
        return shown

    def close(self) -> None:
        """Disconnect from PyBullet; safe to call twice."""
        if self._cid >= 0:
            with contextlib.suppress(Exception), quiet_native_output():
                self._p.disconnect(physicsClientId=self._cid)
            self._cid = -1

    def __enter__(self) -> KinematicReplay:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
