"""Environment entities: Ground, HeightField, Sky, Light, Camera."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.sensors.mount import camera_mount
from simrun.world.assets import open_image, read_image_file
from simrun.world.entity import BuildContext, Entity, Material, check_positive
from simrun.world.pose import Pose


@dataclass(kw_only=True)
class Ground(Entity):
    """An infinite-looking plane at the entity's pose (size only affects rendering).

    Attributes:
        size: Rendered half extent, metres.
        texture: A PNG file; default a grey checker.
        material: Contact material.
    """

    TYPE: ClassVar[str] = "Ground"
    size: float = 10.0
    texture: str | None = None
    material: Material | None = None

    def build(self, body: Any, ctx: BuildContext) -> None:
        """One plane geom."""
        check_positive(self, size=self.size)
        geom = body.add_geom(name=ctx.name("plane"), type=mujoco.mjtGeom.mjGEOM_PLANE, size=[self.size, self.size, 0.1])
        if self.texture:
            geom.material = ctx.assets.texture_material(self.texture, ctx.base_dir)
        else:
            tex = ctx.spec.add_texture(
                name=ctx.name("checker"),
                type=mujoco.mjtTexture.mjTEXTURE_2D,
                builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                width=256,
                height=256,
                rgb1=[0.35, 0.35, 0.38],
                rgb2=[0.5, 0.5, 0.53],
            )
            mat = ctx.spec.add_material(name=ctx.name("material"), texrepeat=[self.size, self.size], texuniform=True)
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
            geom.material = mat.name
        if self.material is not None:
            self.material.apply(geom)


@dataclass(kw_only=True)
class HeightField(Entity):
    """Terrain from a height array (rows along y, columns along x) or a grayscale image.

    Attributes:
        heights: Rows of heights in 0..1 (scaled by ``size[2]``), or ``None`` when ``image`` is given.
        image: A grayscale PNG (relative to the scene folder); black 0, white 1.
        size: (x half-extent, y half-extent, top height, base depth), metres.
    """

    TYPE: ClassVar[str] = "HeightField"
    heights: list[list[float]] | None = None
    image: str | None = None
    size: tuple[float, float, float, float] = (5.0, 5.0, 1.0, 0.1)

    def build(self, body: Any, ctx: BuildContext) -> None:
        """One hfield asset and its geom."""
        if (self.heights is None) == (self.image is None):
            raise EntityError(f"HeightField {self.name!r}: give exactly one of heights and image")
        if self.heights is not None:
            rows = [len(row) for row in self.heights]
            if len(set(rows)) > 1:
                raise EntityError(f"HeightField {self.name!r}: rows must be equally long, got lengths {rows}")
            grid = np.asarray(self.heights, dtype=np.float64)
        else:
            data = read_image_file(ctx.base_dir / str(self.image), str(self.image))
            image = open_image(data, f"height-field image {self.image!r}")
            grid = np.asarray(image.convert("L"), dtype=np.float64)[::-1] / 255.0
        if grid.ndim != 2 or min(grid.shape) < 2 or not np.isfinite(grid).all():
            raise EntityError(f"HeightField {self.name!r}: heights must be a finite 2D grid of at least 2x2")
        check_positive(self, **{f"size[{k}]": v for k, v in enumerate(self.size)})
        lo, hi = grid.min(), grid.max()
        normalised = (grid - lo) / (hi - lo) if hi > lo else np.zeros_like(grid)
        ctx.spec.add_hfield(
            name=ctx.name("hfield"),
            nrow=grid.shape[0],
            ncol=grid.shape[1],
            size=list(self.size),
            userdata=normalised.ravel().tolist(),
        )
        body.add_geom(name=ctx.name("geom"), type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=ctx.name("hfield"))


@dataclass(kw_only=True)
class Sky(Entity):
    """The skybox: a vertical gradient from ``top`` to ``bottom`` colour, or a PNG.

    Attributes:
        top: RGB 0..1 at the zenith.
        bottom: RGB 0..1 at the nadir.
        texture: A PNG (relative to the scene folder) instead of the gradient.
    """

    TYPE: ClassVar[str] = "Sky"
    HAS_BODY: ClassVar[bool] = False
    top: tuple[float, float, float] = (0.4, 0.6, 0.8)
    bottom: tuple[float, float, float] = (0.0, 0.0, 0.0)
    texture: str | None = None

    def build(self, body: Any, ctx: BuildContext) -> None:
        """A skybox texture."""
        kind = mujoco.mjtTexture.mjTEXTURE_SKYBOX
        if self.texture:
            png = ctx.assets.read_image((ctx.base_dir / self.texture).resolve(), self.texture)
            ctx.assets.add_texture(ctx.full_name, png, kind)
        else:
            ctx.spec.add_texture(
                name=ctx.full_name,
                type=kind,
                builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                width=256,
                height=256,
                rgb1=list(self.top),
                rgb2=list(self.bottom),
            )


LIGHT_KINDS = {
    "directional": mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
    "spot": mujoco.mjtLightType.mjLIGHT_SPOT,
    "point": mujoco.mjtLightType.mjLIGHT_POINT,
}


@dataclass(kw_only=True)
class Light(Entity):
    """A light at the entity's pose, shining along ``direction`` (in the entity frame).

    Attributes:
        kind: ``directional``, ``spot`` or ``point``.
        direction: Unit-ish vector.
        diffuse: RGB.
        cast_shadow: Whether it casts shadows.
    """

    TYPE: ClassVar[str] = "Light"
    kind: str = "directional"
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    diffuse: tuple[float, float, float] = (0.8, 0.8, 0.8)
    cast_shadow: bool = True

    def build(self, body: Any, ctx: BuildContext) -> None:
        """One light."""
        if self.kind not in LIGHT_KINDS:
            raise EntityError(f"Light {self.name!r}: kind must be one of {', '.join(LIGHT_KINDS)}")
        light = body.add_light(
            name=ctx.name("light"),
            type=LIGHT_KINDS[self.kind],
            dir=list(self.direction),
            diffuse=list(self.diffuse),
            castshadow=self.cast_shadow,
        )
        light.pos = [0.0, 0.0, 0.0]


@dataclass(kw_only=True)
class Camera(Entity):
    """A camera at the entity's pose (MuJoCo cameras look along their -Z), or at ``eye`` looking at ``target``.

    Where it rides (:func:`simrun.sensors.mount.camera_mount`): on ``body`` (a robot's body by its full name,
    ``NAME/link``) when given, else, as a child of a robot (``parent``), on that robot's root body (the body that
    moves: a free-base walker's trunk, not the marker left at its spawn point), else on its own body. Its
    MuJoCo camera is put into that body of the spec, so MuJoCo moves it; the pose (or ``eye`` and ``target``)
    is then in that body's frame. The robot must be inserted before the camera.

    Attributes:
        fovy: Vertical field of view, degrees.
        resolution: (width, height) pixels.
        eye: Position to look from (overrides the pose).
        target: Point to look at.
        main: Use this camera as the main view (the default rendering camera).
        body: The body it rides on, by its full name (``NAME/link``); ``None``: see above.
    """

    TYPE: ClassVar[str] = "Camera"
    fovy: float = 45.0
    resolution: tuple[int, int] = (640, 480)
    eye: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    main: bool = False
    body: str | None = None

    def body_pose(self) -> Pose:
        """The pose, from eye/target when given."""
        if self.eye is not None and self.target is not None:
            return Pose.look_at(self.eye, self.target)
        return self.pose

    def build(self, body: Any, ctx: BuildContext) -> None:
        """One camera, in the body it rides on."""
        check_positive(self, fovy=self.fovy, width=self.resolution[0], height=self.resolution[1])
        pose = self.body_pose()
        mount, place = camera_mount(
            ctx.spec, body, ctx.full_name, self.parent, self.body, (pose.position, pose.orientation)
        )
        pos, quat = place((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
        mount.add_camera(name=ctx.full_name, pos=pos, quat=quat, fovy=self.fovy, resolution=list(self.resolution))
