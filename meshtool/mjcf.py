"""MJCF output: a MuJoCo model per ``.mbin`` asset, following MuJoCo Menagerie's conventions.

Default classes ``visual`` (group 2, no contacts, massless) and ``collision`` (group 3); one visual geom
per submesh with its material; one collision geom per stored hull with ``inertia="convex"``; textures as
PNG files; mesh data as MuJoCo's binary ``.msh`` files beside the XML. The body's mass comes from the
collision geoms only: from ``density``, or split by hull volume so the body weighs exactly ``mass``.
meshtool does not import mujoco; the XML is plain text and the tests compile it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import trimesh

from meshtool.errors import OptionsError
from meshtool.mesh import safe_identifier
from meshtool.packfile.export import to_msh
from meshtool.packfile.read import PackedMesh


@dataclass(frozen=True, slots=True)
class MjcfOptions:
    """Options of ``meshtool mjcf``.

    Attributes:
        free_joint: Give the body a free joint (it falls and can be pushed); else it is fixed to the world.
        density: Density of the collision geometry, kg/m^3 (ignored when ``mass`` is given).
        mass: Total body mass in kg, split over the collision hulls by volume.
        max_hull_vertices: ``maxhullvert`` written on every mesh.
    """

    free_joint: bool = False
    density: float = 1000.0
    mass: float | None = None
    max_hull_vertices: int = 64

    def __post_init__(self) -> None:
        if not self.density > 0 or (self.mass is not None and not self.mass > 0) or self.max_hull_vertices < 4:
            raise OptionsError("density and mass must be positive, max hull vertices at least 4")


class _Msh:
    """Arrays shaped like a PackedMesh, for :func:`to_msh`."""

    def __init__(self, positions: Any, indices: Any, normals: Any = None, uvs: Any = None) -> None:
        self.positions, self.indices, self.normals, self.uvs = positions, indices, normals, uvs


@dataclass(slots=True)
class MeshFragment:
    """The MJCF pieces of one packed mesh, for a model that places it somewhere.

    Attributes:
        files: ``.msh`` meshes and PNG textures by file name.
        assets: ``<texture>``, ``<material>`` and ``<mesh>`` elements.
        visual: ``<geom class="visual" .../>`` attributes, one per submesh, without pose or closing.
        collision: ``<geom class="collision" .../>`` attributes, one per hull, without pose or closing.
        volumes: Volume of each hull, m^3.
    """

    files: dict[str, bytes]
    assets: list[str]
    visual: list[str]
    collision: list[str]
    volumes: list[float]


def mesh_fragment(packed: PackedMesh, prefix: str, max_hull_vertices: int = 64) -> MeshFragment:
    """Meshes, materials, textures and geoms of ``packed``, every name starting with ``prefix``."""
    model = prefix
    files: dict[str, bytes] = {}
    assets: list[str] = []
    textures = list(packed.meta.get("textures", []))
    for k, data in enumerate(packed.textures):
        file_name = f"{model}_{textures[k]}"
        files[file_name] = bytes(data)
        assets.append(f'<texture name="{model}_tex{k}" type="2d" file={quoteattr(file_name)}/>')
    material_names = []
    for k, m in enumerate(packed.materials):
        mat = f"{model}_{safe_identifier(str(m.get('name', k)), f'material{k}')}"
        material_names.append(mat)
        kd = m.get("colors", {}).get("Kd", [0.8, 0.8, 0.8])
        alpha = float(m.get("scalars", {}).get("d", 1.0))
        rgba = " ".join(_num(float(c)) for c in [*kd[:3], alpha])
        texture = m.get("maps", {}).get("map_Kd")
        attrs = f' texture="{model}_tex{int(texture["texture"])}"' if texture is not None else ""
        if texture is not None:
            rgba = f"1 1 1 {_num(alpha)}"
        assets.append(f'<material name="{mat}" rgba="{rgba}"{attrs}/>')

    visual: list[str] = []
    positions = np.asarray(packed.positions, dtype=np.float32)
    indices = np.asarray(packed.indices, dtype=np.int64)
    for k, (first, count, material, _part) in enumerate(np.asarray(packed.submeshes, dtype=np.int64).tolist()):
        faces = indices[first : first + count]
        used, inverse = np.unique(faces, return_inverse=True)
        normals = packed.normals[used] if packed.normals is not None else None
        uvs = packed.uvs[used] if packed.uvs is not None else None
        mesh_file = f"{model}_visual_{k}.msh"
        files[mesh_file] = to_msh(_Msh(positions[used], inverse.reshape(-1, 3), normals, uvs))  # type: ignore[arg-type]
        assets.append(f'<mesh name="{model}_visual_{k}" file="{mesh_file}" inertia="shell"/>')
        mat = f' material="{material_names[material]}"' if material_names else ""
        visual.append(f'class="visual" mesh="{model}_visual_{k}"{mat}')

    volumes = [float(trimesh.Trimesh(v, f, process=False).volume) for v, f in packed.hulls]
    collision: list[str] = []
    for k, (hull_vertices, hull_faces) in enumerate(packed.hulls):
        mesh_file = f"{model}_collision_{k}.msh"
        files[mesh_file] = to_msh(_Msh(np.asarray(hull_vertices, np.float32), np.asarray(hull_faces, np.int64)))  # type: ignore[arg-type]
        hull_attrs = f'inertia="convex" maxhullvert="{max_hull_vertices}"'
        assets.append(f'<mesh name="{model}_collision_{k}" file="{mesh_file}" {hull_attrs}/>')
        collision.append(f'class="collision" mesh="{model}_collision_{k}"')
    return MeshFragment(files, assets, visual, collision, volumes)


def build_mjcf(packed: PackedMesh, name: str, options: MjcfOptions | None = None) -> dict[str, bytes]:
    """The files of a MuJoCo model for one asset: ``NAME.xml``, meshes (``.msh``) and PNG textures.

    Raises:
        OptionsError: The file has no collision hulls (pack it with ``--hulls`` other than ``none``).
    """
    options = options or MjcfOptions()
    if not packed.hulls:
        raise OptionsError("the .mbin has no collision hulls", hint="convert it with obj2bin --hulls convex")
    model = safe_identifier(name, "asset")
    fragment = mesh_fragment(packed, model, options.max_hull_vertices)
    files, assets = fragment.files, fragment.assets
    geoms = [f"<geom {g}/>" for g in fragment.visual]
    total = sum(fragment.volumes)
    for k, geom in enumerate(fragment.collision):
        if options.mass is not None:
            weight = f' mass="{_num(options.mass * fragment.volumes[k] / total)}"'
        else:
            weight = f' density="{_num(options.density)}"'
        geoms.append(f"<geom {geom}{weight}/>")

    joint = ["    <freejoint/>"] if options.free_joint else []
    xml = "\n".join(
        [
            f'<mujoco model="{model}">',
            '  <compiler angle="radian" meshdir="." texturedir="."/>',
            "  <default>",
            '    <default class="visual"><geom type="mesh" group="2" contype="0" conaffinity="0" mass="0"/></default>',
            '    <default class="collision"><geom type="mesh" group="3"/></default>',
            "  </default>",
            "  <asset>",
            *(f"    {a}" for a in assets),
            "  </asset>",
            "  <worldbody>",
            f'   <body name="{model}">',
            *joint,
            *(f"    {g}" for g in geoms),
            "   </body>",
            "  </worldbody>",
            "</mujoco>",
            "",
        ]
    )
    files[f"{model}.xml"] = xml.encode("utf-8")
    return files


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text
