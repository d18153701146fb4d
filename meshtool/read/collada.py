"""COLLADA (``.dae``) reader: the XML parsed once, bounded; pycollada reads the asset, effects and materials.

- **Geometry**: every geometry instanced by the visual scene, placed by its node transforms (composed in
  float32 as pycollada does), winding reversed under a mirroring transform. Triangles, polylists,
  polygons, triangle strips and fans are read (:mod:`meshtool.read.collada_geometry` checks every
  count, stride and index; :mod:`meshtool.read.collada_scene` walks the node graph without recursion);
  lines are skipped with a finding.
- **Limits**: what the scene expands to (``<instance_node>`` fan-out included) is counted per node and
  charged to the file's :class:`~meshtool.read.budget.ExpansionBudget` before anything is placed; at
  most :data:`~meshtool.read.budget.MAX_INSTANCES` node and primitive instances
  (``MESHTOOL_MAX_INSTANCES``) and :data:`~meshtool.read.collada_xml.MAX_ELEMENTS` XML elements.
- **Broken references**: an ``<instance_geometry>``/``<instance_node>`` naming nothing, or an
  ``<instance_material>`` whose material is missing or unreadable, is skipped with a warning; the rest of
  the geometry is kept.
- **Frame**: ``<unit meter>`` and ``<up_axis>`` of the document's ``<asset>`` are honoured: the unit
  becomes the source unit of the normaliser (``cm``, ``mm``, ``in``... or a scale), ``Y_UP``/``Z_UP`` the
  up axis; ``X_UP`` is turned to ``Y_UP`` here (``(x, y, z) -> (-y, x, z)``, the COLLADA 1.4 axes).
- **Materials**: each bound material's effect: ``diffuse`` colour -> ``Kd`` (or its texture -> ``map_Kd``),
  ``emission`` -> ``Ke``, ``specular`` -> ``Ks``, ``shininess`` -> ``Ns``, transparency -> ``d`` (A_ONE).
  Image files are found and read by the asset's resolver only (never by pycollada), with the containment
  rules of an OBJ's textures.

Locations of findings count triangles in file order.
"""

from __future__ import annotations

import io
import re
import warnings
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

import numpy as np

from meshtool.errors import FormatError, MeshtoolError
from meshtool.findings import Finding, info, warning
from meshtool.read.budget import ExpansionBudget
from meshtool.read.collada_scene import Instance, SceneWalk
from meshtool.read.collada_xml import parse_xml, subset
from meshtool.read.obj.mtl import Material, TextureMap
from meshtool.read.source_mesh import (
    FloatArray,
    IntArray,
    Piece,
    SourceFrame,
    SourceMesh,
    assemble,
    merge_rows,
    mirrors,
)

if TYPE_CHECKING:
    from pathlib import Path

    from meshtool.files.resolve import Resolver

_DECLARATION = re.compile(rb"<!(?:DOCTYPE|ENTITY)", re.IGNORECASE)
#: What pycollada still reads; geometry and the scene are read by :mod:`meshtool.read.collada_geometry` and
#: :mod:`meshtool.read.collada_scene`.
_PYCOLLADA_PARTS = ("asset", "library_images", "library_effects", "library_materials")
_X_TO_Y = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def read_collada(data: bytes, path: str) -> SourceMesh:
    """Read a COLLADA file.

    Args:
        data: The file's bytes.
        path: Name for findings and errors.

    Returns:
        The mesh (one part per geometry instance), its materials and declared frame.

    Raises:
        FormatError: XML or COLLADA structure pycollada cannot read.
    """
    if data.startswith(b"PK\x03\x04"):  # pycollada would unzip it (.zae): no bounded, checked read of the inside
        raise FormatError(
            "a zipped COLLADA archive (.zae) is not read", path=path, offset=0, hint="unzip it and pass the .dae"
        )
    if _DECLARATION.search(data):
        raise FormatError(
            "COLLADA with a DOCTYPE or ENTITY declaration is not read (entities could read or expand files "
            "outside the asset)",
            path=path,
            hint="remove the declaration; COLLADA files need none",
        )
    root = parse_xml(data, path)
    budget = ExpansionBudget.for_file(path)
    findings: list[Finding] = []
    try:
        doc = _pycollada(root, _PYCOLLADA_PARTS)
    except Exception as exc:  # pycollada raises DaeError subclasses, lxml errors, ValueError...
        text = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        try:  # a damaged effect or image: the geometry is still read, without materials
            doc = _pycollada(root, ("asset",))
        except Exception:
            raise FormatError(f"COLLADA cannot be read: {text}", path=path, hint="the file is damaged") from None
        findings.append(
            warning("collada-materials-unreadable", f"materials cannot be read ({text}): none are kept", path)
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PendingDeprecationWarning)  # pycollada builds numpy matrices
        try:
            return _read(doc, root, path, budget, findings)
        except MeshtoolError:
            raise
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
            what = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
            raise FormatError(
                f"malformed COLLADA: {what}", path=path, hint="the file is damaged; export it again"
            ) from None


def _pycollada(root: Any, parts: tuple[str, ...]) -> Any:
    """The pycollada document of the top-level elements ``parts`` of ``root`` (asset, materials...)."""
    import collada

    ignore = [collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError]
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return collada.Collada(io.BytesIO(subset(root, parts)), ignore=ignore, aux_file_loader=_no_files)


def _read(doc: Any, root: Any, path: str, budget: ExpansionBudget, findings: list[Finding]) -> SourceMesh:
    frame, rotate = _frame(doc, path, findings)
    materials: list[Material] = []
    by_id: dict[str, int] = {}
    pieces: list[Piece] = []
    triangles = 0
    walk = SceneWalk(root, path, {str(m.id): m for m in doc.materials}, findings)
    roots = walk.scene_roots()
    if roots is None:
        findings.append(warning("collada-no-scene", "no visual scene: nothing is instanced", path))
        instances: list[Instance] = []
    else:
        instances = walk.place(roots, budget)  # counted and charged before anything is placed
    for instance in instances:
        matrix = instance.matrix  # float32, and placed in float32, as pycollada binds geometry
        flip = mirrors(np.asarray(matrix, dtype=np.float64))
        linear, shift = matrix.T[:3, :3], matrix[:3, 3]
        for prim in instance.geometry.prims:
            with np.errstate(all="ignore"):
                positions = np.asarray(np.dot(prim.positions, linear) + shift, dtype=np.float64)
            faces = prim.vertex_index
            if not np.isfinite(positions[faces.reshape(-1)]).all():
                raise FormatError(
                    f"geometry '{instance.geometry.name}' placed here has non-finite coordinates (its transform "
                    "overflows float32)",
                    path=path,
                    line=instance.line,
                    hint="the COLLADA file is damaged; export it again",
                )
            m = faces.shape[0]
            normals = uvs = None
            if prim.normals is not None and prim.normal_index is not None:
                with np.errstate(all="ignore"):  # non-finite normals are replaced by assemble, with a warning
                    normals = np.asarray(np.dot(prim.normals, linear), dtype=np.float64)[prim.normal_index.reshape(-1)]
            if prim.uvs is not None and prim.uv_index is not None:
                uvs = np.asarray(prim.uvs, dtype=np.float64)[prim.uv_index.reshape(-1)]
            corners = faces.reshape(-1)
            if normals is not None or uvs is not None:  # attributes indexed per corner: split the corners
                positions = positions[corners]
                faces = np.arange(corners.size, dtype=np.int64).reshape(-1, 3)
            if rotate:
                positions = positions @ _X_TO_Y.T
                normals = None if normals is None else normals @ _X_TO_Y.T
            if flip:
                faces = faces[:, ::-1].copy()
            bound = instance.materials.get(prim.material) if prim.material is not None else None
            material = _material(bound, materials, by_id, path, findings)
            locations = np.arange(triangles + 1, triangles + m + 1, dtype=np.int64)
            triangles += m
            pieces.append(Piece(instance.geometry.name, material, positions, faces, locations, uvs, normals))
    if walk.lines:
        findings.append(info("lines-skipped", f"{walk.lines} line primitive(s) skipped: not surface geometry", path))
    record = {
        "unit_meter": frame.unit_m,
        "up_axis": str(doc.assetInfo.upaxis),
        "geometries": sum(1 for _ in root.iterfind("./{*}library_geometries/{*}geometry")),
        "instances": len(instances),
    }
    mesh = assemble(pieces, path, "collada", "triangle", materials, frame, findings, record)
    return _weld(mesh)


def _no_files(name: str) -> bytes | None:
    """The loader pycollada gets of referenced files: meshtool's resolver reads images, pycollada never does."""
    return None


def _frame(doc: Any, path: str, findings: list[Finding]) -> tuple[SourceFrame, bool]:
    info_ = doc.assetInfo
    meter = float(info_.unitmeter) if info_.unitmeter is not None else 1.0
    name = str(info_.unitname or "")
    if not (np.isfinite(meter) and meter > 0):
        findings.append(
            warning("collada-unit-invalid", f"<unit meter={meter!r}> is not a positive number: metres used", path)
        )
        meter = 1.0
    up_text = str(info_.upaxis or "Y_UP")
    rotate = up_text == "X_UP"
    up = "z" if up_text == "Z_UP" else "y"
    if rotate:
        findings.append(info("collada-x-up", "X_UP turned to Y_UP ((x, y, z) -> (-y, x, z))", path))
    frame = SourceFrame(
        meter,
        f'COLLADA <unit meter="{meter:g}" name="{name}"/>',
        up,
        f"COLLADA <up_axis>{up_text}</up_axis>",
    )
    return frame, rotate


def _material(bound: Any, materials: list[Material], by_id: dict[str, int], path: str, findings: list[Finding]) -> int:
    if bound is None or isinstance(bound, str) or getattr(bound, "effect", None) is None:
        return -1
    key = str(bound.id)
    if key in by_id:
        return by_id[key]
    effect = bound.effect
    out = Material(str(bound.name or bound.id or f"material{len(materials)}"), 0, illum=2)
    for attr, colour_key, map_key in (
        ("diffuse", "Kd", "map_Kd"),
        ("emission", "Ke", "map_Ke"),
        ("specular", "Ks", None),
    ):
        value = getattr(effect, attr, None)
        if isinstance(value, tuple) and len(value) >= 3:
            out.colors[colour_key] = (_clamp(value[0]), _clamp(value[1]), _clamp(value[2]))
        elif value is not None and map_key is not None and hasattr(value, "sampler"):
            image = _image_path(value)
            if image:
                out.maps[map_key] = TextureMap(image, {}, 0)
                if colour_key == "Kd":
                    out.colors["Kd"] = (1.0, 1.0, 1.0)
            else:
                findings.append(warning("texture-missing", f"material {out.name!r}: {attr} texture has no image", path))
    if "Kd" not in out.colors and "map_Kd" not in out.maps:
        out.colors["Kd"] = (0.8, 0.8, 0.8)
    shininess = getattr(effect, "shininess", None)
    if isinstance(shininess, float | int) and np.isfinite(shininess) and shininess > 0:
        out.scalars["Ns"] = float(min(shininess, 1000.0))
    alpha = _opacity(effect)
    if alpha < 1.0:
        out.scalars["d"] = alpha
    materials.append(out)
    by_id[key] = len(materials) - 1
    return by_id[key]


def _image_path(texture_map: Any) -> str | None:
    try:
        image = texture_map.sampler.surface.image
    except AttributeError:
        return None
    raw = getattr(image, "path", None)
    return unquote(str(raw)) if raw else None


def _opacity(effect: Any) -> float:
    """Opacity in the A_ONE mode (the default): ``transparent.a * transparency``."""
    transparency = getattr(effect, "transparency", None)
    transparent = getattr(effect, "transparent", None)
    t = float(transparency) if isinstance(transparency, float | int) and np.isfinite(transparency) else 1.0
    a = float(transparent[3]) if isinstance(transparent, tuple) and len(transparent) >= 4 else 1.0
    if getattr(effect, "opaque_mode", "A_ONE") == "RGB_ZERO":
        rgb = transparent[:3] if isinstance(transparent, tuple) else (0.0, 0.0, 0.0)
        return float(min(max(1.0 - t * float(np.mean(rgb)), 0.0), 1.0))
    return float(min(max(a * t, 0.0), 1.0))


def _clamp(value: Any) -> float:
    v = float(value)
    return min(max(v, 0.0), 1.0) if np.isfinite(v) else 1.0


def _weld(mesh: SourceMesh) -> SourceMesh:
    """Merge vertices split per corner back where position and every attribute are equal (exact match)."""
    if mesh.corner_v.size == 0:
        return mesh
    positions, remap = merge_rows(mesh.positions)
    first = _first_index(remap, positions.shape[0])
    # texcoords and normals keep their own (per-corner) indices; positions are shared
    mesh.vertex_lines = mesh.vertex_lines[first]
    mesh.colors = None if mesh.colors is None else mesh.colors[first]
    mesh.positions = positions
    mesh.corner_v = remap[mesh.corner_v]
    mesh.texcoords, mesh.corner_vt = _unique_rows(mesh.texcoords, mesh.corner_vt)
    mesh.normals, mesh.corner_vn = _unique_rows(mesh.normals, mesh.corner_vn)
    return mesh


def _first_index(remap: IntArray, size: int) -> IntArray:
    """For each of ``size`` merged rows, the first input row that maps to it."""
    first = np.full(size, remap.size, dtype=np.int64)
    np.minimum.at(first, remap, np.arange(remap.size, dtype=np.int64))
    return first


def _unique_rows(values: FloatArray, index: IntArray) -> tuple[FloatArray, IntArray]:
    """Equal rows of ``values`` merged (first-use order); ``index`` remapped, -1 kept."""
    if values.shape[0] == 0:
        return values, index
    rows, remap = merge_rows(values)
    return rows, np.where(index >= 0, remap[np.maximum(index, 0)], -1)


def read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """The formats registry's reader (:data:`meshtool.formats.MESH_FORMATS`): :func:`read_collada`."""
    return read_collada(data, path)
