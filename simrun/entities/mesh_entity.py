"""MeshEntity: a packed ``.mbin`` asset in the world, visual and collision geometry from memory."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, ClassVar

import mujoco

from simrun.errors import EntityError
from simrun.world.entity import BuildContext, Entity, Material, check_positive

COLLISION = ("hulls", "convex", "none")
MESH = mujoco.mjtGeom.mjGEOM_MESH
#: Largest uniform scale accepted (and smallest: its inverse).
MAX_SCALE = 1e6


@lru_cache(maxsize=65536)
def _joined(base_dir: Path, name: str) -> Path:
    """``base_dir / name``, one ``Path`` object per pair.

    The thousands of entities naming one file share it, and with it the hash the asset library's per-path
    tables (resolution, added meshes) look it up by.
    """
    return base_dir / name


@dataclass(kw_only=True)
class MeshEntity(Entity):
    """A mesh asset.

    Attributes:
        asset: A name from the world's ``assets`` table, or a path of an ``.mbin`` (relative to the world folder).
        scale: Uniform scale.
        collision: ``hulls`` (the stored collision hulls; the default), ``convex`` (MuJoCo's hull of the whole
            mesh) or ``none`` (visual only).
        mass: Total mass in kg, split over the collision geoms by volume; else ``density``.
        density: kg/m^3.
        material: Contact material of the collision geoms.
    """

    TYPE: ClassVar[str] = "MeshEntity"
    BATCHABLE: ClassVar[bool] = True  # build: geoms of its body, meshes of ctx.assets

    asset: str
    scale: float = 1.0
    collision: str = "hulls"
    mass: float | None = None
    density: float = 1000.0
    material: Material | None = None

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Visual geoms per submesh (group 2, massless) and collision geoms (group 3)."""
        check_positive(self, scale=self.scale, mass=self.mass, density=self.density)
        if not 1 / MAX_SCALE <= self.scale <= MAX_SCALE:
            raise EntityError(f"MeshEntity {self.name!r}: scale must be in [{1 / MAX_SCALE:g}, {MAX_SCALE:g}]")
        if self.collision not in COLLISION:
            raise EntityError(f"MeshEntity {self.name!r}: collision must be one of {', '.join(COLLISION)}")
        path = _joined(ctx.base_dir, ctx.asset_paths.get(self.asset, self.asset))
        asset = ctx.assets.mesh(path, self.scale)
        prefix = ctx.full_name
        for k, (mesh, material) in enumerate(asset.visual):
            # attributes set one by one: add_geom's keyword arguments cost the bindings twice as much (issue 41)
            geom = body.add_geom()
            geom.name, geom.type, geom.meshname = f"{prefix}/visual{k}", MESH, mesh
            geom.group, geom.contype, geom.conaffinity, geom.density = 2, 0, 0, 0.0
            if material:
                geom.material = material
        if self.collision == "none":
            return
        if self.collision == "hulls" and not asset.hulls:
            raise EntityError(
                f"MeshEntity {self.name!r}: {self.asset} has no collision hulls "
                "(convert it with obj2bin --hulls convex|decompose, or use collision='convex')"
            )
        meshes = asset.hulls if self.collision == "hulls" else [ctx.assets.whole(path, self.scale)]
        # the hulls' volumes only where a mass is split by them (computing them was a fifth of a distinct file's
        # build, issue 41)
        volumes = (asset.hull_volumes if self.collision == "hulls" else [1.0]) if self.mass is not None else []
        for k, mesh in enumerate(meshes):
            geom = body.add_geom()
            geom.name, geom.type, geom.meshname, geom.group = f"{prefix}/collision{k}", MESH, mesh, 3
            if self.mass is not None:
                geom.mass = self.mass * volumes[k] / sum(volumes)
            else:
                geom.density = self.density
            if self.material is not None:
                self.material.apply(geom)
