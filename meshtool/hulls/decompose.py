"""Convex decomposition with CoACD, made safe: validated input, manifold repair, a subprocess, a cache.

CoACD can kill its process on bad input and prints to C stdout, so it runs in a child Python process
(:mod:`meshtool.hulls.coacd_worker`) with a timeout and its output silenced; a crash or hang becomes a message
for that part. The child runs in its own process group and dies with this process (it watches its parent
and has a parent-death signal); the job's temporary folder ``meshtool-coacd-*`` is removed on every exit
path: here on success, failure, timeout and exceptions (Ctrl-C), by the child when this process is killed.
The caller shares one time budget across parts (:class:`Budget`). Results are cached under a key made
of the mesh arrays, the options and the versions of meshtool and CoACD, so a second run over unchanged
assets reads the cache. Each entry is a :mod:`meshtool.files.cachefile` envelope naming its key and the digest
of its content: a damaged entry, or one copied from another key, is a miss and is computed again.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from meshtool import __version__
from meshtool.files import cachefile
from meshtool.files.outdir import write_file
from meshtool.files.resolve import read_cache

if TYPE_CHECKING:
    from meshtool.hulls.compute import HullOptions

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def _coacd_version() -> str:
    try:
        return version("coacd")
    except PackageNotFoundError:
        return "missing"


#: CoACD's Monte Carlo tree search iterations per cut. CoACD's own default is 150; obj2mjcf passes 100, and so
#: does meshtool: the same search effort per cut as the tool users compare it with (docs/benchmarks.md, hulls).
MCTS_ITERATIONS = 100


def cache_key(points: FloatArray, faces: IntArray, options: HullOptions) -> str:
    """SHA-256 over the arrays, the result-relevant options and the tool versions."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(points, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(faces, dtype="<i8").tobytes())
    search = {"mcts_iterations": MCTS_ITERATIONS}
    h.update(json.dumps([options.fingerprint(), search, __version__, _coacd_version()], sort_keys=True).encode())
    return h.hexdigest()


def repair(points: FloatArray, faces: IntArray) -> tuple[FloatArray, IntArray, bool]:
    """Merge duplicate vertices with manifold3d and tell whether the result is a closed 2-manifold.

    Returns:
        The (possibly merged) points and faces, and whether they form a manifold.
    """
    import manifold3d

    mesh = manifold3d.Mesh(vert_properties=np.asarray(points, dtype=np.float32), tri_verts=np.asarray(faces, np.uint32))
    merged = mesh.merge()
    ok = bool(manifold3d.Manifold(mesh).status() == manifold3d.Error.NoError)
    if not (ok and merged):
        return points, faces, ok
    out = manifold3d.Manifold(mesh).to_mesh()
    return (
        np.asarray(out.vert_properties, dtype=np.float64)[:, :3],
        np.asarray(out.tri_verts, dtype=np.int64),
        True,
    )


@dataclass(slots=True)
class Budget:
    """Seconds left for decomposing the parts of one asset (a monotonic-clock deadline).

    Args:
        seconds: The whole budget.
    """

    seconds: float
    deadline: float = 0.0

    def __post_init__(self) -> None:
        self.deadline = time.monotonic() + self.seconds

    def left(self) -> float:
        """Seconds left (0 when spent)."""
        return max(0.0, self.deadline - time.monotonic())


def decompose(
    points: FloatArray,
    faces: IntArray,
    options: HullOptions,
    timeout_s: float | None = None,
    problems: list[str] | None = None,
) -> tuple[list[FloatArray], bool, str | None]:
    """Decompose one part into convex pieces.

    Args:
        points: (n, 3) vertices, metres.
        faces: (k, 3) triangles.
        options: Budgets, threshold, seed, timeout and cache folder.
        timeout_s: Seconds this run may take (default ``options.timeout_s``); the caller passes what is
            left of the asset's time budget when that is less.
        problems: When given, a cache entry that exists but was not used (damaged, or answering another
            key) is described here, one line each (:func:`meshtool.files.cachefile.describe`).

    Returns:
        The pieces' points, whether they came from the cache, and a problem description (then no pieces).
    """
    limit = options.timeout_s if timeout_s is None else min(timeout_s, options.timeout_s)
    if not np.isfinite(points).all() or points.shape[0] < 4 or faces.shape[0] < 4:
        return [], False, "mesh is empty, too small or not finite"
    key = cache_key(points, faces, options)
    cached = _read(options.cache_dir, key, problems)
    if cached is not None:
        return cached, True, None
    points, faces, manifold = repair(points, faces)
    mode = "off" if manifold else "auto"  # CoACD's remeshing only where the mesh needs it
    tmp = tempfile.mkdtemp(prefix="meshtool-coacd-")
    try:
        job, out = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        params = {
            "threshold": options.threshold,
            "max_convex_hull": options.max_hulls,
            "preprocess_mode": mode,
            "seed": options.seed,
            "max_ch_vertex": max(options.max_hull_vertices, 4),
            "mcts_iterations": MCTS_ITERATIONS,
        }
        buffer = io.BytesIO()
        np.savez(buffer, points=points, faces=faces, params=np.frombuffer(json.dumps(params).encode(), np.uint8))
        write_file(job, buffer.getvalue())
        returncode, stderr = _run_worker([str(os.getpid()), tmp, str(job), str(out)], limit)
        if returncode is None:
            return [], False, f"CoACD did not finish within {limit:.0f} s"
        if returncode != 0:
            last = (stderr.decode("utf-8", "replace").strip().splitlines() or [f"exit {returncode}"])[-1]
            return [], False, f"CoACD failed ({last[:160]})"
        pieces = _load(read_cache(out))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if not pieces:
        return [], False, "CoACD returned no hulls"
    _write(options.cache_dir, key, pieces)
    return pieces, False, None


def _run_worker(args: list[str], timeout_s: float) -> tuple[int | None, bytes]:
    """Run the worker in its own process group; (exit status or ``None`` on timeout, its stderr).

    The whole group is killed on timeout and on any exception here (Ctrl-C), so no CoACD run survives.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "meshtool.hulls.coacd_worker", *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    finished = False
    try:
        _, stderr = proc.communicate(timeout=max(timeout_s, 0.001))
        finished = True
    except subprocess.TimeoutExpired:
        return None, b""
    finally:
        if not finished:  # timeout, Ctrl-C or any error here: no CoACD run may survive
            _kill_group(proc)
    return proc.returncode, stderr


def _kill_group(proc: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.kill()
    proc.communicate()


def _load(data: bytes | None) -> list[FloatArray]:
    if data is None:
        return []
    with np.load(io.BytesIO(data)) as archive:
        return [np.asarray(archive[f"hull_{k}"], dtype=np.float64) for k in range(len(archive.files))]


#: Entry kinds (:mod:`meshtool.files.cachefile`): CoACD's pieces and the finished hulls of one key never stand in
#: for each other.
PIECES_KIND, HULLS_KIND = "meshtool-decompose-pieces", "meshtool-decompose-hulls"
#: What a cache payload that passed its digests can still raise when it does not hold what it should.
_PAYLOAD_ERRORS = (
    OSError,
    ValueError,
    KeyError,
    TypeError,
    IndexError,
    AttributeError,
    EOFError,
    RecursionError,
    MemoryError,
    zipfile.BadZipFile,
)


def _entry(cache_dir: Path, key: str, suffix: str) -> Path:
    return cache_dir / key[:2] / f"{key}{suffix}"


def _lookup(cache_dir: Path, key: str, suffix: str, kind: str, problems: list[str] | None) -> bytes | None:
    path = _entry(cache_dir, key, suffix)
    found = cachefile.read_entry(path, kind, key)
    if found.problem is not None and problems is not None:
        problems.append(cachefile.describe(path, found.problem))
    return found.payload


def _read(cache_dir: Path | None, key: str, problems: list[str] | None = None) -> list[FloatArray] | None:
    if cache_dir is None:
        return None
    data = _lookup(cache_dir, key, ".npz", PIECES_KIND, problems)
    if data is None:
        return None
    try:
        pieces = _load(data)
    except _PAYLOAD_ERRORS:
        pieces = []
    if not pieces or any(p.ndim != 2 or p.shape[1] != 3 or not np.isfinite(p).all() for p in pieces):
        if problems is not None:
            problems.append(cachefile.describe(_entry(cache_dir, key, ".npz"), "payload is not a decomposition"))
        return None
    return pieces


def _write(cache_dir: Path | None, key: str, pieces: list[FloatArray]) -> None:
    if cache_dir is None:
        return
    buffer = io.BytesIO()
    np.savez(buffer, **{f"hull_{k}": p for k, p in enumerate(pieces)})  # type: ignore[arg-type]
    write_file(_entry(cache_dir, key, ".npz"), cachefile.seal(PIECES_KIND, key, buffer.getvalue()))


def read_hulls(
    cache_dir: Path | None, key: str, problems: list[str] | None = None
) -> list[tuple[FloatArray, IntArray, list[str]]] | None:
    """The finished hulls (vertices, faces, notes) of a part decomposed before with the same key, if cached.

    Stored beside the decomposition (``KEY.hulls.npz``, a :mod:`meshtool.files.cachefile` envelope holding an
    ``.npz``) so that a cached conversion needs neither CoACD nor qhull. A damaged entry, or one that
    answers another key, is a miss; its one-line description is appended to ``problems`` when given.
    """
    if cache_dir is None:
        return None
    data = _lookup(cache_dir, key, ".hulls.npz", HULLS_KIND, problems)
    if data is None:
        return None
    try:
        with np.load(io.BytesIO(data)) as archive:
            notes = json.loads(bytes(archive["notes"]).decode())
            hulls = [
                (
                    np.asarray(archive[f"v_{k}"], dtype=np.float64),
                    np.asarray(archive[f"f_{k}"], dtype=np.int64),
                    [str(n) for n in notes[k]] if isinstance(notes[k], list) else ["?"],
                )
                for k in range(len(notes))
            ]
    except _PAYLOAD_ERRORS:
        hulls = []
    if not _sound(hulls):
        if problems is not None:
            problems.append(cachefile.describe(_entry(cache_dir, key, ".hulls.npz"), "payload is not a hull set"))
        return None
    return hulls


#: The notes a finished hull may carry (``meshtool.hulls.compute._NOTE``); a cached entry with another one is refused.
_HULL_NOTES = frozenset({"thickened", "reduced", "boxed"})


def _sound(hulls: list[tuple[FloatArray, IntArray, list[str]]]) -> bool:
    if any(n not in _HULL_NOTES for _, _, notes in hulls for n in notes):
        return False
    if not hulls or any(v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 for v, f, _ in hulls):
        return False
    if any(not np.isfinite(v).all() for v, _, _ in hulls):
        return False
    return not any(f.size and (f.min() < 0 or f.max() >= len(v)) for v, f, _ in hulls)


def write_hulls(cache_dir: Path | None, key: str, hulls: list[tuple[FloatArray, IntArray, list[str]]]) -> None:
    """Cache the finished hulls of a decomposed part (see :func:`read_hulls`), atomically."""
    if cache_dir is None or not hulls:
        return
    arrays: dict[str, npt.NDArray[np.generic]] = {}
    for k, (vertices, faces, _) in enumerate(hulls):
        arrays[f"v_{k}"] = np.asarray(vertices, dtype=np.float64)
        arrays[f"f_{k}"] = np.asarray(faces, dtype=np.int64)
    arrays["notes"] = np.frombuffer(json.dumps([notes for _, _, notes in hulls]).encode(), np.uint8)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    write_file(_entry(cache_dir, key, ".hulls.npz"), cachefile.seal(HULLS_KIND, key, buffer.getvalue()))
