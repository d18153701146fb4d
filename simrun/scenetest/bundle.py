"""Scene bundles: a scene file and every file it reads, as bytes, so a worker needs no shared folder.

:func:`collect` loads a scene here and notes every file opened for reading while it is read and built
(textures, ``.mbin`` packs, URDFs and their meshes: simrun and meshtool read them all through Python,
which raises the ``open`` audit event). The bundle keeps them by path relative to the deepest folder that
holds the scene and all of them, so relative references (``../urdf/arm.urdf``) work where it is unpacked.
:func:`materialise` writes a bundle into a folder.
"""

from __future__ import annotations

import hashlib
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from simrun.errors import SimrunError
from simrun.safeio import FileReadError, read_regular

#: Largest bundle (all files of one scene together), bytes.
MAX_BUNDLE_BYTES = 512 * 1024 * 1024
_SKIP_SUFFIXES = (".py", ".pyc", ".so", ".pth", ".pyi", ".typed", ".dist-info")
_lock = threading.Lock()
_opened: list[set[str]] = []  # the sets of the collections in progress (audit hooks cannot be removed)
_hooked = False


@dataclass(frozen=True)
class Bundle:
    """A scene and the files it reads.

    Attributes:
        files: Relative POSIX path to bytes (the scene among them).
        scene: The scene's relative path in ``files``.
        digest: SHA-256 over paths and contents (hex): equal bundles have equal digests.
    """

    files: dict[str, bytes]
    scene: str
    digest: str


def _hook(event: str, args: tuple[Any, ...]) -> None:
    if event != "open" or not _opened:
        return
    path = args[0]
    mode = args[1] if len(args) > 1 else None
    flags = args[2] if len(args) > 2 else None
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, str) or (isinstance(mode, str) and any(c in mode for c in "wax+")):
        return
    if isinstance(flags, int) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
        return
    for found in _opened:
        found.add(path)


@contextmanager
def watching() -> Iterator[set[str]]:
    """Within the block, collect the paths of files opened for reading (by Python code)."""
    global _hooked
    with _lock:
        if not _hooked:
            sys.addaudithook(_hook)
            _hooked = True
    found: set[str] = set()
    _opened.append(found)
    try:
        yield found
    finally:
        _opened.remove(found)


def collect(scene: Path, load: Callable[[], Any], extra: tuple[Path, ...] = ()) -> tuple[Bundle, Any]:
    """Run ``load()`` (reading ``scene``) and bundle every regular file it opened, plus ``extra``.

    Python's own files (modules, extensions) and those under the interpreter's prefixes are left out.

    Returns:
        The bundle and what ``load()`` returned.

    Raises:
        SimrunError: A file cannot be read again, or the bundle is over :data:`MAX_BUNDLE_BYTES`.
    """
    with watching() as found:
        result = load()
    prefixes = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    paths = {scene.resolve(), *(p.resolve() for p in extra)}
    # files read relative to an open folder (openat: meshtool's race-free reads) show no full path to the
    # audit hook; a world lists what its builds read
    paths.update(Path(os.path.realpath(p)) for p in getattr(result, "files_read", list)())
    for name in found:
        real = Path(os.path.realpath(name))
        text = str(real)
        if real.suffix in _SKIP_SUFFIXES or any(text.startswith(p + os.sep) for p in prefixes):
            continue
        if text.startswith(("/proc/", "/sys/", "/dev/")) or not real.is_file():
            continue
        paths.add(real)
    root = Path(os.path.commonpath([str(p.parent) for p in paths]))
    files: dict[str, bytes] = {}
    total = 0
    for path in sorted(paths):
        try:
            data = read_regular(path, "file")
        except FileReadError as exc:
            raise SimrunError(str(exc)) from None
        total += len(data)
        if total > MAX_BUNDLE_BYTES:
            raise SimrunError(f"{scene}: the files it reads pass {MAX_BUNDLE_BYTES // 2**20} MiB; tests ship them all")
        files[path.relative_to(root).as_posix()] = data
    return Bundle(files, scene.resolve().relative_to(root).as_posix(), _digest(files)), result


def _digest(files: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for name in sorted(files):
        data = files[name]
        h.update(f"{name}\0{len(data)}\0".encode("utf-8", "surrogateescape"))
        h.update(data)
    return h.hexdigest()


def materialise(bundle: Bundle, folder: Path) -> None:
    """Write the bundle's files under ``folder`` (which must exist); refuses paths that would leave it."""
    for name, data in bundle.files.items():
        rel = PurePosixPath(name)
        if rel.is_absolute() or ".." in rel.parts:
            raise SimrunError(f"bundle path {name!r} leaves its folder")
        target = folder.joinpath(*rel.parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
