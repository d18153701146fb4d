"""Offscreen rendering in MSRS's five modes, with settings fast enough for CPU (Mesa) rendering.

| mode | what is drawn |
|---|---|
| ``visual`` | visual geoms (groups 0-2), textures, shadows off for speed |
| ``wireframe`` | the same as wireframe |
| ``physics`` | collision geoms (groups 0, 1, 3), contact points and contact forces |
| ``combined`` | both, visual geoms transparent |
| ``none`` | nothing: no GL context is created |

The OpenGL backend is chosen when simrun is imported (:mod:`simrun.run.headless`: EGL, then OSMesa, on a
machine without a display); a machine without one gets one error line naming the packages to install.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import SimrunError
from simrun.run.headless import INSTALL_HINT, gl_choice

MODES = ("visual", "wireframe", "physics", "combined", "none")


def scene_option(mode: str) -> mujoco.MjvOption:
    """The MuJoCo visualisation options of a render mode."""
    if mode not in MODES:
        raise SimrunError(f"unknown render mode {mode!r} (use one of {', '.join(MODES)})")
    option = mujoco.MjvOption()
    groups = {"visual": (0, 1, 2), "wireframe": (0, 1, 2), "physics": (0, 1, 3), "combined": (0, 1, 2, 3)}
    option.geomgroup[:] = [1 if g in groups.get(mode, ()) else 0 for g in range(6)]
    if mode in ("physics", "combined"):
        option.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = True
        option.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = True
    if mode == "combined":
        option.flags[mujoco.mjtVisFlag.mjVIS_TRANSPARENT] = True
    return option


def open_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A ``mujoco.Renderer`` of ``width`` x ``height`` pixels, or one error line saying how to get OpenGL.

    Raises:
        SimrunError: No usable OpenGL backend (:func:`simrun.run.headless.gl_choice`), or the context failed.
    """
    choice = gl_choice()
    if choice.problem is not None:
        raise SimrunError(f"cannot render: {choice.problem}")
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as exc:  # any GL failure (MuJoCo, PyOpenGL, the driver): one line with the fix
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise SimrunError(
            f"cannot render: no OpenGL context with MUJOCO_GL={choice.backend} ({detail[:200]}); {INSTALL_HINT}"
        ) from None


@dataclass
class Camera:
    """A free camera looking at ``lookat`` (used when the scene names no camera)."""

    lookat: tuple[float, float, float] = (0.0, 0.0, 0.2)
    distance: float = 3.0
    azimuth: float = 135.0
    elevation: float = -25.0


#: ``--camera follow:ENTITY``: a camera that follows the entity (:func:`follow_camera`).
FOLLOW = "follow:"


def follow_camera(model: mujoco.MjModel, data: mujoco.MjData | None, entity: str) -> mujoco.MjvCamera:
    """A camera that follows ``entity``'s body: MuJoCo's tracking camera, looking at its subtree's centre of mass.

    It keeps the direction of the scene's main camera (azimuth and elevation of its view axis) and its
    distance to the entity at the start, so the first frame looks as the main view does with the entity in
    the middle; without a main camera it looks down 25 degrees from 1.2 m (a table-top robot's framing).

    Raises:
        SimrunError: No body is named ``entity``.
    """
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, entity)
    if body <= 0:
        bodies = [model.body(k).name for k in range(1, model.nbody) if "/" not in model.body(k).name]
        raise SimrunError(f"{FOLLOW}{entity}: no entity named {entity!r} (entities: {', '.join(bodies) or 'none'})")
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    cam.trackbodyid = body
    cam.distance, cam.azimuth, cam.elevation = 1.2, 90.0, -25.0
    main = int(model.vis.global_.cameraid)
    if data is not None and 0 <= main < model.ncam:
        start = mujoco.MjData(model)  # the start's poses, computed aside: the simulated data is never touched
        start.qpos[:], start.mocap_pos[:], start.mocap_quat[:] = data.qpos, data.mocap_pos, data.mocap_quat
        mujoco.mj_kinematics(model, start)
        mujoco.mj_comPos(model, start)
        mujoco.mj_camlight(model, start)
        forward = -np.asarray(start.cam_xmat[main]).reshape(3, 3)[:, 2]  # MuJoCo cameras look along -Z
        cam.azimuth = float(np.degrees(np.arctan2(forward[1], forward[0])))
        cam.elevation = float(np.degrees(np.arcsin(np.clip(forward[2], -1.0, 1.0))))
        cam.distance = float(np.linalg.norm(start.cam_xpos[main] - start.subtree_com[body]))
    return cam


class FrameRenderer:
    """Renders frames of a model in one mode from a named camera, the main view, or a free camera.

    Args:
        model: The compiled model.
        width: Pixels.
        height: Pixels.
        mode: One of :data:`MODES` (``none`` cannot render).
        camera: A camera name; ``follow:ENTITY`` a camera following that entity (:func:`follow_camera`);
            ``None`` uses the model's main view (``vis.global.cameraid``) or a free camera.
        data: With a free camera, frame the bodies' current positions; with ``follow:``, the start's poses.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int = 320,
        height: int = 240,
        mode: str = "visual",
        camera: str | None = None,
        data: mujoco.MjData | None = None,
    ) -> None:
        if mode == "none":
            raise SimrunError("render mode 'none' draws nothing")
        follow = camera[len(FOLLOW) :] if camera is not None and camera.startswith(FOLLOW) else None
        if camera is not None and follow is None:
            names = [model.camera(k).name for k in range(model.ncam)]
            if camera not in names:
                raise SimrunError(
                    f"no camera named {camera!r} (cameras: {', '.join(names) or 'none'}; "
                    f"{FOLLOW}ENTITY follows an entity)"
                )
        self.model, self.mode, self.option = model, mode, scene_option(mode)
        model.vis.quality.offsamples = 0  # no multisampling: CPU rendering stays fast
        model.vis.quality.shadowsize = 1024
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self.renderer = open_renderer(model, width, height)
        if mode == "wireframe":
            self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_WIREFRAME] = True
        if mode in ("physics", "combined"):
            model.vis.scale.contactwidth, model.vis.scale.contactheight = 0.05, 0.01
            model.vis.scale.forcewidth, model.vis.map.force = 0.02, 0.05
        self.camera: Any
        if follow is not None:
            self.camera = follow_camera(model, data, follow)
        elif camera is not None:
            self.camera = camera
        elif model.vis.global_.cameraid >= 0:
            self.camera = int(model.vis.global_.cameraid)
        else:
            free = mujoco.MjvCamera()
            view = Camera()
            if data is not None and model.nbody > 1:
                points = np.asarray(data.xpos[1:])
                centre = points.mean(axis=0)
                spread = float(np.linalg.norm(points - centre, axis=1).max())
                view = Camera((float(centre[0]), float(centre[1]), float(centre[2])), max(1.0, 2.5 * spread))
            free.lookat[:], free.distance = view.lookat, view.distance
            free.azimuth, free.elevation = view.azimuth, view.elevation
            self.camera = free

    def render(self, data: mujoco.MjData) -> npt.NDArray[np.uint8]:
        """One RGB frame (H, W, 3)."""
        self.renderer.update_scene(data, camera=self.camera, scene_option=self.option)
        if self.mode == "wireframe":
            self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_WIREFRAME] = True
        frame: npt.NDArray[np.uint8] = self.renderer.render().copy()
        return frame

    def close(self) -> None:
        """Release the GL context."""
        self.renderer.close()
