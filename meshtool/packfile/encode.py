"""Array encodings of ``.mbin``: render vertices, u16 box quantisation and octahedral normals."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from meshtool.repair.mesh import TriMesh

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

    Each column's range is widened slightly (by less than 1 % of a step) onto an exact grid when one exists
    (see :func:`exact_grid`), so that readers decode it in float32 at memory speed with the same result as
    the format's float64 formula.

    Returns:
        The codes, ``lo``, ``hi`` and the measured maximum absolute error per column (decoding with
        :func:`dequantize_box`).
    """
    if values.shape[0] == 0:
        zeros = [0.0] * values.shape[1]
        return np.zeros(values.shape, dtype=np.uint16), zeros, zeros, zeros
    bounds = [_grid_bounds(float(a), float(b)) for a, b in zip(values.min(axis=0), values.max(axis=0), strict=True)]
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    span = np.where(hi > lo, hi - lo, 1.0)
    codes = np.clip(np.rint((values - lo) / span * U16_MAX), 0, U16_MAX).astype(np.uint16)
    decoded = dequantize_box(codes, lo.tolist(), hi.tolist())
    error = np.abs(decoded.astype(np.float64) - values).max(axis=0)
    return codes, lo.tolist(), hi.tolist(), error.tolist()


#: Decoded box values are integers times a power of two below this many units: exact in float32.
_EXACT_UNITS = 1 << 24


def _grid_bounds(lo: float, hi: float) -> tuple[float, float]:
    """``(lo', hi')`` with ``lo' <= lo``, ``hi' >= hi`` on which :func:`exact_grid` holds, else ``(lo, hi)``.

    The step is ``S * 2**e`` with ``S`` of at most 8 significant bits (finest first), so it is at most 1 %
    coarser than ``(hi - lo) / 65535``; ``lo'`` is ``lo`` rounded down to a multiple of ``2**e``.
    """
    span = hi - lo
    if not (span > 0 and math.isfinite(span)):
        return lo, hi
    target = span / U16_MAX
    for bits in range(7, -1, -1):
        e = math.floor(math.log2(target)) - bits
        if e < -140:  # values this small would not be float32 normals
            break
        unit = math.ldexp(1.0, e)
        m = math.floor(lo / unit)
        step = math.ceil(target / unit)
        while (m + U16_MAX * step) * unit < hi:
            step += 1
        if abs(m) + U16_MAX * step < _EXACT_UNITS:
            new_lo, new_hi = math.ldexp(m, e), math.ldexp(m + U16_MAX * step, e)
            if exact_grid(new_lo, new_hi):
                return new_lo, new_hi
    return lo, hi


@functools.lru_cache(maxsize=256)
def exact_grid(lo: float, hi: float) -> bool:
    """Whether ``float32(lo + q * ((hi - lo) / 65535))`` (float64) equals float32 ``q * step + lo`` for every q.

    True when ``step = (hi - lo) / 65535`` and ``lo`` are float32 numbers and every ``lo + q * step`` is an
    integer multiple of a common power of two below 2**24 units: every intermediate is then exact in both
    precisions (with or without fused multiply-add).
    """
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo:
        return False
    step = (hi - lo) / U16_MAX
    with np.errstate(over="ignore"):  # beyond float32's range: not a float32 number, so no exact grid
        if float(np.float32(step)) != step or float(np.float32(lo)) != lo:
            return False
    fs, fl = Fraction(step), Fraction(lo)
    scale = max(fs.denominator, fl.denominator)
    s, m = int(fs * scale), int(fl * scale)
    shift = min((s & -s).bit_length() - 1 if s else 64, (m & -m).bit_length() - 1 if m else 64)
    s, m = s >> shift, m >> shift
    return abs(m) + U16_MAX * s < _EXACT_UNITS


def dequantize_box(codes: npt.NDArray[np.uint16], lo: list[float], hi: list[float]) -> npt.NDArray[np.float32]:
    """Decode :func:`quantize_box`: ``float32(lo + q * ((hi - lo) / 65535))`` computed in float64.

    When every column is on an exact grid (:func:`exact_grid`; meshtool 1.1 writers make it so) the same
    values are computed in float32, about 20x faster.
    """
    if codes.ndim == 2 and all(exact_grid(a, b) for a, b in zip(lo, hi, strict=True)):
        return _dequantize_exact(codes, lo, hi)
    lo_a = np.asarray(lo, dtype=np.float64)
    step = (np.asarray(hi, dtype=np.float64) - lo_a) / U16_MAX
    with np.errstate(over="ignore", invalid="ignore"):  # hostile lo/hi: the reader refuses non-finite results
        result: npt.NDArray[np.float32] = (lo_a + codes.astype(np.float64) * step).astype(np.float32)
    return result


#: Rows per block of the float32 decode (the block stays in the CPU cache between its three passes).
_BLOCK_ROWS = 8192


def _dequantize_exact(codes: npt.NDArray[np.uint16], lo: list[float], hi: list[float]) -> npt.NDArray[np.float32]:
    """``q * step + lo`` in float32, block by block over the flat array (columns repeat with period ``cols``).

    Numpy's broadcasting over a 3-wide last axis runs a 3-element inner loop; the flat blocks with tiled
    per-column constants run contiguous SIMD loops instead.
    """
    rows, cols = codes.shape
    block_rows = min(rows, _BLOCK_ROWS)
    block = block_rows * cols
    step = np.array([(b - a) / U16_MAX for a, b in zip(lo, hi, strict=True)], dtype=np.float32)
    step_tile = np.tile(step, block_rows)
    lo_tile = np.tile(np.array(lo, dtype=np.float32), block_rows)
    flat = codes.reshape(-1)
    out = np.empty(flat.size, dtype=np.float32)
    for start in range(0, flat.size, block):
        chunk = out[start : start + block]
        k = chunk.size
        chunk[...] = flat[start : start + block]
        np.multiply(chunk, step_tile[:k], out=chunk)
        np.add(chunk, lo_tile[:k], out=chunk)
    return out.reshape(rows, cols)


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
