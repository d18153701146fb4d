"""Single-shape entities: Box, Sphere, Capsule, Cylinder (MSRS's single-shape entities)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco

from simrun.errors import EntityError
from simrun.world.entity import BuildContext, Entity, Material, check_positive


@dataclass(kw_only=True)
class Shape(Entity):
    """Common shape parameters.

    Attributes:
        mass: Total mass, kg (takes precedence over density).
        density: kg/m^3 when no mass is given.
        color: RGBA 0..1.
        texture: A PNG file (relative to the scene/world folder) mapped onto the shape.
        material: Contact material (friction, restitution).
    """

    GEOM: ClassVar[int] = mujoco.mjtGeom.mjGEOM_BOX
    BATCHABLE: ClassVar[bool] = True  # build: one geom of its body, a texture material of ctx.assets

    mass: float | None = None
    density: float = 1000.0
    color: tuple[float, float, float, float] = (0.7, 0.7, 0.7, 1.0)
    texture: str | None = None
    material: Material | None = None

    def size(self) -> list[float]:
        """MuJoCo ``size`` of the geom."""
        raise EntityError(f"{self.TYPE} has no size")  # overridden by every concrete shape

    def build(self, body: Any, ctx: BuildContext) -> None:
        """One geom of this shape, with mass or density, colour or texture, and contact material."""
        check_positive(self, mass=self.mass, density=self.density)
        if len(self.color) != 4:
            raise EntityError(f"{self.TYPE} {self.name!r}: color needs 4 numbers (RGBA)")
        geom = body.add_geom(name=ctx.name("geom"), type=self.GEOM, size=self.size(), rgba=list(self.color))
        if self.mass is not None:
            geom.mass = self.mass
        else:
            geom.density = self.density
        if self.texture is not None:
            geom.material = ctx.assets.texture_material(self.texture, ctx.base_dir)
            geom.rgba = [1.0, 1.0, 1.0, self.color[3]]
        if self.material is not None:
            self.material.apply(geom)


@dataclass(kw_only=True)
class Box(Shape):
    """A box. ``dimensions`` are the full side lengths (x, y, z) in metres."""

    TYPE: ClassVar[str] = "Box"
    GEOM: ClassVar[int] = mujoco.mjtGeom.mjGEOM_BOX
    dimensions: tuple[float, float, float] = (0.1, 0.1, 0.1)

    def size(self) -> list[float]:
        """Half extents."""
        if len(self.dimensions) != 3:
            raise EntityError(f"Box {self.name!r}: dimensions need 3 numbers")
        check_positive(self, **{f"dimensions[{k}]": v for k, v in enumerate(self.dimensions)})
        return [v / 2 for v in self.dimensions]


@dataclass(kw_only=True)
class Sphere(Shape):
    """A sphere of ``radius`` metres."""

    TYPE: ClassVar[str] = "Sphere"
    GEOM: ClassVar[int] = mujoco.mjtGeom.mjGEOM_SPHERE
    radius: float = 0.05

    def size(self) -> list[float]:
        """Radius."""
        check_positive(self, radius=self.radius)
        return [self.radius, 0.0, 0.0]


@dataclass(kw_only=True)
class _Rod(Shape):
    """A round shape along its local Z: ``radius`` and ``length`` (without caps), metres."""

    radius: float = 0.05
    length: float = 0.1

    def size(self) -> list[float]:
        """Radius and half length."""
        check_positive(self, radius=self.radius, length=self.length)
        return [self.radius, self.length / 2, 0.0]


@dataclass(kw_only=True)
class Capsule(_Rod):
    """A capsule along its local Z: ``radius`` and cylinder ``length`` (without the caps), metres."""

    TYPE: ClassVar[str] = "Capsule"
    GEOM: ClassVar[int] = mujoco.mjtGeom.mjGEOM_CAPSULE


@dataclass(kw_only=True)
class Cylinder(_Rod):
    """A cylinder along its local Z: ``radius`` and ``length``, metres."""

    TYPE: ClassVar[str] = "Cylinder"
    GEOM: ClassVar[int] = mujoco.mjtGeom.mjGEOM_CYLINDER
