"""Content checks of an ``.mbin``: every index against its table, every field's type, every float finite.

The container checks (header, table, bounds, checksums) live in :mod:`meshtool.packfile.read`; this module
checks what the sections *say*, so that a file with valid checksums but hostile content (a hull face
naming vertex 4,000,000, a submesh naming a material that does not exist, a colour that is a string,
positions of +-inf) is refused with the section and byte offset instead of crashing a consumer later.
See docs/mbin-spec.md section 5.

The JSON checks (``META`` and ``MATL``) run whenever a file is loaded (they are cheap); the array checks
run with ``verify=True``.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.errors import PackFormatError
from meshtool.repair.pnginfo import IHDR_WIDTH_OFFSET, over_limit, png_size

HINT = "the file is damaged or was not written by meshtool; convert the source again"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: A texture file name: one path component, no separators, no control characters, not ``.``/``..``.
_BAD_NAME = re.compile(r"[/\\\x00-\x1f\x7f:]")


def fail(message: str, name: str, offset: int) -> PackFormatError:
    """A :class:`PackFormatError` for content that breaks the spec, with the standard hint."""
    return PackFormatError(message, path=name, offset=offset, hint=HINT)


# ------------------------------------------------------------------------------------------------ JSON


def reject_constant(text: str) -> Any:
    """``json.loads`` hook: ``NaN``/``Infinity`` are not JSON and the spec forbids them."""
    raise ValueError(f"non-finite number {text} (the format allows only finite numbers)")


def finite_float(text: str) -> float:
    """``json.loads`` hook: a float literal that overflows to infinity (``1e999``) is refused."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text[:40]} is outside the float range")
    return value


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _file_name(value: Any) -> bool:
    return (
        isinstance(value, str)
        and 0 < len(value.encode("utf-8", "surrogatepass")) <= 255
        and value not in (".", "..")
        and not _BAD_NAME.search(value)
    )


class _Json:
    """Type checks of one JSON section; every error names the field and the section's offset."""

    def __init__(self, kind: str, name: str, offset: int) -> None:
        self.kind, self.name, self.offset = kind, name, offset

    def fail(self, where: str, what: str) -> PackFormatError:
        return fail(f"section {self.kind!r}: {where} {what}", self.name, self.offset)

    def expect(self, value: Any, types: type | tuple[type, ...], where: str, what: str) -> Any:
        if not isinstance(value, types) or (isinstance(value, bool) and bool not in _tuple(types)):
            raise self.fail(where, f"is not {what}")
        return value

    def optional(self, obj: dict[str, Any], key: str, types: type | tuple[type, ...], what: str, where: str) -> Any:
        if key not in obj:
            return None
        return self.expect(obj[key], types, f"{where}.{key}", what)

    def numbers(self, value: Any, where: str, length: int | None = None) -> list[float]:
        self.expect(value, list, where, "an array of numbers")
        if length is not None and len(value) != length:
            raise self.fail(where, f"has {len(value)} numbers, expected {length}")
        if not all(_number(x) for x in value):
            raise self.fail(where, "holds something other than numbers")
        return [float(x) for x in value]

    def strings(self, value: Any, where: str) -> list[str]:
        self.expect(value, list, where, "an array of strings")
        if not all(isinstance(x, str) for x in value):
            raise self.fail(where, "holds something other than strings")
        return list(value)


def _tuple(types: type | tuple[type, ...]) -> tuple[type, ...]:
    return types if isinstance(types, tuple) else (types,)


def check_meta(
    meta: dict[str, Any], n_textures: int, quantized: dict[str, int], name: str, offset: int
) -> tuple[list[str], list[str]]:
    """Check the types of the ``META`` keys meshtool and its consumers read.

    Args:
        meta: The parsed object.
        n_textures: Number of ``TEX `` sections.
        quantized: Columns of each box-quantised array (``{"positions": 3, "uvs": 2}`` as present).
        name: File name for errors.
        offset: The section's byte offset.

    Returns:
        The texture file names and the part names.

    Raises:
        PackFormatError: A key of the wrong type, a texture list that does not match the ``TEX`` sections,
            a texture name that is not a plain file name, or missing/invalid quantisation parameters.
    """
    j = _Json("META", name, offset)
    for key in ("format", "name"):
        j.optional(meta, key, str, "a string", "META")
    for key in ("options", "transform", "stats", "render", "mass_properties"):
        j.optional(meta, key, dict, "an object", "META")
    for key in ("findings", "resolutions"):
        j.optional(meta, key, list, "an array", "META")
    tool = j.optional(meta, "tool", dict, "an object", "META")
    if tool is not None:
        for key in ("name", "version"):
            j.optional(tool, key, str, "a string", "META.tool")
    for k, source in enumerate(j.optional(meta, "sources", list, "an array", "META") or []):
        j.expect(source, dict, f"META.sources[{k}]", "an object")
        for key in ("role", "path", "sha256"):
            j.expect(source.get(key), str, f"META.sources[{k}].{key}", "a string")
    textures = j.strings(meta.get("textures", []), "META.textures")
    if len(textures) != n_textures:
        raise j.fail("META.textures", f"names {len(textures)} texture(s) but the file has {n_textures} TEX section(s)")
    for k, texture in enumerate(textures):
        if not _file_name(texture):
            raise j.fail(f"META.textures[{k}]", f"{texture[:80]!r} is not a plain file name")
    if len(set(textures)) != len(textures):
        raise j.fail("META.textures", "names the same file twice")
    parts = j.strings(meta.get("parts", []), "META.parts")
    quant = j.optional(meta, "quantization", (dict, type(None)), "an object or null", "META") or {}
    for array, columns in quantized.items():
        params = j.expect(quant.get(array), dict, f"META.quantization.{array}", "an object (the array is quantised)")
        lo = j.numbers(params.get("lo"), f"META.quantization.{array}.lo", columns)
        hi = j.numbers(params.get("hi"), f"META.quantization.{array}.hi", columns)
        if any(h < low for low, h in zip(lo, hi, strict=True)):
            raise j.fail(f"META.quantization.{array}", "has hi below lo")
    hull_parts = j.optional(meta, "hull_parts", list, "an array", "META") or []
    for k, part in enumerate(hull_parts):
        if not _integer(part) or not 0 <= part < len(parts):
            raise j.fail(f"META.hull_parts[{k}]", f"is {part!r}, not a part index below {len(parts)}")
    report = j.optional(meta, "hull_quality", (dict, type(None)), "an object or null", "META")
    if report:
        if "hulls" in report and not _integer(report["hulls"]):
            raise j.fail("META.hull_quality.hulls", "is not an integer")
        for key, value in report.items():
            if key != "vertices_per_hull" and value is not None and not _number(value):
                raise j.fail(f"META.hull_quality.{key}", "is not a number or null")
        if "vertices_per_hull" in report:
            j.numbers(report["vertices_per_hull"], "META.hull_quality.vertices_per_hull")
    return textures, parts


def check_materials(materials: list[Any], n_textures: int, name: str, offset: int) -> None:
    """Check every material of ``MATL``: its fields' types, finite numbers, texture indices in range.

    Raises:
        PackFormatError: The first field that breaks docs/mbin-spec.md "MATL".
    """
    j = _Json("MATL", name, offset)
    for k, m in enumerate(materials):
        at = f"material {k}"
        j.expect(m, dict, at, "an object")
        j.expect(m.get("name"), str, f"{at}.name", "a string")
        for key, value in (j.optional(m, "colors", dict, "an object", at) or {}).items():
            if not all(0.0 <= c <= 1.0 for c in j.numbers(value, f"{at}.colors.{key}", 3)):
                raise j.fail(f"{at}.colors.{key}", f"is {value!r}, not three numbers in 0..1")
        for key, value in (j.optional(m, "scalars", dict, "an object", at) or {}).items():
            if not _number(value):
                raise j.fail(f"{at}.scalars.{key}", "is not a number")
        illum = m.get("illum")
        if illum is not None and not _integer(illum):
            raise j.fail(f"{at}.illum", "is not an integer or null")
        for key, spec in (j.optional(m, "maps", dict, "an object", at) or {}).items():
            where = f"{at}.maps.{key}"
            j.expect(spec, dict, where, "an object")
            texture = spec.get("texture")
            if not _integer(texture) or not 0 <= texture < n_textures:
                raise j.fail(f"{where}.texture", f"is {texture!r}, not a texture index below {n_textures}")
            j.optional(spec, "file", str, "a string", where)
            for option, args in (j.optional(spec, "options", dict, "an object", where) or {}).items():
                j.strings(args, f"{where}.options.{option}")


# ------------------------------------------------------------------------------------------------ arrays


def check_finite(values: npt.NDArray[Any], what: str, name: str, offset: int, itemsize: int) -> None:
    """Refuse a non-finite float; ``offset``/``itemsize`` locate the first one in the stored section.

    Args:
        values: The array (stored floats, or values decoded from stored codes of ``itemsize`` bytes each).
        what: The section kind for the message.
        name: File name.
        offset: The section's byte offset.
        itemsize: Stored bytes per element (4 for f32, 2 for u16 codes).
    """
    flat = np.asarray(values).reshape(-1)
    if np.isfinite(flat).all():  # one pass, no inverted copy: the common case
        return
    bad = ~np.isfinite(flat)
    if bad.any():
        k = int(np.argmax(bad))
        raise fail(
            f"section {what!r}: value {k} is {float(flat[k])} (every float must be finite)",
            name,
            offset + k * itemsize,
        )


def check_indices(indices: npt.NDArray[Any], n: int, what: str, name: str, offset: int, exact: bool) -> None:
    """Refuse an index ``>= n``; the offset is the element's when ``exact`` (plain storage), else the section's."""
    if not indices.size:
        return
    flat = indices.reshape(-1)
    if int(flat.max()) < n:  # a max reduction reads the indices once and allocates nothing
        return
    bad = flat >= n
    if bad.any():
        k = int(np.argmax(bad))
        at = offset + k * indices.dtype.itemsize if exact else offset
        raise fail(f"section {what!r}: an index is {int(flat[k])} but there are {n} vertices", name, at)


def check_submeshes(
    submeshes: npt.NDArray[Any], triangles: int, n_materials: int, n_parts: int, name: str, offset: int
) -> None:
    """Submeshes tile the triangles in order, are non-empty, and name existing materials and parts.

    With no materials, the material column must be 0 (what writers store).
    """
    if not submeshes.size:
        if triangles:
            raise fail("triangles without a submesh table", name, offset)
        return
    rows = submeshes.astype(np.int64)
    first, count = rows[:, 0], rows[:, 1]
    end = first + count
    if first[0] != 0 or (first[1:] != end[:-1]).any() or end[-1] != triangles or (count == 0).any():
        raise fail("section 'SUBM': submeshes do not tile the triangles (or one is empty)", name, offset)
    for column, have, limit, what in ((2, n_materials, max(n_materials, 1), "material"), (3, n_parts, n_parts, "part")):
        bad = rows[:, column] >= limit
        if bad.any():
            k = int(np.argmax(bad))
            raise fail(
                f"section 'SUBM': submesh {k} names {what} {int(rows[k, column])} but there are {have}",
                name,
                offset + (k * 4 + column) * 4,
            )


def check_hulls(
    table: npt.NDArray[Any], vertices: int, faces: npt.NDArray[Any], offsets: tuple[int, int], name: str
) -> None:
    """Hulls tile the hull arrays in order, each has >= 4 vertices and faces indexing only its own vertices.

    Args:
        table: (H, 4) rows (first vertex, vertex count, first face, face count).
        vertices: Rows of ``HULV``.
        faces: (F, 3) ``HULF``.
        offsets: Byte offsets of ``HULT`` and ``HULF``.
        name: File name.
    """
    table_at, faces_at = offsets
    rows = table.astype(np.int64)
    nv, nf = rows[:, 1], rows[:, 3]
    v_end, f_end = np.cumsum(nv), np.cumsum(nf)
    tiles = (
        (rows[:, 0] == v_end - nv).all()
        and (rows[:, 2] == f_end - nf).all()
        and int(v_end[-1] if len(rows) else 0) == vertices
        and int(f_end[-1] if len(rows) else 0) == faces.shape[0]
    )
    if not tiles:
        raise fail("section 'HULT': hulls do not tile the hull vertex and face arrays", name, table_at)
    if (nv < 4).any() or (nf < 4).any():
        k = int(np.argmax((nv < 4) | (nf < 4)))
        raise fail(
            f"section 'HULT': hull {k} has {int(nv[k])} vertices and {int(nf[k])} faces (at least 4 each)",
            name,
            table_at + k * 16,
        )
    if faces.size:
        limit = np.repeat(nv, nf)[:, None]
        bad = faces.astype(np.int64) >= limit
        if bad.any():
            k = int(np.argmax(bad.reshape(-1)))
            hull = int(np.searchsorted(f_end, k // 3, side="right"))
            raise fail(
                f"section 'HULF': a face of hull {hull} names vertex {int(faces.reshape(-1)[k])} but the hull "
                f"has {int(nv[hull])}",
                name,
                faces_at + k * 4,
            )


def check_png(data: memoryview, index: int, name: str, offset: int) -> None:
    """A ``TEX`` section starts with the PNG signature and its IHDR declares a size within the texture limits.

    The image itself is not decoded here (that is the consumer's job, and a consumer reports an image it
    cannot decode as an input error, not a crash): fixtures such as ``P001_mujoco_compile`` rely on a file
    whose container is sound and whose image MuJoCo refuses.
    """
    if bytes(data[:8]) != PNG_SIGNATURE:
        raise fail(f"section 'TEX ' {index} is not a PNG file (no PNG signature)", name, offset)
    size = png_size(data)  # the IHDR's width and height, read without decoding (a 879 KB bomb decodes to 900 MB)
    too_big = over_limit(*size) if size is not None else None
    if too_big:
        raise fail(f"section 'TEX ' {index}: {too_big}", name, offset + IHDR_WIDTH_OFFSET)
