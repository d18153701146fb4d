"""Compiled-model cache: a world compiled once loads from MuJoCo's binary model (MJB) while nothing changed.

A world's model depends on its options, its entities (every field), its asset table, the files its
entities read (``.mbin`` meshes, PNG textures) and the code that builds and compiles it (MuJoCo, simrun,
meshtool). The cache entry of a world is found by a key over everything but the files (the *description*);
the entry records the files the build read with their size and XXH3-128 content hash, and is used only
while every one of them still has that content. Anything else is a miss and the world compiles as usual,
after which the entry is (re)written. A hit gives the same model, byte for byte in MJB form, as compiling
(tests/test_model_cache.py checks).

Only worlds whose entities read files solely through the world's :class:`~simrun.assets.AssetLibrary` are
cached (:data:`CACHEABLE`: meshes, shapes, ground, sky, lights, cameras); a world with any other entity
(robots, height fields, URDF models) or with meshes registered from memory always compiles.

Enable it with ``SIMRUN_MODEL_CACHE=DIR`` in the environment or ``world.model_cache = ModelCache(DIR)``.
Entries are written atomically; a damaged or foreign entry is a miss, never an error.
"""

from __future__ import annotations

import hashlib
import json
import mmap
import os
import stat
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import xxhash

if TYPE_CHECKING:
    from simrun.world import World

#: Entry format; bump when what an entry holds changes.
FORMAT = 1
#: Entity types whose builds read files only through the world's AssetLibrary (by class name and module).
CACHEABLE = frozenset(
    {
        ("simrun.mesh_entity", "MeshEntity"),
        ("simrun.shapes", "Box"),
        ("simrun.shapes", "Sphere"),
        ("simrun.shapes", "Capsule"),
        ("simrun.shapes", "Cylinder"),
        ("simrun.environment", "Ground"),
        ("simrun.environment", "Sky"),
        ("simrun.environment", "Light"),
        ("simrun.environment", "Camera"),
    }
)
#: Source files whose content shapes a compiled model (their sizes and times are part of the key).
_CODE_ROOTS = ("simrun", "meshtool", "meshtool/packfile")


def default() -> ModelCache | None:
    """The cache named by ``SIMRUN_MODEL_CACHE`` (a folder), or ``None`` when it is unset or empty."""
    folder = os.environ.get("SIMRUN_MODEL_CACHE", "")
    return ModelCache(Path(folder)) if folder else None


def _code_stamp() -> str:
    """Size and modification time of every source file of the packages that build models."""
    here = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for root in _CODE_ROOTS:
        for path in sorted((here / root).glob("*.py")):
            st = path.stat()
            h.update(f"{path.name}:{st.st_size}:{st.st_mtime_ns};".encode())
    return h.hexdigest()


def _file_digest(path: Path) -> tuple[int, str] | None:
    """(size, XXH3-128 hex) of a regular file's content (memory-mapped), ``None`` when it cannot be read."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return None
        if st.st_size == 0:
            return 0, xxhash.xxh3_128_hexdigest(b"")
        with mmap.mmap(fd, 0, access=mmap.ACCESS_READ) as mapped:
            return st.st_size, xxhash.xxh3_128_hexdigest(mapped)
    except (OSError, ValueError):
        return None
    finally:
        os.close(fd)


class ModelCache:
    """A folder of compiled models (``KEY.mjb``) and their dependency records (``KEY.json``).

    Args:
        folder: Where entries live (created on first store).
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.hits = 0
        self.misses = 0
        self._code = _code_stamp()

    def key(self, world: World) -> str | None:
        """The key of a world's description, ``None`` when the world cannot be cached."""
        from meshtool import __version__ as meshtool_version
        from simrun import __version__ as simrun_version

        parts: list[str] = [
            f"format {FORMAT}",
            f"mujoco {mujoco.__version__}",
            f"simrun {simrun_version}",
            f"meshtool {meshtool_version}",
            f"code {self._code}",
            f"base {Path(world.base_dir).resolve()}",
            f"options {world.options!r}",
            f"assets {sorted(world.assets.items())!r}",
        ]
        for full, entity in world:
            cls = type(entity)
            if (cls.__module__, cls.__name__) not in CACHEABLE:
                return None
            parts.append(f"entity {full} {cls.__module__}.{cls.__name__} {entity!r}")
        return hashlib.sha256("\n".join(parts).encode()).hexdigest()

    def load(self, world: World) -> mujoco.MjModel | None:
        """The cached model of ``world`` when its entry exists and every file it read is unchanged."""
        key = self.key(world)
        if key is None:
            return None
        try:
            record = json.loads((self.folder / f"{key}.json").read_text())
            if record.get("format") != FORMAT or record.get("key") != key:
                raise ValueError("foreign entry")
            for path, size, digest in record["files"]:
                if _file_digest(Path(path)) != (size, digest):
                    raise ValueError("a file changed")
            model = mujoco.MjModel.from_binary_path(str(self.folder / f"{key}.mjb"))
        except (OSError, ValueError, KeyError, TypeError):
            self.misses += 1
            return None
        self.hits += 1
        return model

    def store(self, world: World, model: mujoco.MjModel, files: list[Path]) -> bool:
        """Record ``model`` (just compiled from ``world``, having read ``files``); False when not cacheable."""
        key = self.key(world)
        if key is None:
            return False
        entries = []
        for path in sorted({p.resolve() for p in files}):
            digest = _file_digest(path)
            if digest is None:
                return False
            entries.append([str(path), digest[0], digest[1]])
        buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, buffer)
        record = {"format": FORMAT, "key": key, "mujoco": mujoco.__version__, "files": entries}
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            _write_atomic(self.folder / f"{key}.mjb", buffer.tobytes())
            _write_atomic(self.folder / f"{key}.json", json.dumps(record, indent=1).encode())
        except OSError:
            return False
        return True


def _write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)  # gone already when the replace succeeded


def model_bytes(model: mujoco.MjModel) -> bytes:
    """A model in MuJoCo's binary format (MJB): equal bytes mean equal models."""
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def read_files(assets: Any) -> list[Path]:
    """The files the builds of a world read through its :class:`~simrun.assets.AssetLibrary`."""
    return [*assets.files, *assets.images]
