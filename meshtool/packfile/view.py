"""A typed view of a packed asset: parts, materials, textures, hulls and frame, as every consumer uses them.

An ``.mbin`` stores its materials as the MTL-shaped records the normaliser produced (``colors``, ``scalars``,
``maps``) and its triangles as one index buffer split into submeshes. Every consumer wants the same thing
from that: one part per submesh with its own vertices, and a material reduced to what renderers and
simulators draw. :func:`asset_view` is that conversion, done once, for the MJCF builder
(:mod:`meshtool.mjcf.asset_model`), simrun's asset loading (:mod:`simrun.world.assets`), and the GLB and USD exports
(:mod:`meshtool.packfile.export`, :mod:`meshtool.packfile.usd`).

Frame: positions, normals and hull vertices are metres in the pack's Z-up frame (``.mbin`` is always
normalised). Texture coordinates keep the pack's (OBJ) convention: ``v = 0`` at the image bottom.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.formats import suffix
from meshtool.packfile.read import PackedMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: The diffuse colour of a material that states none (MTL's ``Kd`` default in most viewers).
DEFAULT_COLOUR = (0.8, 0.8, 0.8)


def unique_name(name: str, taken: Collection[str]) -> str:
    """``name``, or ``name_2``, ``name_3``... the first not in ``taken`` (the project's one unique-name rule)."""
    candidate, n = name, 2
    while candidate in taken:
        candidate, n = f"{name}_{n}", n + 1
    return candidate


def unique_names(names: Iterable[str]) -> list[str]:
    """The names in order, each repeated one suffixed ``_2``, ``_3``... (:func:`unique_name`)."""
    out: list[str] = []
    taken: set[str] = set()
    for name in names:
        out.append(unique_name(name, taken))
        taken.add(out[-1])
    return out


@dataclass(frozen=True, slots=True)
class Texture:
    """One packed image.

    Attributes:
        file: Its file name as the pack records it (``tile_albedo.png``; ``tex{k}.png`` when unrecorded).
        data: The PNG bytes.
    """

    file: str
    data: bytes

    @property
    def stem(self) -> str:
        """The file name without its suffix."""
        return self.file.rsplit(".", 1)[0]


@dataclass(frozen=True, slots=True)
class PartMaterial:
    """What a part is drawn with.

    Attributes:
        name: The material's name in the pack (not made unique; see :func:`unique_names`).
        diffuse: ``Kd``, linear RGB 0..1 (:data:`DEFAULT_COLOUR` when unstated).
        alpha: ``d``, 1 opaque.
        colour_map: Index into :attr:`AssetView.textures` of the diffuse map (``map_Kd``), ``None`` when the
            material has none or the pack has no texture coordinates to map it with.
        normal_map: Index of the tangent-space normal map (:func:`meshtool.repair.normalmaps.normal_map`), ``None``
            likewise.
        normal_scale: The normal map's strength (``-bm``; 1 by default).
        record: The pack's material record, for the maps no renderer slot takes (findings, USD roughness).
    """

    name: str
    diffuse: tuple[float, float, float]
    alpha: float
    colour_map: int | None
    normal_map: int | None
    normal_scale: float
    record: dict[str, Any]

    @property
    def rgba(self) -> tuple[float, float, float, float]:
        """Base colour with alpha: the diffuse colour, or white under a colour map (the map is the colour)."""
        r, g, b = (1.0, 1.0, 1.0) if self.colour_map is not None else self.diffuse
        return (r, g, b, self.alpha)


@dataclass(frozen=True, slots=True)
class Part:
    """One submesh with its own vertices (only those its triangles use).

    Shapes: ``n`` vertices, ``m`` triangles.

    Attributes:
        index: The submesh's index in the pack.
        material: Index into :attr:`AssetView.materials`, -1 when the pack has no materials.
        vertices: (n,) indices of the pack's vertices it uses, ascending.
        positions: (n, 3) metres, Z-up.
        faces: (m, 3) indices into ``positions``, counter-clockwise.
        normals: (n, 3) or ``None``.
        uvs: (n, 2) OBJ convention, or ``None``.
    """

    index: int
    material: int
    vertices: IntArray
    positions: FloatArray
    faces: IntArray
    normals: FloatArray | None
    uvs: FloatArray | None


@dataclass(frozen=True, slots=True)
class AssetView:
    """A packed asset, typed.

    Attributes:
        parts: One per submesh, in pack order.
        materials: One per pack material, in pack order.
        textures: One per packed image, in pack order.
        hulls: Collision hulls: ``(vertices (k, 3) metres, faces (j, 3))`` each.
        positions: (V, 3) every vertex of the pack, metres, Z-up.
        indices: (M, 3) every triangle of the pack.
        up: The frame's up axis (always ``z``: a pack is normalised).
        unit: The frame's unit (always metres).
    """

    parts: list[Part]
    materials: list[PartMaterial]
    textures: list[Texture]
    hulls: list[tuple[FloatArray, IntArray]]
    positions: FloatArray
    indices: IntArray
    up: str = "z"
    unit: str = "m"


def asset_view(packed: PackedMesh) -> AssetView:
    """The typed view of ``packed`` (arrays are copies or read-only views; nothing refers back to the file)."""
    from meshtool.repair.normalmaps import normal_map

    recorded = list(packed.pack_meta.textures)
    textures = [
        Texture(str(recorded[k]) if k < len(recorded) else f"tex{k}{suffix('png')}", bytes(data))
        for k, data in enumerate(packed.textures)
    ]
    mappable = packed.uvs is not None
    materials = []
    for k, record in enumerate(packed.materials):
        kd = record.get("colors", {}).get("Kd", DEFAULT_COLOUR)
        colour = record.get("maps", {}).get("map_Kd")
        normal = normal_map(record, packed.textures) if mappable else None
        materials.append(
            PartMaterial(
                name=str(record.get("name", f"material_{k}")),
                diffuse=(float(kd[0]), float(kd[1]), float(kd[2])),
                alpha=float(record.get("scalars", {}).get("d", 1.0)),
                colour_map=int(colour["texture"]) if colour is not None and mappable else None,
                normal_map=normal.texture if normal is not None else None,
                normal_scale=normal.scale if normal is not None else 1.0,
                record=record,
            )
        )
    positions = np.asarray(packed.positions, dtype=np.float64)
    indices = np.asarray(packed.indices, dtype=np.int64).reshape(-1, 3)
    normals = np.asarray(packed.normals, dtype=np.float64) if packed.normals is not None else None
    uvs = np.asarray(packed.uvs, dtype=np.float64) if packed.uvs is not None else None
    parts = []
    for k, (first, count, material, _) in enumerate(np.asarray(packed.submeshes, dtype=np.int64).tolist()):
        corners = indices[first : first + count]
        seen = np.zeros(len(positions), dtype=bool)
        seen[corners] = True  # the vertices the part uses, ascending, and their ranks (np.unique's, in O(n))
        if seen.all():  # every vertex: the pack's arrays as they are
            used, faces = np.arange(len(positions)), corners
            part_positions, part_normals, part_uvs = positions, normals, uvs
        else:
            used = np.flatnonzero(seen)
            faces = (np.cumsum(seen) - 1)[corners]
            part_positions = positions[used]
            part_normals = normals[used] if normals is not None else None
            part_uvs = uvs[used] if uvs is not None else None
        parts.append(
            Part(
                index=k,
                material=int(material) if materials else -1,
                vertices=used,
                positions=part_positions,
                faces=faces,
                normals=part_normals,
                uvs=part_uvs,
            )
        )
    hulls = [(np.asarray(v, np.float64), np.asarray(f, np.int64)) for v, f in packed.hulls]
    return AssetView(parts, materials, textures, hulls, positions, indices)
