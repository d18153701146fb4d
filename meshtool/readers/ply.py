"""PLY reader: ASCII and binary (both byte orders), vertex colours, normals and texture coordinates.

Parsing is trimesh's (:func:`trimesh.exchange.ply.load_ply`); this module takes its arrays and the raw
element data: texture coordinates from vertex properties (``s t``, ``u v``, ``texture_u texture_v``,
``texture_s texture_t``) or from a per-face ``texcoord`` list, and the texture image from a
``comment TextureFile NAME`` header line (resolved by the asset's resolver, like an MTL ``map_Kd``).
PLY has no unit and no up axis. Locations of findings count faces.
"""

from __future__ import annotations

import io
import re
import warnings
from typing import Any

import numpy as np

from meshtool.errors import FormatError
from meshtool.findings import Finding, info
from meshtool.obj.mtl import Material, TextureMap
from meshtool.readers.model import FloatArray, Piece, SourceFrame, SourceMesh, assemble

FRAME = SourceFrame(None, "PLY has no unit", None, "PLY has no up axis")
_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
_TEXTURE = re.compile(rb"^comment\s+TextureFile\s+(.+?)\s*$", re.MULTILINE | re.IGNORECASE)
_FORMAT = re.compile(rb"^format\s+(\S+)", re.MULTILINE)


def read_ply(data: bytes, path: str) -> SourceMesh:
    """Read a PLY file.

    Args:
        data: The file's bytes.
        path: Name for findings and errors.

    Returns:
        The mesh: one part, a textured material when the header names a ``TextureFile``.

    Raises:
        FormatError: Not a PLY file, or a header/body trimesh cannot read.
    """
    if not data.startswith(b"ply"):
        raise FormatError("not a PLY file: it does not start with 'ply'", path=path, hint="pass a PLY file")
    end = data.find(b"end_header")
    if end < 0:
        raise FormatError("PLY header has no 'end_header'", path=path, offset=0, hint="the file is damaged")
    header = data[:end]
    match = _FORMAT.search(header)
    encoding = match.group(1).decode("latin-1") if match else "unknown"
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            from trimesh.exchange.ply import load_ply

            loaded: dict[str, Any] = load_ply(io.BytesIO(data), resolver=None, fix_texture=False, skip_materials=True)
    except Exception as exc:  # trimesh raises ValueError, IndexError, struct errors... for damaged files
        text = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise FormatError(f"PLY cannot be read: {text}", path=path, hint="the file is damaged or not PLY") from None
    findings: list[Finding] = []
    positions = np.asarray(loaded.get("vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(loaded.get("faces", np.zeros((0, 3))))
    raw = (loaded.get("metadata") or {}).get("_ply_raw", {})
    n_faces_src = int(raw.get("face", {}).get("length", 0)) if isinstance(raw, dict) else 0
    faces, locations = _triangles(faces, n_faces_src)
    normals = loaded.get("vertex_normals")
    colors = loaded.get("vertex_colors")
    uvs = _vertex_uvs(raw)
    face_uvs = _face_uvs(raw) if uvs is None else None
    materials: list[Material] = []
    texture = _TEXTURE.search(header)
    if texture is not None:
        name = texture.group(1).decode("utf-8", "replace").strip()
        line = header[: texture.start()].count(b"\n") + 1
        materials.append(
            Material("ply_texture", line, colors={"Kd": (1.0, 1.0, 1.0)}, maps={"map_Kd": TextureMap(name, {}, line)})
        )
    piece = Piece(
        "default",
        0 if materials else -1,
        positions,
        faces,
        locations,
        uvs=uvs,
        normals=None if normals is None else np.asarray(normals, dtype=np.float64),
        colors=None if colors is None else np.asarray(colors, dtype=np.float64)[:, :3] / 255.0,
    )
    if face_uvs is not None and faces.shape[0] == face_uvs.shape[0]:
        piece.corner_uvs = face_uvs.reshape(-1, 2)
    if loaded.get("face_colors") is not None:
        findings.append(info("ply-face-colors-dropped", "per-face colours are not kept (vertex colours are)", path))
    record = {"encoding": encoding, "vertices": int(positions.shape[0]), "faces": n_faces_src or int(faces.shape[0])}
    return assemble([piece], path, "ply", "face", materials, FRAME, findings, record)


def _triangles(faces: np.ndarray, n_src: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles from trimesh's faces (quads and polygons fanned) and the 1-based face each came from."""
    if faces.size == 0:
        return np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    faces = np.asarray(faces, dtype=np.int64)
    if faces.ndim == 2 and faces.shape[1] == 3:
        k = faces.shape[0]
        source = np.arange(1, k + 1) if n_src in (0, k) else np.zeros(k, dtype=np.int64) + 1
        return faces, source.astype(np.int64)
    width = faces.shape[1]
    rows = np.concatenate([faces[:, [0, k, k + 1]] for k in range(1, width - 1)])
    source = np.tile(np.arange(1, faces.shape[0] + 1), width - 2)
    order = np.argsort(source, kind="stable")
    return rows[order], source[order].astype(np.int64)


def _vertex_uvs(raw: Any) -> FloatArray | None:
    vertex = raw.get("vertex") if isinstance(raw, dict) else None
    if not vertex:
        return None
    names = list(vertex.get("properties", {}))
    data = vertex.get("data")
    for u, v in _UV_NAMES:
        if u in names and v in names:
            cu, cv = _column(data, u), _column(data, v)
            return np.stack([cu, cv], axis=1)
    return None


def _face_uvs(raw: Any) -> FloatArray | None:
    face = raw.get("face") if isinstance(raw, dict) else None
    if not face or "texcoord" not in face.get("properties", {}):
        return None
    data = face.get("data")
    try:
        values = data["texcoord"]
        if values.dtype.names:  # binary: (count, values)
            values = values[values.dtype.names[1]]
        out: FloatArray = np.asarray(values, dtype=np.float64).reshape(-1, 3, 2)
    except (ValueError, KeyError, TypeError, IndexError):
        return None
    return out


def _column(data: Any, name: str) -> FloatArray:
    out: FloatArray = np.asarray(data[name], dtype=np.float64).reshape(-1)
    return out
