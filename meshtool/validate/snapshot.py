"""What an asset's folder holds: the names (with case), kinds, permissions and link targets of every entry.

An OBJ's check can look at any file under its folder: references are resolved by exact path, ignoring case,
by file name, through symbolic links (see :mod:`meshtool.files.resolve`); a file appearing, disappearing, changing
case, becoming unreadable or a link pointing elsewhere can change the result without changing a byte of
what the check read. The cache therefore keys a result on this listing as well as on the SHA-256 of every
file read (:mod:`meshtool.validate.cache`), and the Dask executor ships the folder's files with it
(:mod:`meshtool.validate.ship`).

An OBJ's result also depends on folders above it (:mod:`meshtool.frame.modelroot`, :mod:`meshtool.frame.consumers`):
a model-root marker (``package.xml``, ``model.config`` up to :data:`meshtool.frame.modelroot.MAX_MARKER_LEVELS`
folders up, a URDF up to :data:`meshtool.frame.modelroot.MAX_LEVELS`) opens the whole model root to references,
and description files (URDF, SDF, MJCF) there say the mesh's unit and frame. :func:`dependency_listings`
covers those: the OBJ's folder and the model root recursively, and in each folder above the OBJ the markers
and description files (names and SHA-256).

Consumers may sit further away, anywhere under the mesh's *index root*
(:func:`meshtool.frame.consumers.find_index_root`: ``robots/NAME/robot.xml`` over ``meshes/PART/part.obj``
below one repository). :func:`consumer_state` is what
the description files there say about one mesh: the root, every reference to the mesh (file, format, scale,
the reference as written), the limit that stopped the index, and each consumer file's SHA-256. It is part of
the cache key, so a result is checked again when a file that uses the mesh changes (or one starts or stops
using it), and not when a description file that does not use it changes.

The listing does not follow links into folders (a link is recorded with its target) and stops at
:data:`MAX_ENTRIES` entries: an asset in a bigger folder is checked but not cached. The cache folder is left
out when it lies inside (its entries change with every run).
"""

from __future__ import annotations

import hashlib
import os
import stat
from dataclasses import dataclass
from pathlib import Path

from meshtool.errors import MeshtoolError
from meshtool.files.safeopen import read_file
from meshtool.frame.consumers import SUFFIXES as DESCRIPTION_SUFFIXES
from meshtool.frame.consumers import consumers_and_limit, find_index_root, printable_root
from meshtool.frame.modelroot import MARKERS, MAX_LEVELS, MAX_MARKER_LEVELS, find_model_root

#: Entries listed under one asset folder at most (beyond: no listing, so the result is not cached).
MAX_ENTRIES = 20_000


@dataclass(frozen=True, slots=True)
class Entry:
    """One entry under the folder.

    Attributes:
        path: Relative to the folder, ``/``-separated, with its case.
        kind: ``file``, ``dir``, ``link`` or ``other`` (FIFO, socket, device).
        detail: The link target for a link, else the permission bits in octal.
    """

    path: str
    kind: str
    detail: str


def is_description(name: str) -> bool:
    """Whether a file name is a model-root marker or a description file that can name the mesh."""
    return name in MARKERS or name.lower().endswith(DESCRIPTION_SUFFIXES)


def _content(path: str) -> str:
    """``sha256:...`` of a description file's bytes (``unreadable`` when it cannot be read)."""
    try:
        return "sha256:" + hashlib.sha256(read_file(Path(path), 64 * 1024 * 1024)).hexdigest()
    except (MeshtoolError, OSError):  # a refusal (special file, too big, gone) is a state like any other
        return "unreadable"


def listing(
    folder: Path, limit: int = MAX_ENTRIES, recursive: bool = True, exclude: Path | None = None
) -> list[Entry] | None:
    """Every entry under ``folder`` in sorted order, or ``None`` when there are more than ``limit``.

    Description files (:func:`is_description`) carry their content hash in ``detail``. A folder that cannot
    be listed (missing, no permission) is recorded as having no entries.

    Args:
        folder: The folder.
        limit: Most entries.
        recursive: Also list subfolders (else only the description files of ``folder`` itself).
        exclude: A folder left out (the cache).
    """
    out: list[Entry] = []
    skip = str(exclude) if exclude is not None else None
    stack = [""]
    while stack:
        rel = stack.pop()
        try:
            with os.scandir(folder / rel if rel else folder) as it:
                items = sorted(it, key=lambda e: e.name)
        except OSError:
            continue
        for item in items:
            path = f"{rel}/{item.name}" if rel else item.name
            if item.path == skip or (not recursive and not is_description(item.name)):
                continue
            try:
                mode = item.stat(follow_symlinks=False).st_mode
            except OSError:
                continue
            if stat.S_ISLNK(mode):
                try:
                    target = os.readlink(item.path)
                except OSError:
                    target = "?"
                out.append(Entry(path, "link", target))
            elif stat.S_ISDIR(mode):
                out.append(Entry(path, "dir", oct(mode & 0o7777)))
                if recursive:
                    stack.append(path)
            elif stat.S_ISREG(mode):
                content = f" {_content(item.path)}" if is_description(item.name) else ""
                out.append(Entry(path, "file", oct(mode & 0o7777) + content))
            else:
                out.append(Entry(path, "other", oct(mode & 0o7777)))
            if len(out) > limit:
                return None
    out.sort(key=lambda e: e.path)
    return out


def listing_digest(key: str, exclude: Path | None = None) -> str | None:
    """SHA-256 of the listing a key names (``tree:FOLDER`` or ``dir:FOLDER``); ``None``: too many entries."""
    mode, _, folder = key.partition(":")
    entries = listing(Path(folder), recursive=mode == "tree", exclude=exclude)
    if entries is None:
        return None
    text = "\n".join(f"{e.kind}\0{e.path}\0{e.detail}" for e in entries)
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()


def dependency_listings(obj: Path, exclude: Path | None = None) -> dict[str, str | None]:
    """Listing key -> digest for every folder an OBJ's check can look into (see the module docstring)."""
    here = Path(os.path.realpath(obj.parent))
    keys = [f"tree:{here}"]
    root = find_model_root(here)
    if root is not None and root.folder != here:
        keys.append(f"tree:{root.folder}")
    keys.extend(f"dir:{folder}" for folder in [here, *here.parents][1 : max(MAX_LEVELS, MAX_MARKER_LEVELS) + 1])
    return {key: listing_digest(key, exclude) for key in keys}


def consumer_state(obj: Path, contents: dict[Path, str] | None = None) -> str:
    """SHA-256 (hex) of what the description files under ``obj``'s index root say about it (see the module).

    Args:
        obj: The mesh file.
        contents: Description file (real path) -> ``sha256:...``, filled and reused across the meshes of a run
            (each consumer file is hashed once).
    """
    here = Path(os.path.realpath(obj.parent))
    model_root = find_model_root(here)
    refs, limit = consumers_and_limit(obj, model_root)
    known = {} if contents is None else contents
    lines = [printable_root(find_index_root(here, model_root)), limit or ""]
    for ref in refs:  # nearest first, then by path: a stable order
        scale = "" if ref.scale is None else " ".join(repr(float(v)) for v in ref.scale)
        real = Path(os.path.realpath(here / ref.file))
        if real not in known:
            known[real] = _content(str(real))
        lines.append(f"{ref.file}\0{ref.format}\0{scale}\0{ref.ref}\0{known[real]}")
    return hashlib.sha256("\n".join(lines).encode("utf-8", "surrogateescape")).hexdigest()
