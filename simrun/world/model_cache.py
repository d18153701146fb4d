"""Compiled-model cache: a world compiled once loads from MuJoCo's binary model (MJB) while nothing changed.

A world's model depends on its options, its entities (every field), its asset table, the files its
entities read (``.mbin`` meshes, PNG textures) and the code that builds and compiles it (MuJoCo, simrun,
meshtool). Two keys, both SHA-256:

* the *description* key (:meth:`ModelCache.key`) over the format, the MuJoCo, simrun and meshtool versions,
  the content of simrun's and meshtool's model-building sources, the base folder relative names are
  resolved against, the options, the asset table and every entity's type and fields. It names the entry
  (``DIR/KEY.mjb``) and is the key its :mod:`meshtool.files.cachefile` envelope must answer;
* the *content* key over the description key and, for every file an entity field or the asset table
  names (relative to the base folder), the real path it resolves to (symbolic links followed), its size
  and its XXH3-128 content hash. The entry records it; an entry of another content key is a miss.

Paths and modification times decide nothing: the same bytes written again still hit, other bytes under
the same name miss, a symbolic link pointed elsewhere misses. A world whose build read a file that no
field names is not stored (its dependencies would not all be in the key). Anything else is a miss and the
world compiles as usual, after which the entry is (re)written. A hit gives the same model, byte for byte
in MJB form, as compiling (tests/test_model_cache.py checks).

Only worlds whose entities read files solely through the world's :class:`~simrun.world.assets.AssetLibrary` are
cached (:data:`CACHEABLE`: meshes, shapes, ground, sky, lights, cameras); a world with any other entity
(robots, height fields, URDF models) or with meshes registered from memory always compiles.

Enable it with ``SIMRUN_MODEL_CACHE=DIR`` in the environment or ``world.model_cache = ModelCache(DIR)``.
Entries are written atomically (a temporary file in the folder, then a rename). A damaged entry, one
copied from another world's key, or one whose payload is not a model is a miss, never an error or
another model; :attr:`ModelCache.problems` describes each, one line.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import mmap
import os
import stat
import struct
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import xxhash

from meshtool.files import cachefile

if TYPE_CHECKING:
    from simrun.world.world import World

#: Entry format; bump when what an entry holds changes.
FORMAT = 2
#: Entry kind in the :mod:`meshtool.files.cachefile` envelope.
KIND = "simrun-compiled-model"
#: Largest entry read, bytes.
MAX_ENTRY_BYTES = 1 << 30
#: Entity types whose builds read files only through the world's AssetLibrary (by class name and module).
CACHEABLE = frozenset(
    {
        ("simrun.entities.mesh_entity", "MeshEntity"),
        ("simrun.entities.shapes", "Box"),
        ("simrun.entities.shapes", "Sphere"),
        ("simrun.entities.shapes", "Capsule"),
        ("simrun.entities.shapes", "Cylinder"),
        ("simrun.entities.environment", "Ground"),
        ("simrun.entities.environment", "Sky"),
        ("simrun.entities.environment", "Light"),
        ("simrun.entities.environment", "Camera"),
    }
)
#: Source folders whose files' content shapes a compiled model (part of the description key).
_CODE_ROOTS = ("simrun", "meshtool")
_HEADER_LENGTH = struct.Struct("<I")


def default() -> ModelCache | None:
    """The cache named by ``SIMRUN_MODEL_CACHE`` (a folder), or ``None`` when it is unset or empty.

    One :class:`ModelCache` per folder and process, so the command line can report every entry it found but
    did not use (:func:`notes`) once the command is done.
    """
    folder = os.environ.get("SIMRUN_MODEL_CACHE", "")
    if not folder:
        return None
    if folder not in _OPEN:
        _OPEN[folder] = ModelCache(Path(folder))
    return _OPEN[folder]


def notes() -> list[str]:
    """Each cache entry this process found but did not use (damaged, answering another key), once; cleared."""
    found = [problem for cache in _OPEN.values() for problem in cache.problems]
    for cache in _OPEN.values():
        cache.problems.clear()
    return found


#: The caches :func:`default` opened in this process, by folder.
_OPEN: dict[str, ModelCache] = {}


@functools.cache
def _code_digest() -> str:
    """SHA-256 over the name and content of every source file of the packages that build models."""
    here = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for root in _CODE_ROOTS:
        for path in sorted((here / root).rglob("*.py")):
            h.update(f"{path.relative_to(here).as_posix()}\0".encode())
            h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def _file_digest(path: Path | str) -> tuple[int, str] | None:
    """(size, XXH3-128 hex) of a regular file's content (memory-mapped), ``None`` when it cannot be read."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except (OSError, ValueError):
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


def _named(world: World) -> list[str]:
    """Every text an entity field or the asset table holds that could name a file (sorted, unique)."""
    names = {str(v) for v in world.assets.values()}
    for _, entity in world:
        for item in dataclasses.fields(entity):
            if item.name in ("name", "parent"):  # entity names, never files
                continue
            value = getattr(entity, item.name)
            if isinstance(value, str | Path) and str(value):
                names.add(str(value))
                if str(value) in world.assets:
                    names.add(str(world.assets[str(value)]))
    return sorted(names)


@dataclasses.dataclass(frozen=True, slots=True)
class _Content:
    """The content key of a world and the real paths of the files it covers."""

    key: str
    files: frozenset[str]
    record: list[list[Any]]


class ModelCache:
    """A folder of compiled models (``KEY.mjb``, each a :mod:`meshtool.files.cachefile` envelope).

    Args:
        folder: Where entries live (created on first store).

    Attributes:
        hits: Lookups answered from the folder.
        misses: Lookups of cacheable worlds that compiled.
        problems: One line per entry found but not used because it was damaged, answered another key or
            held no model (an entry made for other file contents is an ordinary miss, not a problem).
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.hits = 0
        self.misses = 0
        self.problems: list[str] = []
        self._code = _code_digest()
        self._pending: tuple[World, str, _Content] | None = None

    def key(self, world: World) -> str | None:
        """The description key of a world (hex), ``None`` when the world cannot be cached."""
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
        return hashlib.sha256("\n".join(parts).encode("utf-8", "surrogateescape")).hexdigest()

    def _content(self, world: World, description: str) -> _Content:
        base = Path(world.base_dir)
        digests: dict[str, tuple[int, str] | None] = {}
        record: list[list[Any]] = []
        for name in _named(world):
            try:
                candidate = base / name
                real = os.path.realpath(candidate) if os.path.exists(candidate) else None
            except (OSError, ValueError):
                real = None
            if real is not None and real not in digests:
                digests[real] = _file_digest(real)
            found = digests.get(real) if real is not None else None
            record.append([name, real, *found] if found is not None else [name, None])
        text = json.dumps([description, record], ensure_ascii=True)
        covered = frozenset(real for real, found in digests.items() if found is not None)
        return _Content(hashlib.sha256(text.encode()).hexdigest(), covered, record)

    def _entry(self, key: str) -> Path:
        return self.folder / f"{key}.mjb"

    def load(self, world: World) -> mujoco.MjModel | None:
        """The cached model of ``world`` when its entry is sound, answers its key and every file is unchanged.

        A world rebuilt after its first compile (its asset library already holds files) is not looked up.
        """
        from simrun.world.assets import AssetLibrary

        self._pending = None
        key = self.key(world)
        library = getattr(world, "_assets", None)
        if key is None or (isinstance(library, AssetLibrary) and read_files(library)):
            return None  # a rebuild reuses the files in memory, which the key (the files on disk) may not show
        content = self._content(world, key)
        self._pending = (world, key, content)
        path = self._entry(key)
        found = cachefile.read_entry(path, KIND, key, MAX_ENTRY_BYTES)
        model = None
        if found.payload is not None:
            model = self._model(found.payload, content.key, path)
        elif found.problem is not None:
            self.problems.append(cachefile.describe(path, found.problem))
        if model is None:
            self.misses += 1
            return None
        self.hits += 1
        return model

    def _model(self, payload: bytes, content_key: str, path: Path) -> mujoco.MjModel | None:
        """The model in a sound entry's payload, ``None`` when it was made for other content or is not one."""
        try:
            (length,) = _HEADER_LENGTH.unpack_from(payload)
            header = json.loads(payload[_HEADER_LENGTH.size : _HEADER_LENGTH.size + length])
            if header["format"] != FORMAT:
                raise ValueError(f"format {header['format']!r}")
            if header["content"] != content_key:
                return None  # an input changed since the entry was made: an ordinary miss
            return _from_mjb(memoryview(payload)[_HEADER_LENGTH.size + length :])
        except (struct.error, ValueError, KeyError, TypeError, IndexError, RecursionError):
            self.problems.append(cachefile.describe(path, "payload is not a compiled model"))
            return None

    def store(self, world: World, model: mujoco.MjModel, files: list[Path]) -> bool:
        """Record ``model`` (just compiled from ``world``, having read ``files``); False when not stored.

        Stored only right after a :meth:`load` of the same world that missed. Not stored: a world that cannot
        be cached, a rebuild (its files were read into memory by an earlier build, and may be older than the
        files on disk), one whose build read a file no field names, one whose files changed while it
        compiled, and anything when the cache folder cannot be written.
        """
        pending, self._pending = self._pending, None
        key = self.key(world)
        if key is None or pending is None or pending[0] is not world or pending[1] != key:
            return False
        after = self._content(world, key)
        if after.key != pending[2].key or not {os.path.realpath(p) for p in files} <= after.files:
            return False
        header = json.dumps(
            {"format": FORMAT, "content": after.key, "mujoco": mujoco.__version__, "files": after.record}
        ).encode()
        payload = _HEADER_LENGTH.pack(len(header)) + header + model_bytes(model)
        if len(payload) + cachefile.HEADER_BYTES > MAX_ENTRY_BYTES:
            return False
        return cachefile.write_entry(self._entry(key), KIND, key, payload)


def _from_mjb(mjb: memoryview) -> mujoco.MjModel:
    """A model from MJB bytes already checked.

    Through an anonymous in-memory file where the system has them (MuJoCo reads a file five times faster
    than its virtual file system), else the virtual file system.

    Raises:
        ValueError: MuJoCo cannot load the bytes.
    """
    memfd_create = getattr(os, "memfd_create", None)
    if memfd_create is not None and os.path.isdir("/proc/self/fd"):
        try:
            fd = memfd_create("simrun-model", getattr(os, "MFD_CLOEXEC", 0))
        except OSError:
            fd = -1
        if fd >= 0:
            try:
                done = 0
                while done < len(mjb):
                    done += os.write(fd, mjb[done:])
                return mujoco.MjModel.from_binary_path(f"/proc/self/fd/{fd}")
            except OSError:
                pass  # no room for the copy (a file-size limit): the virtual file system below
            finally:
                os.close(fd)
    return mujoco.MjModel.from_binary_path("entry.mjb", {"entry.mjb": bytes(mjb)})


def model_bytes(model: mujoco.MjModel) -> bytes:
    """A model in MuJoCo's binary format (MJB): equal bytes mean equal models."""
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def read_files(assets: Any) -> list[Path]:
    """The files the builds of a world read through its :class:`~simrun.world.assets.AssetLibrary` (imports too)."""
    return [*assets.files, *assets.images, *sorted(assets.sources)]
