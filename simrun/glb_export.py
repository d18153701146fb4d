"""GLB export of a whole world, for web viewers: every geom at its initial world pose, via trimesh.

glTF is Y-up, so one rotation (-90 degrees about X) maps the world's Z-up frame onto it; units stay
metres. Each geom becomes a node named like the geom (``robot/chassis``) with a PBR material of its
colour; primitives are tessellated (spheres and capsules as subdivision-3 icospheres, cylinders with 32
segments), planes as a 1 mm thick box of their drawn size. Textures are not carried (colours only).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import trimesh

from meshtool.packfile.export import Z_UP_TO_Y_UP
from simrun.compiled_mesh import compiled_mesh
from simrun.errors import SimrunError
from simrun.outfile import stamp_glb, write_bytes
from simrun.world import World


def world_to_glb(world: World) -> bytes:
    """The world's geoms, posed by ``mj_forward`` at the initial state, as GLB bytes."""
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = trimesh.Scene()
    for g in range(model.ngeom):
        mesh = _geom_mesh(model, g)
        if mesh is None:
            continue
        rgba = np.clip(np.asarray(model.geom_rgba[g], dtype=float), 0.0, 1.0)
        mesh.visual = trimesh.visual.TextureVisuals(  # type: ignore[no-untyped-call]
            material=trimesh.visual.material.PBRMaterial(  # type: ignore[no-untyped-call]
                name=f"rgba_{g}", baseColorFactor=rgba.tolist(), metallicFactor=0.0, roughnessFactor=1.0
            )
        )
        pose = np.eye(4)
        pose[:3, :3] = np.asarray(data.geom_xmat[g], dtype=float).reshape(3, 3)
        pose[:3, 3] = data.geom_xpos[g]
        name = model.geom(g).name or f"geom{g}"
        scene.add_geometry(mesh, node_name=name, geom_name=name, transform=Z_UP_TO_Y_UP @ pose)
    if not scene.geometry:
        raise SimrunError("the world has no geoms to export")
    out: bytes = scene.export(file_type="glb", tree_postprocessor=stamp_glb)  # type: ignore[no-untyped-call]
    return out


def export_world_glb(world: World, out: Path) -> None:
    """Write :func:`world_to_glb` atomically to ``out`` (must end in ``.glb``)."""
    if out.suffix.lower() != ".glb":
        raise SimrunError(f"{out}: GLB output must end in .glb")
    write_bytes(out, world_to_glb(world))


def _geom_mesh(model: mujoco.MjModel, g: int) -> trimesh.Trimesh | None:
    kind, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=float)
    mesh: trimesh.Trimesh
    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == int(mujoco.mjtGeom.mjGEOM_PLANE):
        half = [s if s > 0 else 50.0 for s in size[:2]]
        mesh = trimesh.creation.box(extents=[2 * half[0], 2 * half[1], 0.001])
    elif kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=float(size[0]))
    elif kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
        mesh = trimesh.creation.capsule(height=float(2 * size[1]), radius=float(size[0]), count=[16, 16])
    elif kind == int(mujoco.mjtGeom.mjGEOM_CYLINDER):
        mesh = trimesh.creation.cylinder(radius=float(size[0]), height=float(2 * size[1]), sections=32)
    elif kind == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        mesh.apply_scale(size)  # type: ignore[no-untyped-call]
    elif kind == int(mujoco.mjtGeom.mjGEOM_MESH):
        vertices, faces = compiled_mesh(model, int(model.geom_dataid[g]))
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    else:
        return None  # height fields and SDF plugins are not exported
    return mesh
