"""GLB export of a whole world, for web viewers: every visible geom at its initial world pose.

Built with the project's one glTF writer (:class:`meshtool.export.gltf_write.GltfBuilder`), as the asset and
recording exports are. glTF is Y-up, so one root node turned -90 degrees about X (:data:`Z_UP_TO_Y_UP`)
maps the world's Z-up frame onto it; units stay metres. Each geom becomes a node named like the geom
(``robot/chassis``) at its world pose under that root, with a material of its colour (``rgba_G``, G the geom
id). Primitives are tessellated as the recordings' exports tessellate them (:mod:`simrun.export.tessellate`:
spheres, capsules, cylinders with normals; planes as a quad of their drawn size, double-sided); mesh geoms
are MuJoCo's compiled vertices and faces as they are. Textures are not carried (colours only).

Collision geometry (geoms in group 3 and above, which MuJoCo's viewer hides by default too: the hulls of
mesh assets, tyres) is left out. With ``collision=True`` it is written as well, under a node
``collision`` (nodes ``collision/NAME``) that only the file's second scene (``visual+collision``) shows: the
default scene, the one viewers open, stays the visual one, and tools that know about scenes can switch.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from meshtool.export.gltf_write import Z_UP_TO_Y_UP, Z_UP_TO_Y_UP_ROTATION, GltfBuilder
from meshtool.formats import check_suffix
from simrun.errors import SimrunError
from simrun.export.compiled_mesh import compiled_mesh
from simrun.export.tessellate import geom_surface
from simrun.outfile import GENERATOR, write_bytes
from simrun.world.world import World

__all__ = ["COLLISION_GROUP", "Z_UP_TO_Y_UP", "export_world_glb", "world_to_glb"]

#: Geoms in this MuJoCo group and above are collision geometry (hidden by default, as in MuJoCo's viewer).
COLLISION_GROUP = 3


def world_to_glb(world: World, collision: bool = False) -> bytes:
    """The world's geoms, posed by ``mj_forward`` at the initial state, as GLB bytes.

    Args:
        world: The world (compiled if needed).
        collision: Also write the collision geoms, as the hidden node set described in the module.

    Raises:
        SimrunError: The world has no geom to export.
    """
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gltf = GltfBuilder(GENERATOR)
    shown: list[int] = []
    hidden: list[int] = []
    for g in range(model.ngeom):
        is_collision = int(model.geom_group[g]) >= COLLISION_GROUP
        if is_collision and not collision:
            continue
        name = model.geom(g).name or f"geom{g}"
        mesh = _geom_mesh(gltf, model, g, f"collision/{name}" if is_collision else name)
        if mesh is None:
            continue
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(data.geom_xmat[g], dtype=np.float64))
        node = gltf.node(
            {
                "name": f"collision/{name}" if is_collision else name,
                "mesh": mesh,
                "translation": [float(v) for v in data.geom_xpos[g]],
                "rotation": [float(quat[1]), float(quat[2]), float(quat[3]), float(quat[0])],
            }
        )
        (hidden if is_collision else shown).append(node)
    if not shown and not hidden:
        raise SimrunError("the world has no geoms to export")
    root = gltf.node({"name": "world", "rotation": Z_UP_TO_Y_UP_ROTATION, "children": shown})
    if not hidden:
        gltf.scene("visual", [root])
        return gltf.glb()
    extras = {"hidden": True}
    group = gltf.node({"name": "collision", "rotation": Z_UP_TO_Y_UP_ROTATION, "children": hidden, "extras": extras})
    gltf.scene("visual", [root])
    gltf.extra_scene("visual+collision", [root, group])
    return gltf.glb()


def _geom_mesh(gltf: GltfBuilder, model: mujoco.MjModel, g: int, name: str) -> int | None:
    """Geom ``g`` as a glTF mesh in its own frame, ``None`` for height fields and SDF geoms."""
    if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_MESH):
        vertices, faces = compiled_mesh(model, int(model.geom_dataid[g]))
        attributes = {"POSITION": gltf.accessor(vertices, bounds=True)}
        triangles = gltf.indices(faces, len(vertices))
    else:
        surface = geom_surface(model, g, np.ones(2), False)
        if surface is None:
            return None
        attributes = {
            "POSITION": gltf.accessor(surface.positions, bounds=True),
            "NORMAL": gltf.accessor(surface.normals),
        }
        triangles = gltf.indices(surface.triangles, len(surface.positions))
    rgba = [float(c) for c in np.clip(np.asarray(model.geom_rgba[g], dtype=float), 0.0, 1.0)]
    plane = int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE)
    return gltf.mesh(name, attributes, triangles, gltf.material(f"rgba_{g}", rgba, None, rgba[3] < 1.0, plane))


def export_world_glb(world: World, out: Path, collision: bool = False) -> None:
    """Write :func:`world_to_glb` atomically to ``out`` (must end in ``.glb``)."""
    wrong = check_suffix(out, "glb")
    if wrong is not None:
        raise SimrunError(f"{out}: {wrong}")
    write_bytes(out, world_to_glb(world, collision), world=world)
