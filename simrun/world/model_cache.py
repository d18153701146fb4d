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
the same name miss, a symbolic link pointed elsewhere misses. A file's hash is taken again only when its
*fingerprint* changed (device, inode, size, modification and status-change times in ns, as the entry
recorded them): a file's content cannot change without its status-change time (``st_ctime_ns``, which no
program sets) moving on, except within the clock tick of the change itself, so a file that changed less
than :data:`RACY_NS` before its fingerprint was taken is hashed at every lookup (git's "racy" rule).
``ModelCache(DIR, hash_inputs=True)`` hashes every file at every lookup instead.

An entry is the envelope around ``XXH3-128 of the rest | u32 header length | header (JSON: format,
content key, MuJoCo version, the files with their fingerprints, the files the build read) | zero padding
to 16 bytes | the MJB``. A hit maps the entry into memory (no read copy), checks the envelope's magic,
version, length and key digest and the XXH3-128 of the payload (instead of the envelope's SHA-256, a tenth
of the cost; the SHA-256 is still written, so :func:`meshtool.files.cachefile.read_entry` reads the entry),
then hands MuJoCo the mapped MJB (``mj_loadModelBuffer``: MuJoCo's one copy into the model's own buffer).
Nothing is written on a hit. A world whose build read a file that no field names is not stored (its
dependencies would not all be in the key). Anything else is a miss and the world compiles as usual, after
which the entry is (re)written. A hit gives the same model, byte for byte in MJB form, as compiling, and
the world the same list of files read (:meth:`~simrun.world.world.World.files_read`; tests/test_model_cache.py
checks both and the simulation that follows).

Only worlds whose entities read files solely through the world's :class:`~simrun.world.assets.AssetLibrary` are
cached (:data:`CACHEABLE`: meshes, shapes, ground, sky, lights, cameras); a world with any other entity
(robots, height fields, URDF models) or with meshes registered from memory always compiles.

Enable it with ``SIMRUN_MODEL_CACHE=DIR`` in the environment or ``world.model_cache = ModelCache(DIR)``.
Entries are written atomically (a temporary file in the folder, then a rename). A damaged entry, one
copied from another world's key, or one whose payload is not a model is a miss, never an error or
another model; :attr:`ModelCache.problems` describes each, one line. As for every cache entry
(:mod:`meshtool.files.cachefile`), the folder must be as trusted as the code: whoever can write it can
write a well-formed entry of any model.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import functools
import glob
import hashlib
import json
import mmap
import os
import stat
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import mujoco
import numpy as np
import numpy.typing as npt
import xxhash

from meshtool.errors import OutputError
from meshtool.files import cachefile
from meshtool.files.outdir import AtomicFile

if TYPE_CHECKING:
    from simrun.world.world import World

#: Entry format; bump when what an entry holds changes.
FORMAT = 3
#: Entry kind in the :mod:`meshtool.files.cachefile` envelope.
KIND = "simrun-compiled-model"
#: Largest entry read, bytes.
MAX_ENTRY_BYTES = 1 << 30
#: A file whose status changed less than this before its fingerprint was taken is hashed at every lookup, ns.
RACY_NS = 2_000_000_000
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
#: The envelope's header (meshtool/files/cachefile.py: magic, version, key SHA-256, payload length, payload SHA-256).
_ENVELOPE = struct.Struct("<8sI32sQ32s")
#: Bytes of the payload's own digest (XXH3-128), at its start.
_DIGEST = 16
#: The first int of every MJB (MuJoCo's ``ID`` in engine_io.c).
_MJB_ID = 54321


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


def _fingerprint(st: os.stat_result, taken: int) -> list[int]:
    """``[device, inode, size, mtime_ns, ctime_ns, taken_ns]`` of a file's status ``st`` read at ``taken`` (ns)."""
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns, taken]


def _trusted(recorded: Any, st: os.stat_result) -> bool:
    """Whether a file whose status is ``st`` still holds the bytes hashed when ``recorded`` was taken."""
    if not isinstance(recorded, list) or len(recorded) != 6:
        return False
    return recorded[:5] == _fingerprint(st, 0)[:5] and recorded[4] < recorded[5] - RACY_NS


def _file_digest(path: Path | str) -> tuple[int, str, list[int]] | None:
    """(size, XXH3-128 hex, fingerprint) of a regular file (memory-mapped), ``None`` when it cannot be read."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except (OSError, ValueError):
        return None
    try:
        taken = time.time_ns()
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return None
        if st.st_size == 0:
            return 0, xxhash.xxh3_128_hexdigest(b""), _fingerprint(st, taken)
        with mmap.mmap(fd, 0, access=mmap.ACCESS_READ) as mapped:
            return st.st_size, xxhash.xxh3_128_hexdigest(mapped), _fingerprint(st, taken)
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
    """The content key of a world, the real paths of the files it covers and their fingerprints."""

    key: str
    files: frozenset[str]
    record: list[list[Any]]
    fingerprints: dict[str, list[int]]


def _real(base: str, name: str, folders: dict[str, str]) -> tuple[str, os.stat_result] | None:
    """The real path of ``base/name`` and its status (links followed), ``None`` when nothing is there.

    One ``lstat`` per plain name in a folder already resolved (``folders``: each folder's real path, filled
    here); a name that is a symbolic link, or holds a folder or ``..``, is resolved in full.
    """
    candidate = os.path.join(base, name)
    try:
        st = os.lstat(candidate)
        head, tail = os.path.split(candidate)
        if stat.S_ISLNK(st.st_mode) or tail in ("", ".", "..") or os.path.normpath(head) != os.path.normpath(base):
            real = os.path.realpath(candidate)
            return real, os.stat(real)
        if head not in folders:
            folders[head] = os.path.realpath(head)
        return os.path.join(folders[head], tail), st
    except (OSError, ValueError):
        return None


class ModelCache:
    """A folder of compiled models (``KEY.mjb``, each a :mod:`meshtool.files.cachefile` envelope).

    Args:
        folder: Where entries live (created on first store).
        hash_inputs: Hash every input file at every lookup (else only those whose fingerprint changed).

    Attributes:
        hits: Lookups answered from the folder.
        misses: Lookups of cacheable worlds that compiled.
        problems: One line per entry found but not used because it was damaged, answered another key or
            held no model (an entry made for other file contents is an ordinary miss, not a problem).
    """

    def __init__(self, folder: Path, hash_inputs: bool = False) -> None:
        self.folder = Path(folder)
        self.hash_inputs = hash_inputs
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

    def _content(self, world: World, description: str, known: dict[str, Any] | None = None) -> _Content:
        """The content key of ``world``, hashing only the files ``known`` cannot vouch for.

        ``known``: real path -> [size, hex, fingerprint] as recorded; a file whose fingerprint is unchanged
        (:func:`_trusted`) keeps its recorded hash, any other is hashed.
        """
        base = str(world.base_dir)
        folders: dict[str, str] = {}
        digests: dict[str, tuple[int, str, list[int]] | None] = {}
        record: list[list[Any]] = []
        for name in _named(world):
            found = _real(base, name, folders)
            real = found[0] if found is not None else None
            if found is not None and real not in digests:
                before = known.get(found[0]) if known is not None and not self.hash_inputs else None
                if before is not None and _trusted(before[2], found[1]):
                    digests[found[0]] = (before[0], before[1], before[2])
                else:
                    digests[found[0]] = _file_digest(found[0])
            digest = digests.get(real) if real is not None else None
            record.append([name, real, digest[0], digest[1]] if digest is not None else [name, None])
        text = json.dumps([description, record], ensure_ascii=True)
        covered = {real: found for real, found in digests.items() if found is not None}
        return _Content(
            hashlib.sha256(text.encode()).hexdigest(),
            frozenset(covered),
            record,
            {real: found[2] for real, found in covered.items()},
        )

    def _entry(self, key: str) -> Path:
        return self.folder / f"{key}.mjb"

    def load(self, world: World) -> mujoco.MjModel | None:
        """The cached model of ``world`` when its entry is sound, answers its key and every file is unchanged.

        On a hit the world's asset library learns the files the compile that made the entry read (what
        :meth:`~simrun.world.world.World.files_read` lists). A world rebuilt after its first compile (its
        asset library already holds files) is not looked up.
        """
        from simrun.world.assets import AssetLibrary

        self._pending = None
        key = self.key(world)
        library = getattr(world, "_assets", None)
        if key is None or (isinstance(library, AssetLibrary) and read_files(library)):
            return None  # a rebuild reuses the files in memory, which the key (the files on disk) may not show
        path = self._entry(key)
        found = None
        with _mapped(path) as entry:
            if entry is not None:
                found = self._hit(world, key, path, entry)
        if found is None:
            if self._pending is None:
                self._pending = (world, key, self._content(world, key))
            self.misses += 1
            return None
        model, files = found
        if isinstance(library, AssetLibrary):
            library.sources.update(Path(p) for p in files)
        self.hits += 1
        return model

    def _hit(self, world: World, key: str, path: Path, entry: memoryview) -> tuple[mujoco.MjModel, list[str]] | None:
        """The model and the files read of a mapped entry when it is sound and current; else ``None``."""
        problem = _envelope_problem(entry, key)
        if problem is not None:
            self.problems.append(cachefile.describe(path, problem))
            return None
        payload = entry[cachefile.HEADER_BYTES :]
        if bytes(payload[:_DIGEST]) != xxhash.xxh3_128_digest(payload[_DIGEST:]):
            self.problems.append(cachefile.describe(path, "content digest mismatch (damaged)"))
            return None
        try:
            (length,) = _HEADER_LENGTH.unpack_from(payload, _DIGEST)
            start = _DIGEST + _HEADER_LENGTH.size
            header = json.loads(bytes(payload[start : start + length]))
            if header["format"] != FORMAT:
                raise ValueError(f"format {header['format']!r}")
            known = {str(real): [size, digest, header["stat"][real]] for _, real, size, digest in _covered(header)}
            files = [str(p) for p in header["read"]]
            mjb = payload[-(-(start + length) // 16) * 16 :]
        except (struct.error, ValueError, KeyError, TypeError, IndexError, RecursionError):
            self.problems.append(cachefile.describe(path, "payload is not a compiled model"))
            return None
        content = self._content(world, key, known)
        self._pending = (world, key, content)
        if content.key != header.get("content"):
            return None  # an input changed since the entry was made: an ordinary miss
        model, why = _from_mjb(mjb)
        if model is None:
            self.problems.append(cachefile.describe(path, f"payload is not a compiled model ({why})"))
            return None
        return model, files

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
        before = pending[2]
        known = {real: [size, digest, before.fingerprints[real]] for _, real, size, digest in _covered(before)}
        after = self._content(world, key, known)
        read = sorted({os.path.realpath(p) for p in files})
        if after.key != before.key or not set(read) <= after.files:
            return False
        header = json.dumps(
            {
                "format": FORMAT,
                "content": after.key,
                "mujoco": mujoco.__version__,
                "files": after.record,
                "stat": before.fingerprints,
                "read": read,
            }
        ).encode()
        start = _DIGEST + _HEADER_LENGTH.size + len(header)
        start += -start % 16
        payload = np.zeros(start + mujoco.mj_sizeModel(model), dtype=np.uint8)  # the MJB saved in place: no copy
        if len(payload) + cachefile.HEADER_BYTES > MAX_ENTRY_BYTES:
            return False
        payload[_DIGEST : _DIGEST + _HEADER_LENGTH.size] = np.frombuffer(_HEADER_LENGTH.pack(len(header)), np.uint8)
        payload[_DIGEST + _HEADER_LENGTH.size : _DIGEST + _HEADER_LENGTH.size + len(header)] = np.frombuffer(
            header, np.uint8
        )
        mujoco.mj_saveModel(model, None, payload[start:])
        payload[:_DIGEST] = np.frombuffer(xxhash.xxh3_128_digest(payload[_DIGEST:].data), np.uint8)
        return _write_entry(self._entry(key), key, payload)


def _write_entry(path: Path, key: str, payload: npt.NDArray[np.uint8]) -> bool:
    """:func:`meshtool.files.cachefile.write_entry` of ``payload`` without copying it into one ``bytes``."""
    digest = hashlib.sha256(payload.data).digest()
    head = _ENVELOPE.pack(cachefile.MAGIC, cachefile.VERSION, cachefile.key_digest(KIND, key), len(payload), digest)
    try:
        target = AtomicFile(path)
    except OutputError:
        return False  # a read-only or full cache folder costs the next run time, nothing else
    try:
        target.write(head)
        target.write(cast(bytes, payload.data))  # a buffer: written as it lies
        target.commit()
    except OutputError:
        return False
    finally:
        target.abort()
    return True


def _covered(content: Any) -> Iterator[tuple[str, str, int, str]]:
    """(name, real path, size, hex) of every file a content record (a :class:`_Content` or a header) covers."""
    record = content.record if isinstance(content, _Content) else content["files"]
    for row in record:
        if len(row) == 4 and row[1] is not None:
            yield str(row[0]), str(row[1]), int(row[2]), str(row[3])


@contextlib.contextmanager
def _mapped(path: Path) -> Iterator[memoryview | None]:
    """The bytes of an entry file, memory-mapped (read-only, pages read ahead); ``None`` when there is none.

    A file that cannot be read, is not a regular file or is larger than :data:`MAX_ENTRY_BYTES` maps as
    ``None`` too (a miss: the entry is written again).
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError):
        yield None
        return
    mapped = view = None
    try:
        st = os.fstat(fd)
        if stat.S_ISREG(st.st_mode) and 0 < st.st_size <= MAX_ENTRY_BYTES:
            flags = mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0)
            mapped = mmap.mmap(fd, st.st_size, flags=flags, prot=mmap.PROT_READ)
            view = memoryview(mapped)
        elif stat.S_ISREG(st.st_mode) and st.st_size == 0:
            view = memoryview(b"")
    except (OSError, ValueError):
        view = None
    finally:
        os.close(fd)
    try:
        yield view
    finally:
        with contextlib.suppress(BufferError):  # a view still held (a traceback's frame): closed when it goes
            if view is not None:
                view.release()
            if mapped is not None:
                mapped.close()


def _envelope_problem(entry: memoryview, key: str) -> str | None:
    """Why a mapped envelope cannot answer ``key``, or ``None`` (worded as :func:`meshtool.files.cachefile.unseal`).

    The payload's SHA-256 is not computed: the payload carries its own XXH3-128.
    """
    if len(entry) < _ENVELOPE.size:
        return f"truncated ({len(entry)} bytes, shorter than the {_ENVELOPE.size}-byte header)"
    magic, version, key_sha, length, _ = _ENVELOPE.unpack_from(entry)
    if magic != cachefile.MAGIC:
        return "not a cache entry (wrong magic)"
    if version != cachefile.VERSION:
        return f"entry format version {version}, this version reads {cachefile.VERSION}"
    if key_sha != cachefile.key_digest(KIND, key):
        return "answers another key (copied from another entry?)"
    if len(entry) - _ENVELOPE.size != length:
        return f"truncated or padded ({len(entry) - _ENVELOPE.size} payload bytes, {length} recorded)"
    if length < _DIGEST + _HEADER_LENGTH.size:
        return "payload is not a compiled model"
    return None


@functools.cache
def _loader() -> Any:
    """MuJoCo's ``mj_loadModelBuffer`` (``mjModel* (const void*, int)``) from the library the bindings use.

    ``None`` where it or ``MjModel._from_model_ptr`` (which takes ownership of the model) is missing.
    """
    if not hasattr(mujoco.MjModel, "_from_model_ptr"):
        return None
    for library in sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*"))):
        try:
            function = ctypes.CDLL(library).mj_loadModelBuffer
        except (OSError, AttributeError):
            continue
        function.restype = ctypes.c_void_p
        function.argtypes = [ctypes.c_void_p, ctypes.c_int]
        return function
    return None


def _from_mjb(mjb: memoryview) -> tuple[mujoco.MjModel | None, str]:
    """A model from MJB bytes whose digest was checked, and why not when ``None``.

    MuJoCo reads the bytes where they lie (the mapped entry): ``mj_loadModelBuffer`` copies them into the
    model once. Its warnings (a payload that is not a model) are collected, not printed. Where that function
    cannot be reached, ``MjModel.from_binary_path`` of an anonymous in-memory file (one more copy), else of
    the virtual file system.
    """
    if len(mjb) < 4 or int.from_bytes(mjb[:4], "little") != _MJB_ID or len(mjb) >= 1 << 31:
        return None, "no MJB header"
    load = _loader()
    if load is not None:
        said: list[str] = []
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(said.append)
        try:
            address = np.frombuffer(mjb, np.uint8).ctypes.data
            pointer = load(address, len(mjb))
        finally:
            mujoco.set_mju_user_warning(previous)
        if not pointer:
            return None, "; ".join(said) or "MuJoCo refused it"
        return mujoco.MjModel._from_model_ptr(pointer), ""
    try:
        return _from_binary_path(mjb), ""
    except ValueError as exc:
        return None, str(exc)


def _from_binary_path(mjb: memoryview) -> mujoco.MjModel:
    """``MjModel.from_binary_path`` of MJB bytes.

    Through an anonymous in-memory file where the system has them (MuJoCo reads a file five times faster than
    its virtual file system), else the virtual file system.

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
