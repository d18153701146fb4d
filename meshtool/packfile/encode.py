"""Array encodings of ``.mbin``: render vertices, u16 box quantisation and octahedral normals."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from meshtool.mesh import TriMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

U16_MAX = 65535
I16_MAX = 32767


@dataclass(slots=True)
class RenderMesh:
    """One index per corner: every distinct (position, texcoord, normal) combination is one vertex.

    Attributes:
        positions: (V, 3) metres.
        normals: (V, 3) or ``None``.
        uvs: (V, 2) or ``None``.
        colors: (V, 3) floats 0..1 or ``None``.
        indices: (M, 3) vertex indices.
        source_vertex: (V,) index of each vertex's position in the source mesh.
    """

    positions: FloatArray
    normals: FloatArray | None
    uvs: FloatArray | None
    colors: FloatArray | None
    indices: IntArray
    source_vertex: IntArray


def render_mesh(mesh: TriMesh) -> RenderMesh:
    """Unify a mesh's separate position/texcoord/normal indices into one index, in first-use order."""
    has_uv = mesh.face_uv.size > 0 and bool((mesh.face_uv >= 0).any())
    has_n = mesh.face_normal.size > 0 and bool((mesh.face_normal >= 0).any())
    v = mesh.faces.reshape(-1)
    if not has_uv and not has_n:
        return RenderMesh(mesh.positions, None, None, mesh.colors, mesh.faces.copy(), np.arange(len(mesh.positions)))
    vt = mesh.face_uv.reshape(-1) + 1
    vn = mesh.face_normal.reshape(-1) + 1
    nt, nn = mesh.texcoords.shape[0] + 1, mesh.normals.shape[0] + 1
    key = (v * nt + vt) * nn + vn
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    corner = first[order]
    source = v[corner]
    uvs = normals = None
    if has_uv:
        t = vt[corner] - 1
        uvs = np.where((t >= 0)[:, None], mesh.texcoords[np.maximum(t, 0)], 0.0)
    if has_n:
        n = vn[corner] - 1
        normals = np.where((n >= 0)[:, None], mesh.normals[np.maximum(n, 0)], 0.0)
    colors = mesh.colors[source] if mesh.colors is not None else None
    return RenderMesh(mesh.positions[source], normals, uvs, colors, rank[inverse].reshape(-1, 3), source)


def quantize_box(values: FloatArray) -> tuple[npt.NDArray[np.uint16], list[float], list[float], list[float]]:
    """Quantise each column to u16 in its own [lo, hi] range.

    Returns:
        The codes, ``lo``, ``hi`` and the measured maximum absolute error per column (decoding with
        :func:`dequantize_box`).
    """
    if values.shape[0] == 0:
        zeros = [0.0] * values.shape[1]
        return np.zeros(values.shape, dtype=np.uint16), zeros, zeros, zeros
    lo = values.min(axis=0)
    hi = values.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    codes = np.clip(np.rint((values - lo) / span * U16_MAX), 0, U16_MAX).astype(np.uint16)
    decoded = dequantize_box(codes, lo.tolist(), hi.tolist())
    error = np.abs(decoded.astype(np.float64) - values).max(axis=0)
    return codes, lo.tolist(), hi.tolist(), error.tolist()


def dequantize_box(codes: npt.NDArray[np.uint16], lo: list[float], hi: list[float]) -> npt.NDArray[np.float32]:
    """Decode :func:`quantize_box`: ``float32(lo + q * ((hi - lo) / 65535))`` computed in float64."""
    lo_a = np.asarray(lo, dtype=np.float64)
    step = (np.asarray(hi, dtype=np.float64) - lo_a) / U16_MAX
    with np.errstate(over="ignore", invalid="ignore"):  # hostile lo/hi: the reader refuses non-finite results
        result: npt.NDArray[np.float32] = (lo_a + codes.astype(np.float64) * step).astype(np.float32)
    return result


def oct_encode(normals: FloatArray) -> npt.NDArray[np.int16]:
    """Unit vectors (N, 3) to octahedral snorm16 pairs (N, 2); zero vectors encode +Z."""
    n = np.asarray(normals, dtype=np.float64)
    l1 = np.abs(n).sum(axis=1, keepdims=True)
    n = np.where(l1 > 0, n / np.where(l1 > 0, l1, 1.0), np.array([0.0, 0.0, 1.0]))
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    sx = np.where(x >= 0, 1.0, -1.0)
    sy = np.where(y >= 0, 1.0, -1.0)
    fx = np.where(z < 0, (1 - np.abs(y)) * sx, x)
    fy = np.where(z < 0, (1 - np.abs(x)) * sy, y)
    codes: npt.NDArray[np.int16] = np.rint(np.clip(np.stack([fx, fy], axis=1), -1, 1) * I16_MAX).astype(np.int16)
    return codes


def oct_decode(codes: npt.NDArray[np.int16]) -> npt.NDArray[np.float32]:
    """Decode :func:`oct_encode` to unit float32 vectors (N, 3)."""
    f = codes.astype(np.float64) / I16_MAX
    x, y = f[:, 0], f[:, 1]
    z = 1 - np.abs(x) - np.abs(y)
    sx = np.where(x >= 0, 1.0, -1.0)
    sy = np.where(y >= 0, 1.0, -1.0)
    xo = np.where(z < 0, (1 - np.abs(y)) * sx, x)
    yo = np.where(z < 0, (1 - np.abs(x)) * sy, y)
    v = np.stack([xo, yo, z], axis=1)
    length = np.linalg.norm(v, axis=1, keepdims=True)
    result: npt.NDArray[np.float32] = (v / np.where(length > 0, length, 1.0)).astype(np.float32)
    return result


def max_angle_deg(a: FloatArray, b: npt.NDArray[np.float32]) -> float:
    """Largest angle in degrees between rows of unit vectors ``a`` (normalised here) and ``b``."""
    if a.shape[0] == 0:
        return 0.0
    na = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)
    cos = np.clip((na * b.astype(np.float64)).sum(axis=1), -1.0, 1.0)
    valid = np.linalg.norm(a, axis=1) > 0
    return float(np.degrees(np.arccos(cos[valid])).max(initial=0.0))
