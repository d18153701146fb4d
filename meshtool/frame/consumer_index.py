"""The consumer index: every description file under an index root, read once, and the meshes it uses.

Where the search looks (:func:`find_index_root`): an explicit ``--model-root``, else the nearest folder at most
:data:`MAX_ROOT_LEVELS` levels above the mesh's folder that holds ``package.xml`` (ROS), ``model.config`` /
``model.sdf`` (Gazebo) or ``.git`` / ``.hg`` / ``.svn`` (a repository), or that is a Python package's top folder
(its parent is ``site-packages``); never the temporary folder, the home folder or ``/``. Without one, a urdf
model root is indexed whole; else the *nearby* search (:func:`meshtool.frame.consumers.consumers_and_limit`).

:class:`ConsumerIndex` is keyed by root, built on the first mesh that needs it and reused by every later mesh
under the same root: each description file's references (:mod:`meshtool.frame.consumer_refs`) are resolved
to the files they name, so the index maps mesh file -> the uses. It is kept while nothing under the root
changes (each folder's and description file's ``stat`` is checked on every lookup; a folder changed within
:data:`RACY_SECONDS` of being listed is listed again). Bounded by :data:`MAX_FILES`, :data:`MAX_TOTAL_BYTES`,
:data:`MAX_DEPTH` and :data:`MAX_ENTRIES` (``docs/limits.md``).

Description files are read with :func:`meshtool.files.safeopen.read_file` (regular files only, never blocks,
bounded by :data:`MAX_BYTES`) and parsed by :func:`meshtool.files.mjcf_xml.parse_xml` (lxml, no DTD, no
entities, no network; a ``DOCTYPE`` or ``ENTITY`` is refused); a file that does not parse is skipped.
"""

from __future__ import annotations

import os
import stat
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from meshtool.errors import ResolveError
from meshtool.files.mjcf_xml import etree, parse_xml, refuse_declarations
from meshtool.files.resolve import list_names
from meshtool.files.safeopen import read_file
from meshtool.formats import DESCRIPTION_SUFFIXES
from meshtool.frame.consumer_refs import Use, description_uses
from meshtool.frame.modelroot import MARKERS, REPOSITORY_MARKERS, ModelRoot

#: Largest description file read, bytes.
MAX_BYTES = 4 * 1024 * 1024
#: Most description files read under one index root (MJCF ``<include>`` files count).
MAX_FILES = 4096
#: Most bytes of description files read under one index root.
MAX_TOTAL_BYTES = 256 * 1024 * 1024
#: Deepest folder indexed below the root (the root's own files are depth 0).
MAX_DEPTH = 12
#: Most folder entries (files and folders) listed under one index root.
MAX_ENTRIES = 200_000
#: How many folders above the mesh's folder are searched for its index root.
MAX_ROOT_LEVELS = 8
#: Without an index root: how many folders the nearby search climbs (level L indexes L folders deep), and the
#: folder entries it may list at one level (more: it stops climbing, quietly, with what it has).
MAX_NEARBY_LEVELS = 3
MAX_NEARBY_ENTRIES = 20_000
#: A folder whose modification time is this close to (or after) the moment it was listed is listed again
#: on the next lookup (file systems with coarse timestamps could otherwise hide a change).
RACY_SECONDS = 2.0
#: Folders whose children are Python packages: such a child is an index root.
PYTHON_PACKAGE_FOLDERS = ("site-packages", "dist-packages")
SUFFIXES = DESCRIPTION_SUFFIXES  # the formats registry's


@dataclass(frozen=True, slots=True)
class IndexRoot:
    """The folder whose description files are searched for a mesh's consumers.

    Attributes:
        folder: Absolute, symbolic links resolved.
        kind: ``explicit`` (``--model-root``), ``ros``, ``gazebo``, ``repository``, ``python``, ``urdf`` or
            ``nearby`` (no root found: a folder 1 to :data:`MAX_NEARBY_LEVELS` above the mesh's).
        marker: What marks it (``package.xml``, ``.git``, ``site-packages``, ``--model-root``...; ``""``).
        depth: Deepest folder indexed below it (``nearby``: 1, its subfolders; 0 for the temporary or home
            folder, whose own files only are read).
    """

    folder: Path
    kind: str
    marker: str
    depth: int = MAX_DEPTH


@dataclass(slots=True)
class RootIndex:
    """The description files under one root and the meshes they use."""

    root: IndexRoot
    folders: dict[Path, int] = field(default_factory=dict)  # folder -> st_mtime_ns when listed
    files: dict[Path, tuple[int, int, int, int]] = field(default_factory=dict)  # (dev, ino, size, mtime_ns)
    uses: dict[Path, list[Use]] = field(default_factory=dict)  # mesh (real path) -> uses
    tails: list[Use] = field(default_factory=list)
    trees: dict[Path, Any] = field(default_factory=dict)  # parsed once (None: did not parse), never changed
    racy: bool = False
    limit: str | None = None  # the limit that stopped the walk, as a sentence
    read_bytes: int = 0


class ConsumerIndex:
    """Index roots -> their description files' mesh references, built lazily and kept while unchanged.

    One instance serves a whole run (the module's :data:`INDEX`): every mesh under one root reuses the same
    index, so each description file is parsed once. ``parsed`` counts the files parsed (tests read it).
    """

    def __init__(self) -> None:
        self._roots: dict[tuple[Path, int], RootIndex] = {}
        self.parsed = 0

    def lookup(self, obj: Path, root: IndexRoot) -> tuple[list[Use], RootIndex]:
        """The uses of ``obj`` (any path; compared after resolving links) under ``root``.

        A reference to an unknown package (matched by its path's tail) counts only from a description file
        inside the folder that package would be (the mesh's path less the reference's): a package holds the
        files that name it, so another project's ``package://x/meshes/m.obj`` is not this ``meshes/m.obj``.
        """
        key = (root.folder, root.depth)
        index = self._roots.get(key)
        if index is None or not _current(index):
            index = self._build(root)
            self._roots[key] = index
        target = Path(os.path.realpath(obj))
        found = list(index.uses.get(target, []))
        found.extend(
            u
            for u in index.tails
            if _tail_matches(u.tail, target) and Path(*target.parts[: -len(u.tail)]) in u.file.parents
        )
        return found, index

    def clear(self) -> None:
        """Forget every index (the next lookup reads the files again)."""
        self._roots.clear()

    def _build(self, root: IndexRoot) -> RootIndex:
        index = RootIndex(root)
        started = time.time_ns()
        pending: list[tuple[Path, int]] = [(root.folder, 0)]
        entries = 0
        descriptions: list[Path] = []
        while pending and index.limit is None:
            folder, depth = pending.pop()
            try:
                mtime = os.stat(folder).st_mtime_ns
                with os.scandir(folder) as scan:
                    items = sorted(scan, key=lambda e: e.name)
            except (OSError, ValueError):
                continue
            index.folders[folder] = mtime
            if mtime >= started - int(RACY_SECONDS * 1e9):
                index.racy = True
            entries += len(items)
            budget = MAX_NEARBY_ENTRIES if root.kind == "nearby" else MAX_ENTRIES
            if entries > budget:
                index.limit = f"more than {budget:,} folder entries (MAX_ENTRIES)"
                break
            for item in reversed(items):
                try:
                    if item.is_dir(follow_symlinks=False):
                        if depth < root.depth and not item.name.startswith("."):
                            pending.append((Path(item.path), depth + 1))
                    elif item.name.lower().endswith(SUFFIXES):
                        descriptions.append(Path(item.path))
                except OSError:
                    continue
        for path in sorted(descriptions):
            if index.limit is not None:
                break
            tree = self.read_description(path, index)
            if tree is not None:
                for use in description_uses(tree, path, root.folder, lambda p: self.read_description(p, index)):
                    if use.mesh is not None:
                        index.uses.setdefault(use.mesh, []).append(use)
                    else:
                        index.tails.append(use)
        return index

    def read_description(self, path: Path, index: RootIndex) -> Any:
        """Parse one description file (recorded for :func:`_current`), within the root's limits.

        A file already read for this root (an ``<include>`` fragment many models share) is not read again: its
        kept tree is returned (lxml; ``None``: it did not parse). Callers never change it.
        """
        if path in index.trees:
            return index.trees[path]
        if len(index.files) >= MAX_FILES:
            index.limit = f"more than {MAX_FILES:,} description files (MAX_FILES)"
            return None
        try:
            info = os.stat(path)
        except OSError:
            return None
        if not stat.S_ISREG(info.st_mode):
            return None
        if index.read_bytes + min(info.st_size, MAX_BYTES) > MAX_TOTAL_BYTES:
            index.limit = f"more than {MAX_TOTAL_BYTES // (1024 * 1024)} MiB of description files (MAX_TOTAL_BYTES)"
            return None
        index.files[path] = (info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns)
        if info.st_mtime_ns >= time.time_ns() - int(RACY_SECONDS * 1e9):
            index.racy = True
        tree = _parse(path)
        self.parsed += 1
        index.read_bytes += min(info.st_size, MAX_BYTES)
        index.trees[path] = tree
        return tree


#: The run's index (one per process: obj2bin DIR, validate and their workers each reuse it across meshes).
INDEX = ConsumerIndex()


def find_index_root(obj_dir: Path, model_root: ModelRoot | None = None) -> IndexRoot:
    """The folder searched for the consumers of a mesh in ``obj_dir`` (see the module docstring).

    Args:
        obj_dir: The mesh's folder.
        model_root: Its model root (:func:`meshtool.frame.modelroot.find_model_root`, or an ``explicit`` one
            from ``--model-root``), or ``None``.

    Returns:
        The index root.
    """
    here = Path(os.path.realpath(obj_dir))
    chain = [here, *here.parents]
    if model_root is not None and model_root.kind == "explicit" and model_root.folder in chain:
        return IndexRoot(model_root.folder, "explicit", model_root.marker)
    shared = shared_folders()
    for folder in chain[: MAX_ROOT_LEVELS + 1]:
        if folder in shared:
            break
        names = set(list_names(folder))
        for marker in MARKERS:
            if marker in names and (folder / marker).is_file():
                return IndexRoot(folder, "ros" if marker == "package.xml" else "gazebo", marker)
        for marker in REPOSITORY_MARKERS:
            if marker in names:
                return IndexRoot(folder, "repository", marker)
        if folder.parent.name in PYTHON_PACKAGE_FOLDERS and folder.parent != folder:
            return IndexRoot(folder, "python", folder.parent.name)
    if model_root is not None and model_root.folder in chain and model_root.folder not in shared:
        return IndexRoot(model_root.folder, model_root.kind, model_root.marker)
    parent = chain[1] if len(chain) > 1 else here
    if parent in shared:
        return IndexRoot(here, "nearby", "", 0 if here in shared else 1)
    return IndexRoot(parent, "nearby", "", 1)


def _current(index: RootIndex) -> bool:
    """Whether nothing the index read has changed (folders listed, description files parsed)."""
    if index.racy:
        return False
    for folder, mtime in index.folders.items():
        try:
            if os.stat(folder).st_mtime_ns != mtime:
                return False
        except OSError:
            return False
    for path, sig in index.files.items():
        try:
            info = os.stat(path)
        except OSError:
            return False
        if (info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns) != sig:
            return False
    return True


def shared_folders() -> set[Path]:
    """The folders never taken as an index root: the temporary folder, the home folder, ``/``."""
    return {Path(os.path.realpath(tempfile.gettempdir())), Path(os.path.realpath(Path.home())), Path("/")}


def _parse(path: Path) -> Any:
    """The file's lxml tree, or ``None`` (unreadable, a DTD or entity declared, not well-formed)."""
    try:
        data = read_file(path, MAX_BYTES)  # regular files only, never blocks, bounded
        refuse_declarations(data, str(path))
        return parse_xml(data, str(path))
    except (ResolveError, ValueError, LookupError, etree.LxmlError):  # MjcfReadError is a ValueError
        return None


def _tail_matches(parts: Sequence[str], target: Path) -> bool:
    if not parts:
        return False
    tail = target.parts[-len(parts) :]
    return len(tail) == len(parts) and all(a.casefold() == b.casefold() for a, b in zip(parts, tail, strict=True))
