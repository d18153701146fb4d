"""``.mbin`` writer: a prepared asset to bytes, deterministically (see docs/mbin-spec.md)."""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from meshtool import __version__
from meshtool.errors import PackFormatError
from meshtool.hulls import surface
from meshtool.packfile import format as fmt
from meshtool.packfile.encode import max_angle_deg, oct_decode, oct_encode, quantize_box, render_mesh
from meshtool.packfile.meta import PackMeta

if TYPE_CHECKING:
    from meshtool.hulls.compute import Hull
    from meshtool.read.obj.mtl import Material
    from meshtool.repair.normalise import NormalisedAsset


@dataclass(slots=True)
class StoredSection:
    """One section as stored: its table fields and data bytes (deflated when ``encoding`` is 3).

    Attributes:
        kind: Four-byte tag.
        code: dtype code (see :data:`meshtool.packfile.format.DTYPES`).
        shape: (rows, columns); columns 0 for 1-D data.
        ndim: 1 or 2.
        data: The stored bytes.
        encoding: Encoding code.
        index: Number among sections of the same kind.
    """

    kind: bytes
    code: int
    shape: tuple[int, int]
    ndim: int
    data: bytes
    encoding: int = fmt.ENC_PLAIN
    index: int = 0


def _array(kind: bytes, array: npt.NDArray[Any], code: str, encoding: int = fmt.ENC_PLAIN) -> StoredSection:
    a = np.ascontiguousarray(array, dtype=fmt.DTYPES[fmt.CODES[code]])
    shape = (a.shape[0], a.shape[1] if a.ndim == 2 else 0)
    return StoredSection(kind, fmt.CODES[code], shape, a.ndim, a.tobytes(), encoding)


def _blob(kind: bytes, data: bytes, index: int = 0) -> StoredSection:
    return StoredSection(kind, 0, (len(data), 0), 1, data, fmt.ENC_PLAIN, index)


def _deflated(section: StoredSection) -> StoredSection:
    """The same section stored as a zlib stream (level 6; zlib output is deterministic)."""
    section.data = zlib.compress(section.data, 6)
    section.encoding = fmt.ENC_DEFLATE
    return section


def canonical_json(value: Any) -> bytes:
    """JSON with sorted keys and no spaces: the same value always gives the same bytes.

    Raises:
        PackFormatError: The value holds NaN or an infinity (the format allows only finite numbers).
    """
    try:
        text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    except ValueError as exc:
        raise PackFormatError(
            f"cannot pack: the metadata holds a non-finite number ({exc})",
            hint="fix the non-finite value in the source (an MTL colour or scalar, a coordinate)",
            code="non-finite",
        ) from None
    return text.encode("utf-8")


def pack(
    asset: NormalisedAsset,
    quantize: bool = False,
    options: dict[str, Any] | None = None,
    hulls: list[Hull] | None = None,
    hull_quality: dict[str, Any] | None = None,
) -> bytes:
    """Pack a prepared asset (see :func:`meshtool.repair.normalise.prepare`) into ``.mbin`` bytes.

    Args:
        asset: The asset; its mesh is in metres, Z-up.
        quantize: Store positions and uvs as u16 in their bounding boxes and normals octahedral.
        options: The options that produced the asset, recorded in the metadata (for staleness checks).
        hulls: Collision hulls (see :mod:`meshtool.hulls.compute`), stored in the hull sections.
        hull_quality: The hulls' quality report, recorded in the metadata.

    Returns:
        The file contents; identical inputs give identical bytes.
    """
    rm = render_mesh(asset.mesh)
    _check_float32("vertex position", rm.positions, asset.name)
    for what, values in (("normal", rm.normals), ("texture coordinate", rm.uvs)):
        if values is not None:
            _check_float32(what, values, asset.name)
    for hull in hulls or []:
        _check_float32("hull vertex", hull.vertices, asset.name)
    sections: list[StoredSection] = []
    quant: dict[str, Any] = {}
    if quantize:
        codes, lo, hi, err = quantize_box(rm.positions)
        sections.append(_array(fmt.KIND_POSITIONS, codes, "u16", fmt.ENC_UNORM16_BOX))
        quant["positions"] = {"lo": lo, "hi": hi, "max_abs_error_m": err}
    else:
        sections.append(_array(fmt.KIND_POSITIONS, rm.positions, "f32"))
    if rm.normals is not None:
        if quantize:
            oct_codes = oct_encode(rm.normals)
            sections.append(_array(fmt.KIND_NORMALS, oct_codes, "i16", fmt.ENC_OCT_SNORM16))
            quant["normals"] = {"max_angle_error_deg": max_angle_deg(rm.normals, oct_decode(oct_codes))}
        else:
            sections.append(_array(fmt.KIND_NORMALS, rm.normals, "f32"))
    if rm.uvs is not None:
        if quantize:
            codes, lo, hi, err = quantize_box(rm.uvs)
            sections.append(_array(fmt.KIND_UVS, codes, "u16", fmt.ENC_UNORM16_BOX))
            quant["uvs"] = {"lo": lo, "hi": hi, "max_abs_error": err}
        else:
            sections.append(_array(fmt.KIND_UVS, rm.uvs, "f32"))
    if rm.colors is not None:
        sections.append(_array(fmt.KIND_COLORS, _rgba8(rm.colors), "u8"))
    n = rm.positions.shape[0]
    # Indices stay plain in quantised files too (format 1.1): inflating them cost 10x a lossless load.
    sections.append(_array(fmt.KIND_INDICES, rm.indices, "u16" if n < 65536 else "u32"))
    sections.append(_array(fmt.KIND_SUBMESHES, _submeshes(asset), "u32"))
    table, hull_vertices, hull_faces = _hull_arrays(hulls or [])
    sections.append(_array(fmt.KIND_HULL_TABLE, table, "u32"))
    sections.append(_array(fmt.KIND_HULL_VERTICES, hull_vertices, "f32"))
    sections.append(_array(fmt.KIND_HULL_FACES, hull_faces, "u32"))
    texture_names = sorted(asset.textures)
    sections.extend(_blob(fmt.KIND_TEXTURE, asset.textures[t], k) for k, t in enumerate(texture_names))
    sections.append(_deflated(_blob(fmt.KIND_MATERIALS, canonical_json(_materials(asset.materials, texture_names)))))
    meta = PackMeta.of_asset(
        asset.manifest,
        tool={"name": "meshtool", "version": __version__},
        options=options,
        quantization=quant,
        textures=texture_names,
        parts=asset.mesh.part_names,
        render={"vertices": int(n), "triangles": int(rm.indices.shape[0])},
        mass_properties=_mass_properties(rm.positions, rm.indices),
        hull_parts=[h.part for h in hulls or []],
        hull_quality=hull_quality,
    )
    sections.append(_deflated(_blob(fmt.KIND_META, canonical_json(meta.raw))))
    return assemble(sections, fmt.FLAG_QUANTIZED if quantize else 0)


FLOAT32_MAX = float(np.finfo(np.float32).max)


def _check_float32(what: str, values: npt.NDArray[Any], name: str) -> None:
    """Refuse a value that is not finite or that float32 cannot hold (it would be stored as +-inf)."""
    flat = np.asarray(values, dtype=np.float64).reshape(-1)
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(flat) <= FLOAT32_MAX)
    if bad.any():
        k = int(np.argmax(bad))
        columns = values.shape[1] if values.ndim == 2 else 1
        raise PackFormatError(
            f"cannot pack: {what} {k // columns} has the value {float(flat[k]):g}, beyond float32's range "
            f"(+-{FLOAT32_MAX:.4g})",
            path=name,
            hint="scale the asset down (--units, --scale) or fix the source's coordinates",
            code="non-finite",
        )


def assemble(sections: list[StoredSection], flags: int, minor: int = fmt.MINOR) -> bytes:
    """Header, section table and 64-byte aligned data of a version 1.``minor`` file, in ``sections`` order.

    Args:
        sections: The sections as stored.
        flags: Header flags.
        minor: The minor version; it selects the checksum (:func:`meshtool.packfile.format.checksum`).
            Only ``scripts/make_goldens.py`` writes 1.0 (the committed 1.0 goldens, byte for byte).

    Returns:
        The file.
    """
    table = np.zeros(len(sections), dtype=fmt.ENTRY)
    offset = fmt.align(fmt.HEADER_SIZE + fmt.ENTRY_SIZE * len(sections))
    chunks: list[bytes] = []
    position = offset
    for k, s in enumerate(sections):
        table[k]["kind"] = s.kind
        table[k]["dtype"] = s.code
        table[k]["ndim"] = s.ndim
        table[k]["index"] = s.index
        table[k]["shape"] = s.shape
        table[k]["offset"] = position
        table[k]["length"] = len(s.data)
        table[k]["crc"] = fmt.checksum(s.data, minor)
        table[k]["encoding"] = s.encoding
        padded = fmt.align(len(s.data))
        chunks.append(s.data + b"\0" * (padded - len(s.data)))
        position += padded
    header = np.zeros(1, dtype=fmt.HEADER)
    header["magic"] = fmt.MAGIC
    header["major"], header["minor"] = fmt.MAJOR, minor
    header["flags"] = flags
    header["section_count"] = len(sections)
    header["table_offset"] = fmt.HEADER_SIZE
    header["file_length"] = position
    head = header.tobytes()
    table_bytes = table.tobytes()
    header["table_crc"] = fmt.checksum(head[:32] + table_bytes, minor)
    gap = b"\0" * (offset - fmt.HEADER_SIZE - len(table_bytes))
    return header.tobytes() + table_bytes + gap + b"".join(chunks)


def _hull_arrays(hulls: list[Hull]) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The hull table (first vertex, vertex count, first face, face count) and the concatenated arrays."""
    if not hulls:
        return np.zeros((0, 4), dtype=np.uint32), np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    nv = np.array([len(h.vertices) for h in hulls])
    nf = np.array([len(h.faces) for h in hulls])
    table = np.stack([np.cumsum(nv) - nv, nv, np.cumsum(nf) - nf, nf], axis=1).astype(np.uint32)
    return table, np.concatenate([h.vertices for h in hulls]), np.concatenate([h.faces for h in hulls])


def _rgba8(colors: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
    c = np.clip(np.rint(np.clip(colors, 0.0, 1.0) * 255), 0, 255).astype(np.uint8)
    return np.concatenate([c, np.full((c.shape[0], 1), 255, dtype=np.uint8)], axis=1)


def _submeshes(asset: NormalisedAsset) -> npt.NDArray[np.uint32]:
    """Rows (first triangle, triangle count, material, part) for each run of equal material and part."""
    mesh = asset.mesh
    m = mesh.faces.shape[0]
    if m == 0:
        return np.zeros((0, 4), dtype=np.uint32)
    material = mesh.face_material if asset.materials else np.zeros(m, dtype=np.int64)
    change = np.flatnonzero((np.diff(material) != 0) | (np.diff(mesh.face_part) != 0)) + 1
    first = np.concatenate([[0], change])
    count = np.diff(np.append(first, m))
    rows = np.stack([first, count, material[first], mesh.face_part[first]], axis=1)
    return rows.astype(np.uint32)


def _materials(materials: list[Material], textures: list[str]) -> list[dict[str, Any]]:
    out = []
    for m in materials:
        out.append(
            {
                "name": m.name,
                "colors": {k: list(v) for k, v in m.colors.items()},
                "scalars": dict(m.scalars),
                "illum": m.illum,
                "maps": {
                    k: {
                        "texture": textures.index(t.file),
                        "file": t.file,
                        "options": {o: list(a) for o, a in t.options.items()},
                    }
                    for k, t in m.maps.items()
                },
            }
        )
    return out


def _mass_properties(positions: npt.NDArray[np.float64], indices: npt.NDArray[np.int64]) -> dict[str, Any]:
    """Bounding box, area, and (for unit density, kg/m^3) volume, centre of mass and inertia.

    Computed by :mod:`meshtool.hulls.surface` (bit-identical to trimesh's ``mass_properties``).
    """
    if indices.shape[0] == 0:
        return {"area_m2": 0.0, "watertight": False}
    tris = surface.triangles(positions, indices)
    cross = surface.crosses(tris)
    props = surface.mass_properties(tris, cross)
    com = [_finite(x) for x in props.center_mass]
    return {
        "area_m2": float(surface.face_areas(cross).sum()),
        "watertight": surface.is_watertight(indices),
        "volume_m3": props.volume,
        "center_of_mass_m": com if all(c is not None for c in com) else None,
        "inertia_unit_density_kg_m2": [[_finite(x) for x in row] for row in props.inertia],
        "note": "volume, centre of mass and inertia are only meaningful when watertight (null: zero volume)",
    }


def _finite(x: Any) -> float | None:
    value = float(x)
    return value if np.isfinite(value) else None
