"""GLB export of a whole world, for web viewers: every visible geom at its initial world pose, via trimesh.

glTF is Y-up, so one rotation (-90 degrees about X) maps the world's Z-up frame onto it; units stay
metres. Each geom becomes a node named like the geom (``robot/chassis``) with a PBR material of its
colour; primitives are tessellated (spheres and capsules as subdivision-3 icospheres, cylinders with 32
segments), planes as a 1 mm thick box of their drawn size. Textures are not carried (colours only).

Collision geometry (geoms in group 3 and above, which MuJoCo's viewer hides by default too: the hulls of
mesh assets, tyres) is left out. With ``collision=True`` it is written as well, under a node
``collision`` that only the file's second scene (``visual+collision``) shows: the default scene, the
one viewers open, stays the visual one, and tools that know about scenes can switch.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import trimesh

from meshtool.packfile.export import Z_UP_TO_Y_UP, mark_buffer_views
from simrun.compiled_mesh import compiled_mesh
from simrun.errors import SimrunError
from simrun.outfile import stamp_glb, write_bytes
from simrun.world import World

#: Geoms in this MuJoCo group and above are collision geometry (hidden by default, as in MuJoCo's viewer).
COLLISION_GROUP = 3


def world_to_glb(world: World, collision: bool = False) -> bytes:
    """The world's geoms, posed by ``mj_forward`` at the initial state, as GLB bytes.

    Args:
        world: The world (compiled if needed).
        collision: Also write the collision geoms, as the hidden node set described in the module.
    """
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = trimesh.Scene()
    hidden: list[str] = []
    for g in range(model.ngeom):
        is_collision = int(model.geom_group[g]) >= COLLISION_GROUP
        if is_collision and not collision:
            continue
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
        if is_collision:
            name = f"collision/{name}"
            hidden.append(name)
        scene.add_geometry(mesh, node_name=name, geom_name=name, transform=Z_UP_TO_Y_UP @ pose)
    if not scene.geometry:
        raise SimrunError("the world has no geoms to export")

    def finish(tree: dict[str, Any]) -> None:
        stamp_glb(tree)
        mark_buffer_views(tree)
        if hidden:
            hide_nodes(tree, hidden)

    out: bytes = scene.export(file_type="glb", tree_postprocessor=finish)  # type: ignore[no-untyped-call]
    return out


def hide_nodes(tree: dict[str, Any], names: list[str]) -> None:
    """Move the nodes named in ``names`` under a node ``collision`` shown only by a second scene.

    The default scene (``visual``) keeps every other node; scene 1, ``visual+collision``, shows both.
    """
    nodes = tree["nodes"]
    wanted = set(names)
    moved = [i for i, node in enumerate(nodes) if node.get("name") in wanted]
    for node in nodes:  # trimesh hangs geometry nodes under a root node; detach ours
        if "children" in node:
            node["children"] = [c for c in node["children"] if c not in moved]
            if not node["children"]:
                del node["children"]
    default = tree["scenes"][tree.get("scene", 0)]
    default["nodes"] = [n for n in default["nodes"] if n not in moved]
    nodes.append({"name": "collision", "children": moved, "extras": {"hidden": True}})
    tree["scenes"] = [
        {**default, "name": "visual"},
        {"name": "visual+collision", "nodes": [*default["nodes"], len(nodes) - 1]},
    ]
    tree["scene"] = 0


def export_world_glb(world: World, out: Path, collision: bool = False) -> None:
    """Write :func:`world_to_glb` atomically to ``out`` (must end in ``.glb``)."""
    if out.suffix.lower() != ".glb":
        raise SimrunError(f"{out}: GLB output must end in .glb")
    write_bytes(out, world_to_glb(world, collision))


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
