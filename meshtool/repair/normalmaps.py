"""Which texture of a packed material is its tangent-space normal map, and which maps an export leaves out.

glTF 2.0 (``material.normalTexture``) and USD's ``UsdPreviewSurface`` (``inputs:normal``) take a
*tangent-space normal map*: RGB pixels ``c`` in 0..1 encoding the unit vector ``n = 2 c - 1`` in the
triangle's tangent frame (+X along increasing u, +Y along increasing v, +Z out of the surface; the OpenGL
convention that both formats and every OBJ exporter use). Neither format has a slot for a height (bump)
map or a displacement map.

MTL names normal maps in two ways: ``norm`` (``map_Norm``, ``map_Kn``) is one by definition; ``bump``
(``map_Bump``) is a height map by the MTL specification, but Blender's OBJ exporter, and the many assets
made with it, write their normal map there. So a ``bump`` map is exported as the normal map when the
material has no ``norm`` and its pixels are normal vectors (:func:`looks_like_normal_map`); otherwise it is
a height map and left out of the export (an ``export-map-dropped`` finding says so).

The normal map's strength is its ``-bm`` option (the MTL bump multiplier; 1 when absent), written as
glTF's ``normalTexture.scale`` and as USD's ``UsdUVTexture`` ``scale``/``bias``: ``n = (2 c - 1) *
(s, s, 1)``, as glTF defines its scale.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, info

#: Largest mean distance of decoded normals from unit length, and least share of normals facing out
#: (n_z > NORMAL_MIN_Z), for an image to count as a tangent-space normal map.
NORMAL_LENGTH_TOLERANCE = 0.15
NORMAL_MIN_Z = 0.3
NORMAL_MIN_SHARE = 0.9
#: Pixels examined per image (a regular subsample of larger images).
SAMPLE_PIXELS = 65536

#: Map keys each export carries (``map_Kd`` as base colour, the normal map as its normal input).
EXPORTED = {"glb": ("map_Kd",), "usd": ("map_Kd",)}
FORMAT_NAMES = {"glb": "glTF", "usd": "USD"}


@dataclass(frozen=True, slots=True)
class NormalMap:
    """The normal map of one material.

    Attributes:
        key: The MTL map key it came from (``norm`` or ``bump``).
        texture: Index into the pack's textures.
        scale: Strength: x and y of the decoded normal are multiplied by it (``-bm``; 1 by default).
    """

    key: str
    texture: int
    scale: float


def looks_like_normal_map(png: bytes) -> bool:
    """Whether an image's pixels are tangent-space unit normals facing out of the surface.

    A normal map's pixels decode (``n = 2 c - 1``) to vectors of unit length with a positive z (it is
    mostly blue, ``(128, 128, 255)`` for a flat surface); a height map is grey (``|n|`` is 0 for mid-grey,
    about 1.7 for white) and a colour texture is neither.

    Args:
        png: Image file bytes (any format Pillow reads).

    Returns:
        ``False`` also when the image cannot be decoded.
    """
    from PIL import Image

    try:
        with Image.open(io.BytesIO(png)) as image:
            if image.mode in ("1", "L", "LA", "I", "I;16", "F"):
                return False
            rgb = np.asarray(image.convert("RGB"), dtype=np.float64).reshape(-1, 3)
    except (OSError, ValueError, SyntaxError, EOFError, Image.DecompressionBombError):
        return False
    if rgb.shape[0] == 0:
        return False
    step = max(1, math.ceil(rgb.shape[0] / SAMPLE_PIXELS))
    n = rgb[::step] / 255.0 * 2.0 - 1.0
    length = np.linalg.norm(n, axis=1)
    return bool(
        float(np.mean(np.abs(length - 1.0))) <= NORMAL_LENGTH_TOLERANCE
        and float(np.mean(n[:, 2] > NORMAL_MIN_Z)) >= NORMAL_MIN_SHARE
    )


def normal_map(material: dict[str, Any], textures: list[Any]) -> NormalMap | None:
    """The normal map of a packed material record (``norm``, else a ``bump`` that holds normals).

    Args:
        material: One ``.mbin`` material record (``maps`` by key, each with ``texture`` and ``options``).
        textures: The pack's texture bytes, by index.

    Returns:
        ``None`` when the material has none.
    """
    maps = material.get("maps", {})
    for key in ("norm", "bump"):
        entry = maps.get(key)
        if not isinstance(entry, dict):
            continue
        index = int(entry["texture"])
        if key == "bump" and not looks_like_normal_map(bytes(textures[index])):
            continue
        return NormalMap(key, index, _strength(entry.get("options", {})))
    return None


def _strength(options: dict[str, Any]) -> float:
    """``-bm`` of a map statement's options (1 when absent or not a finite number)."""
    values: Any = options.get("-bm")
    try:
        value = float(values[0])
    except (IndexError, TypeError, ValueError):
        return 1.0
    return value if math.isfinite(value) else 1.0


def export_findings(packed: Any, kind: str) -> list[Finding]:
    """``export-map-dropped`` notes for the maps an export of ``packed`` cannot carry.

    Args:
        packed: The loaded ``.mbin`` (``materials``, ``textures``, ``uvs``).
        kind: ``glb`` or ``usd``.

    Returns:
        One info finding per material that has maps the format has no slot for (or none at all, when the
        pack has no texture coordinates).
    """
    findings: list[Finding] = []
    for material in packed.materials:
        maps = material.get("maps", {})
        if not maps:
            continue
        name = str(material.get("name", "material"))
        if packed.uvs is None:
            kept: set[str] = set()
        else:
            kept = set(EXPORTED[kind])
            normal = normal_map(material, packed.textures)
            if normal is not None:
                kept.add(normal.key)
        dropped = [f"{key} ({_role(key)}: {maps[key].get('file')})" for key in sorted(maps) if key not in kept]
        if dropped:
            why = "the pack has no texture coordinates" if packed.uvs is None else "no slot in the format"
            findings.append(
                info(
                    "export-map-dropped",
                    f"material {name!r}: {', '.join(dropped)} not exported to {FORMAT_NAMES[kind]} ({why})",
                )
            )
    return findings


#: Map keys MuJoCo's renderer does not read: the normal map and the bump (height, or Blender's normal) map.
MUJOCO_IGNORED = {"norm": "normal map", "bump": "bump map"}


def mujoco_findings(materials: Any, path: str | None = None) -> list[Finding]:
    """A ``mujoco-ignores-map`` note when materials going to MuJoCo carry normal or bump maps.

    MuJoCo's renderer (and so simrun) shows a material's colour map only: the maps stay in the ``.mbin``
    for the GLB and USD exports, but the MJCF written from it shades the surface without them.

    Args:
        materials: :class:`meshtool.read.obj.mtl.Material` objects, or a pack's material dicts.
        path: The source file the note is about.

    Returns:
        Zero or one info finding.
    """
    found: list[str] = []
    for material in materials:
        if isinstance(material, dict):
            name = str(material.get("name", "material"))
            maps = {k: str(v.get("file")) for k, v in material.get("maps", {}).items()}
        else:
            name, maps = material.name, {k: v.file for k, v in material.maps.items()}
        found += [f"{maps[key]} ({role} of {name!r})" for key, role in MUJOCO_IGNORED.items() if key in maps]
    if not found:
        return []
    shown = ", ".join(found[:3]) + (f" and {len(found) - 3} more" if len(found) > 3 else "")
    return [
        info(
            "mujoco-ignores-map",
            f"MuJoCo ignores normal and bump maps: {shown} have no effect in MuJoCo or simrun "
            "(kept in the .mbin for the GLB/USD exports)",
            path,
        )
    ]


def _role(key: str) -> str:
    return {
        "bump": "height map",
        "disp": "displacement map",
        "norm": "normal map",
        "map_d": "alpha map",
        "map_Pr": "roughness map",
        "map_Pm": "metallic map",
        "map_Ns": "specular exponent map",
    }.get(key, "map")


def vertex_tangents(
    positions: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    normals: npt.NDArray[np.float64],
    uvs: npt.NDArray[np.float64],
) -> npt.NDArray[np.float32]:
    """Per-vertex tangents ``(n, 4)`` for a normal map, as glTF's ``TANGENT`` attribute.

    ``xyz`` is the unit direction of increasing u on the surface, made orthogonal to the vertex normal
    (triangle contributions summed, each weighted by its area in UV space; Lengyel's method); ``w`` is +1
    or -1 so that ``cross(normal, xyz) * w`` points along increasing v (OBJ convention: up in the image),
    the +Y of a tangent-space normal map. A vertex whose triangles have no usable UV area gets any unit
    vector orthogonal to its normal, with ``w = 1``.

    Args:
        positions: ``(n, 3)`` metres.
        faces: ``(k, 3)`` vertex indices.
        normals: ``(n, 3)`` vertex normals (made unit; a zero normal counts as +Z).
        uvs: ``(n, 2)`` texture coordinates, OBJ convention (v = 0 at the image bottom).
    """
    n = np.asarray(normals, dtype=np.float64)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 1e-12, n / np.where(length > 1e-12, length, 1.0), np.array([0.0, 0.0, 1.0]))
    p = np.asarray(positions, dtype=np.float64)[faces]
    t = np.asarray(uvs, dtype=np.float64)[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    # (e1 dv2 - e2 dv1) / r is the u direction scaled by 1 / r, r the UV area: the sum weights by UV area
    udir = e1 * d2[:, 1:2] - e2 * d1[:, 1:2]
    vdir = e2 * d1[:, 0:1] - e1 * d2[:, 0:1]
    r = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    sign = np.sign(r)[:, None]
    tan_u = np.zeros_like(n)
    tan_v = np.zeros_like(n)
    for corner in range(3):
        np.add.at(tan_u, faces[:, corner], udir * sign)
        np.add.at(tan_v, faces[:, corner], vdir * sign)
    tangent = tan_u - n * np.sum(n * tan_u, axis=1, keepdims=True)
    size = np.linalg.norm(tangent, axis=1)
    bad = ~(size > 1e-12 * np.maximum(1.0, np.linalg.norm(tan_u, axis=1)))
    if bad.any():  # any vector orthogonal to the normal: cross with the axis least aligned with it
        axis = np.eye(3)[np.argmin(np.abs(n[bad]), axis=1)]
        tangent[bad] = np.cross(n[bad], axis)
        size[bad] = np.linalg.norm(tangent[bad], axis=1)
    tangent /= size[:, None]
    w = np.where(np.sum(np.cross(n, tangent) * tan_v, axis=1) < 0.0, -1.0, 1.0)
    return np.column_stack([tangent, w]).astype(np.float32)


def vertex_normals(positions: npt.NDArray[np.float64], faces: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
    """Unit per-vertex normals ``(n, 3)``: the face normals around each vertex weighted by their corner angle.

    For a normal map on a mesh that stores no normals (glTF's ``TANGENT`` needs a ``NORMAL``). A vertex of
    degenerate faces only gets ``(0, 0, 0)``.
    """
    p = np.asarray(positions, dtype=np.float64)[faces]
    face_normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(face_normal, axis=1, keepdims=True)
    face_normal = np.divide(face_normal, length, out=np.zeros_like(face_normal), where=length > 0)
    summed = np.zeros((len(positions), 3))
    for corner in range(3):
        a = p[:, (corner + 1) % 3] - p[:, corner]
        b = p[:, (corner + 2) % 3] - p[:, corner]
        cos = np.sum(a * b, axis=1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
        np.add.at(summed, faces[:, corner], face_normal * angle[:, None])
    size = np.linalg.norm(summed, axis=1, keepdims=True)
    result: npt.NDArray[np.float64] = np.divide(summed, size, out=np.zeros_like(summed), where=size > 0)
    return result
