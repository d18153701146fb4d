"""Cameras as sensors: webcams and stereo rigs, rendered offscreen.

Cameras render offscreen with ``mujoco.Renderer``; headless machines need ``MUJOCO_GL=egl`` (Mesa's
libEGL) or ``osmesa`` set before mujoco is imported (``scripts/install_gl.sh`` installs the Debian
packages). A camera that cannot get an OpenGL context raises :class:`~simrun.errors.SimrunError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError, SimrunError
from simrun.sensors.base import Sensor
from simrun.sensors.mount import camera_mount
from simrun.world.entity import BuildContext, Entity, check_positive

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World


#: Which image side a :class:`StereoRig`'s ``fov`` spans.


FOV_AXES = ("horizontal", "vertical")


@dataclass(kw_only=True)
class StereoRig(Entity):
    """Two cameras ``NAME/left`` and ``NAME/right`` a ``baseline`` apart along Y, looking along +X.

    They ride on ``body`` (a robot's body by its full name) or, as a child of a robot, on its root body, as a
    :class:`~simrun.entities.environment.Camera` does (:func:`simrun.sensors.mount.camera_mount`).

    The defaults are the seed's stereo camera: two 320 x 240 images, a 30-degree field of view across the
    image's width (horizontal), 0.10 m between the eyes.

    Attributes:
        baseline: Distance between the two cameras' centres, metres (along the body's Y; left at +Y).
        fov: Field of view, degrees, across the image side ``fov_axis`` names.
        fov_axis: ``horizontal`` (across the width, the seed's meaning) or ``vertical`` (across the height,
            MuJoCo's ``fovy``).
        resolution: (width, height), pixels.
        body: The body the rig rides on, by its full name (``NAME/link``); ``None``: its parent robot's root
            body, or its own.
    """

    TYPE: ClassVar[str] = "StereoRig"
    baseline: float = 0.10
    fov: float = 30.0
    fov_axis: str = "horizontal"
    resolution: tuple[int, int] = (320, 240)
    body: str | None = None

    def fovy(self) -> float:
        """The vertical field of view MuJoCo's cameras get, degrees (square pixels)."""
        width, height = self.resolution
        if self.fov_axis == "vertical":
            return self.fov
        return math.degrees(2 * math.atan(math.tan(math.radians(self.fov) / 2) * height / width))

    def focal_length(self) -> float:
        """Focal length in pixels (the same across and up the image: square pixels)."""
        return self.resolution[1] / 2 / math.tan(math.radians(self.fovy()) / 2)

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Two cameras; MuJoCo cameras look along their -Z, so each is turned to look along the body's +X."""
        check_positive(self, baseline=self.baseline, fov=self.fov, width=self.resolution[0], height=self.resolution[1])
        if self.fov_axis not in FOV_AXES:
            raise EntityError(f"{self.TYPE} {self.name!r}: fov_axis must be one of {', '.join(FOV_AXES)}")
        if not self.fov < 180.0:
            raise EntityError(f"{self.TYPE} {self.name!r}: fov must be below 180 degrees, got {self.fov}")
        look_x = (0.5, 0.5, -0.5, -0.5)  # camera -Z -> body +X, camera +Y -> body +Z
        pose = self.body_pose()
        mount, place = camera_mount(
            ctx.spec, body, ctx.full_name, self.parent, self.body, (pose.position, pose.orientation)
        )
        for side, sign in (("left", 1.0), ("right", -1.0)):
            pos, quat = place((0.0, sign * self.baseline / 2, 0.0), look_x)
            mount.add_camera(
                name=ctx.name(side),
                pos=pos,
                quat=quat,
                fovy=self.fovy(),
                resolution=list(self.resolution),
            )


def _camera_body(model: mujoco.MjModel, camera: str) -> str:
    """The full name of the body a camera of the model is in.

    Raises:
        EntityError: No camera of that name.
    """
    found = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    if found < 0:
        raise EntityError(f"no camera named {camera!r} in the model", key="camera")
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.cam_bodyid[found])) or ""


@dataclass(frozen=True, slots=True)
class Frame:
    """One rendered image: RGB (H, W, 3) u8 and, when asked, depth (H, W) metres."""

    time: float
    rgb: npt.NDArray[np.uint8]
    depth: npt.NDArray[np.float32] | None


class _Eye:
    """An offscreen renderer for one camera (created on first use, recreated when the model changes)."""

    def __init__(self, camera: str, width: int, height: int, depth: bool) -> None:
        self.camera, self.width, self.height, self.depth = camera, width, height, depth
        self._renderer: Any = None
        self._bound: mujoco.MjModel | None = None  # the model the cached ids are for (held: a freed id is reused)

    def render(self, model: mujoco.MjModel, data: mujoco.MjData) -> Frame:
        if self._renderer is None or self._bound is not model:
            try:
                self._renderer = mujoco.Renderer(model, self.height, self.width)
            except Exception as exc:  # any GL failure: say how to get a context
                raise SimrunError(
                    f"no OpenGL context for camera {self.camera!r} ({exc}); on a headless machine install Mesa "
                    "(scripts/install_gl.sh) and set MUJOCO_GL=egl or osmesa before importing mujoco"
                ) from None
            self._bound = model
        renderer = self._renderer
        renderer.update_scene(data, camera=self.camera)
        rgb = renderer.render().copy()
        depth = None
        if self.depth:
            renderer.enable_depth_rendering()
            renderer.update_scene(data, camera=self.camera)
            depth = renderer.render().copy()
            renderer.disable_depth_rendering()
        return Frame(float(data.time), rgb, depth)


class Webcam(Sensor):
    """Offscreen RGB (and optional depth) from a named MuJoCo camera.

    Args:
        world: The world.
        camera: Camera name (a ``Camera`` entity's full name, or ``RIG/left``).
        width: Pixels.
        height: Pixels.
        depth: Also render depth.
        rate: Hz (0: every step).
    """

    def __init__(
        self, world: World, camera: str, width: int = 320, height: int = 240, depth: bool = False, rate: float = 15.0
    ) -> None:
        entity = camera if camera in dict(world) else camera.rsplit("/", 1)[0]
        super().__init__(world, entity, rate)
        self.eye = _Eye(camera, width, height, depth)

    @property
    def mount(self) -> str:
        """Full name of the body the camera rides on (where its ``Camera``'s ``body`` put it)."""
        return _camera_body(self.world.model, self.eye.camera)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> Frame:
        """Render the camera's view."""
        return self.eye.render(model, data)


@dataclass(frozen=True, slots=True)
class StereoFrame:
    """Left and right frames taken at the same simulation time."""

    time: float
    left: Frame
    right: Frame


class StereoCamera(Sensor):
    """Both cameras of a :class:`StereoRig`, rendered together.

    Args:
        world: The world.
        rig: Full name of the :class:`StereoRig` (its resolution is the images').
        depth: Also render depth.
        rate: Hz (0: every step).
    """

    def __init__(self, world: World, rig: str, depth: bool = False, rate: float = 15.0) -> None:
        entity = world.entity(rig)
        if not isinstance(entity, StereoRig):
            raise EntityError(f"{rig!r} is not a StereoRig")
        super().__init__(world, rig, rate)
        width, height = entity.resolution
        self.left = _Eye(f"{rig}/left", width, height, depth)
        self.right = _Eye(f"{rig}/right", width, height, depth)

    @property
    def mount(self) -> str:
        """Full name of the body the rig's cameras ride on (its ``body``, a robot's root, or its own)."""
        return _camera_body(self.world.model, self.left.camera)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> StereoFrame:
        """Render both eyes."""
        return StereoFrame(float(data.time), self.left.render(model, data), self.right.render(model, data))
