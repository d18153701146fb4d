"""Consumer files: the URDF, SDF and MJCF files that use a mesh, and what they say about it.

A robot or world description that references a mesh fixes two things the mesh cannot say: its frame (URDF,
SDFormat and MJCF are all Z-up, and use the mesh's coordinates as they are) and its unit (the file's
``scale``: ``0.001`` means the mesh is in millimetres).

Where projects keep them: vendors put the model two or more folders above its meshes
(``robots/NAME/robot.xml`` over ``meshes/PART/part.obj`` and ``meshes/convex/PART/part.obj``). The search
walks up from the mesh's folder to its *index root* (:func:`find_index_root`): an explicit ``--model-root``,
else the nearest folder at most :data:`MAX_ROOT_LEVELS` levels up that holds ``package.xml`` (ROS),
``model.config`` / ``model.sdf`` (Gazebo) or ``.git`` / ``.hg`` / ``.svn`` (a repository), or that is a
Python package's top folder (its parent is ``site-packages``: pip-installed models such as dm_control's);
never the temporary folder, the home folder or ``/``. Without one, a urdf model root
(:func:`meshtool.frame.modelroot.find_model_root`) is indexed whole; else the *nearby* search: the folder above the
mesh's folder with its subfolders (``robot/urdf/`` beside ``robot/meshes/``) and, while that holds no
description file, up to :data:`MAX_NEARBY_LEVELS` levels up (level L read L folders deep).

Every description file under the root is read once (:class:`ConsumerIndex`, keyed by root, built on the
first mesh that needs it and reused by every later mesh under the same root): each reference is resolved
to the file it names, so the index maps mesh file -> the consumers using it. It is kept while nothing under
the root changes (each folder's and description file's ``stat`` is checked on every lookup; a folder changed
within :data:`RACY_SECONDS` of being listed is listed again). Bounded by :data:`MAX_FILES`,
:data:`MAX_TOTAL_BYTES`, :data:`MAX_DEPTH` and :data:`MAX_ENTRIES` (``docs/limits.md``).

References resolve as their consumer resolves them: URDF and SDFormat relative to the file, ``package://NAME``
/ ``model://NAME`` in the ancestor folder named ``NAME`` (or whose ``package.xml`` names it, or beside one),
else by the path's tail from inside the folder that package would be; MJCF as MuJoCo does, ``<include
file>`` relative to the main file's folder and spliced in, mesh ``file`` relative to ``<compiler meshdir>``
(else ``assetdir``, else the main file's folder), with ``<default>`` classes' mesh ``scale``.

Description files are read with :func:`meshtool.files.safeopen.read_file` (regular files only, never blocks,
bounded by :data:`MAX_BYTES`) and parsed with the standard XML parser after refusing DTDs and entities (no
entity expansion); a file that does not parse is skipped.
"""

from __future__ import annotations

import copy
import os
import re
import stat
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

from meshtool.errors import ResolveError
from meshtool.files.resolve import list_names
from meshtool.files.safeopen import read_file
from meshtool.findings import Finding, warning
from meshtool.formats import DESCRIPTION_SUFFIXES
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
#: Most ``<include>`` files spliced into one MJCF (nested ones count).
MAX_INCLUDES = 256
#: A folder whose modification time is this close to (or after) the moment it was listed is listed again
#: on the next lookup (file systems with coarse timestamps could otherwise hide a change).
RACY_SECONDS = 2.0
#: Folders whose children are Python packages: such a child is an index root.
PYTHON_PACKAGE_FOLDERS = ("site-packages", "dist-packages")
#: Consumer formats whose loaders never read an OBJ's MTL or the textures it names (MuJoCo: ``docs/findings.md``).
READS_NO_MATERIALS = ("mjcf",)
SUFFIXES = DESCRIPTION_SUFFIXES  # the formats registry's
_URI = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")
_PACKAGE_NAME = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")

Scale = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class ConsumerRef:
    """One reference to the mesh in a description file.

    Attributes:
        file: The description file, relative to the mesh's folder (``../../robots/arm/robot.xml``).
        format: ``urdf``, ``sdf`` or ``mjcf``.
        scale: The (x, y, z) scale the file applies, or ``None`` when it gives none (that is 1 1 1).
        ref: The reference as written.
    """

    file: str
    format: str
    scale: Scale | None
    ref: str

    def describe(self) -> str:
        """``robot.urdf (URDF, scale 0.001 0.001 0.001)``."""
        scale = " ".join(_num(s) for s in self.scale) if self.scale else "none"
        return f"{self.file} ({self.format.upper()}, scale {scale})"

    @property
    def frame(self) -> str:
        """The frame the consumer uses the mesh in: every consumer format is Z-up, so its scale tells them apart.

        ``Z-up, scale 0.001 0.001 0.001`` (no scale reads as ``1 1 1``).
        """
        return "Z-up, scale " + " ".join(_num(s) for s in (self.scale or (1.0, 1.0, 1.0)))

    @property
    def reads_materials(self) -> bool:
        """Whether the consumer's loader reads the OBJ's MTL and textures (MuJoCo's MJCF compiler does not)."""
        return self.format not in READS_NO_MATERIALS


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


@dataclass(frozen=True, slots=True)
class _Use:
    """One mesh reference of a description file, resolved (``mesh``) or, for an unknown package, by tail."""

    file: Path
    format: str
    scale: Scale | None
    ref: str
    mesh: Path | None
    tail: tuple[str, ...] = ()


@dataclass(slots=True)
class _RootIndex:
    """The description files under one root and the meshes they use."""

    root: IndexRoot
    folders: dict[Path, int] = field(default_factory=dict)  # folder -> st_mtime_ns when listed
    files: dict[Path, tuple[int, int, int, int]] = field(default_factory=dict)  # (dev, ino, size, mtime_ns)
    uses: dict[Path, list[_Use]] = field(default_factory=dict)  # mesh (real path) -> uses
    tails: list[_Use] = field(default_factory=list)
    trees: dict[Path, ET.Element | None] = field(default_factory=dict)  # parsed once, copied for each use
    racy: bool = False
    limit: str | None = None  # the limit that stopped the walk, as a sentence
    read_bytes: int = 0


class ConsumerIndex:
    """Index roots -> their description files' mesh references, built lazily and kept while unchanged.

    One instance serves a whole run (the module's :data:`INDEX`): every mesh under one root reuses the same
    index, so each description file is parsed once. ``parsed`` counts the files parsed (tests read it).
    """

    def __init__(self) -> None:
        self._roots: dict[tuple[Path, int], _RootIndex] = {}
        self.parsed = 0

    def lookup(self, obj: Path, root: IndexRoot) -> tuple[list[_Use], _RootIndex]:
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

    def _build(self, root: IndexRoot) -> _RootIndex:
        index = _RootIndex(root)
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
                for use in _uses(tree, path, index, self):
                    if use.mesh is not None:
                        index.uses.setdefault(use.mesh, []).append(use)
                    else:
                        index.tails.append(use)
        return index

    def read_description(self, path: Path, index: _RootIndex) -> ET.Element | None:
        """Parse one description file (recorded for :func:`_current`), within the root's limits.

        A file already read for this root (an ``<include>`` fragment many models share) is not read again:
        a copy of its tree is returned (the caller splices it).
        """
        if path in index.trees:
            kept = index.trees[path]
            return None if kept is None else copy.deepcopy(kept)
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
        return None if tree is None else copy.deepcopy(tree)


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
    shared = _shared_folders()
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


def find_consumers(obj: Path, root: ModelRoot | None, index: ConsumerIndex | None = None) -> list[ConsumerRef]:
    """Every reference to ``obj`` in the description files under its index root, nearest file first.

    Args:
        obj: The mesh file.
        root: Its model root (or an ``explicit`` one from ``--model-root``), or ``None``.
        index: The index to use (default: the run's, :data:`INDEX`).

    Returns:
        The references, ordered by how many folders separate the file from the mesh's folder, then by path.
    """
    refs, _ = consumers_and_limit(obj, root, index)
    return refs


def consumers_and_limit(
    obj: Path, root: ModelRoot | None, index: ConsumerIndex | None = None
) -> tuple[list[ConsumerRef], str | None]:
    """:func:`find_consumers` and the limit that stopped the index (a sentence), or ``None``."""
    iroot = find_index_root(obj.parent, root)
    uses, built = (index or INDEX).lookup(obj, iroot)
    here = Path(os.path.realpath(obj.parent))
    if iroot.kind == "nearby":  # no root: climb while no description file is in sight (robot/urdf/ above)
        shared = _shared_folders()
        level = iroot.depth
        while not built.files and built.limit is None and 0 < level < MAX_NEARBY_LEVELS:
            level += 1
            up = [here, *here.parents][level] if level < len(here.parts) else None
            if up is None or up in shared:
                break
            iroot = IndexRoot(up, "nearby", "", level)
            uses, built = (index or INDEX).lookup(obj, iroot)
        if built.limit is not None and iroot.kind == "nearby":
            return _ranked(uses, here), None  # a heuristic reach, not a root: no warning
    limit = None if built.limit is None else f"{printable_root(iroot)}: {built.limit}"
    return _ranked(uses, here), limit


def _ranked(uses: Sequence[_Use], here: Path) -> list[ConsumerRef]:
    """The uses as references shown relative to ``here``, nearest first, without repeats."""
    seen: set[tuple[str, str, Scale | None]] = set()
    ranked: list[tuple[int, str, ConsumerRef]] = []
    for use in uses:
        shown = Path(os.path.relpath(use.file, here)).as_posix()
        if (shown, use.ref, use.scale) in seen:
            continue
        seen.add((shown, use.ref, use.scale))
        distance = len(Path(shown).parts) - 1  # folders up plus folders down
        ranked.append((distance, shown, ConsumerRef(shown, use.format, use.scale, use.ref)))
    ranked.sort(key=lambda r: (r[0], r[1]))
    return [r[2] for r in ranked]


def printable_root(root: IndexRoot) -> str:
    """``/path/to/root (repository, .git)`` for messages."""
    what = f"{root.kind}, {root.marker}" if root.marker else root.kind
    return f"{root.folder.as_posix()} ({what})"


def frame_conflict(consumers: Sequence[ConsumerRef], path: str | None) -> Finding | None:
    """A ``consumer-frames-differ`` warning when two consumer files use the mesh in different frames.

    One file using the mesh at several scales (a URDF mirroring one STL for two links) places each use
    itself; two files disagreeing leave ``obj2bin`` one frame to choose.

    Args:
        consumers: The mesh's consumers (:func:`find_consumers`).
        path: The mesh as findings name it.

    Returns:
        The warning (naming one file per frame; the first, nearest one is the frame applied), or ``None``.
    """
    if not any(a.file != b.file and a.frame != b.frame for a in consumers for b in consumers):
        return None
    frames: dict[str, ConsumerRef] = {}
    for ref in consumers:
        frames.setdefault(ref.frame, ref)
    listed = "; ".join(f"{ref.file} uses it {frame}" for frame, ref in frames.items())
    first = consumers[0]
    return warning(
        "consumer-frames-differ",
        f"consumers use the mesh in {len(frames)} different frames ({listed}): applied {first.file}'s",
        path,
    )


def _current(index: _RootIndex) -> bool:
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


def _shared_folders() -> set[Path]:
    return {Path(os.path.realpath(tempfile.gettempdir())), Path(os.path.realpath(Path.home())), Path("/")}


def _parse(path: Path) -> ET.Element | None:
    try:
        data = read_file(path, MAX_BYTES)  # regular files only, never blocks, bounded
    except ResolveError:
        return None
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        return None
    try:
        return ET.fromstring(data)
    except (ET.ParseError, LookupError, ValueError):  # also an unknown encoding declaration ('utf0')
        return None


def _uses(tree: ET.Element, path: Path, index: _RootIndex, owner: ConsumerIndex) -> list[_Use]:
    tag = tree.tag.lower()
    if tag == "robot":
        return [
            _resolved(path, "urdf", _scale(m.get("scale")), m.get("filename", ""), path.parent, index)
            for m in tree.iter("mesh")
            if m.get("filename", "").strip()
        ]
    if tag in ("sdf", "model"):
        out = []
        for mesh in tree.iter("mesh"):
            uri = (mesh.findtext("uri") or "").strip()
            if uri:
                out.append(_resolved(path, "sdf", _scale(mesh.findtext("scale")), uri, path.parent, index))
        return out
    if tag == "mujoco":
        return _mjcf_uses(tree, path, index, owner)
    return []  # <mujocoinclude> and other fragments: read as part of the files that include them


def _mjcf_uses(tree: ET.Element, path: Path, index: _RootIndex, owner: ConsumerIndex) -> list[_Use]:
    """MuJoCo's reading: includes spliced in, ``meshdir`` (else ``assetdir``) of the last ``<compiler>``."""
    _splice_includes(tree, path.parent, index, owner, [Path(os.path.realpath(path))], [0])
    meshdir: str | None = None
    assetdir: str | None = None
    for compiler in tree.iter("compiler"):  # several <compiler> elements: later attributes win, as in MuJoCo
        meshdir = compiler.get("meshdir", meshdir)
        assetdir = compiler.get("assetdir", assetdir)
    folder = meshdir if meshdir is not None else assetdir
    base = path.parent / folder if folder else path.parent  # an absolute meshdir replaces the folder
    defaults: dict[str, Scale | None] = {}

    def walk(node: ET.Element, name: str, inherited: Scale | None) -> None:
        mesh = node.find("mesh")
        own = _scale(mesh.get("scale")) if mesh is not None and mesh.get("scale") else inherited
        defaults[name] = own
        for child in node.findall("default"):
            walk(child, child.get("class", name), own)

    for top in tree.findall("default"):
        walk(top, top.get("class", "main"), None)
    out = []
    for asset in tree.iter("asset"):
        for mesh in asset.findall("mesh"):
            file = mesh.get("file", "").strip()
            if not file:
                continue
            scale = _scale(mesh.get("scale")) if mesh.get("scale") else defaults.get(mesh.get("class", "main"))
            out.append(_Use(path, "mjcf", scale, file, _real(base / file.replace("\\", "/"))))
    return out


def _splice_includes(
    node: ET.Element, base: Path, index: _RootIndex, owner: ConsumerIndex, chain: list[Path], count: list[int]
) -> None:
    """Replace every ``<include file>`` below ``node`` by the children of the file's root, recursively.

    ``file`` is relative to the main model's folder ``base`` or, when no such file exists there, to the folder
    of the file that names it (``chain[-1]``), as MuJoCo 4.0.1 reads nested includes (checked by compiling
    both layouts); a file already being spliced (a cycle), missing or unparsable is dropped, as are includes
    past :data:`MAX_INCLUDES`.
    """
    for parent in list(node.iter()):
        for position, child in reversed(list(enumerate(list(parent)))):
            if not isinstance(child.tag, str) or child.tag != "include":
                continue
            parent.remove(child)
            file = child.get("file", "").strip()
            real = _real(base / file) if file else None
            if real is not None and not real.is_file():
                real = _real(chain[-1].parent / file)
            if real is None or real in chain or count[0] >= MAX_INCLUDES:
                continue
            count[0] += 1
            included = owner.read_description(real, index)
            if included is None:
                continue
            _splice_includes(included, base, index, owner, [*chain, real], count)
            for offset, grandchild in enumerate(list(included)):
                parent.insert(position + offset, grandchild)


def _resolved(path: Path, fmt: str, scale: Scale | None, ref: str, base: Path, index: _RootIndex) -> _Use:
    """A URDF/SDF reference as its file names it: relative, ``file://``, ``package://`` or ``model://``."""
    text = ref.strip()
    uri = _URI.match(text)
    if uri is None:
        normal = text.replace("\\", "/")
        return _Use(path, fmt, scale, ref, _real(Path(normal) if normal.startswith("/") else base / normal))
    scheme = uri.group(1).lower()
    rest = unquote(text[uri.end() :]).replace("\\", "/")
    parts = [p for p in rest.split("/") if p]
    if scheme == "file":
        return _Use(path, fmt, scale, ref, _real(Path("/" + "/".join(parts))))
    if scheme in ("package", "model"):
        name, _, inner = rest.partition("/")
        parts = [p for p in inner.split("/") if p]  # package:///x: the robot's own package, by the tail
        folder = _named_ancestor(path.parent, name, index.root.folder) if name else None
        if folder is not None:
            return _Use(path, fmt, scale, ref, _real(folder.joinpath(*parts)))
    return _Use(path, fmt, scale, ref, None, tuple(parts))


def _named_ancestor(start: Path, name: str, top: Path) -> Path | None:
    """The package or model folder ``name`` as ROS and Gazebo find it from ``start``, up to ``top``.

    A folder at or above ``start`` named ``name`` or whose ``package.xml`` names it, or a folder ``name``
    beside one of them (``src/pkg`` beside ``src/robot_description``, as
    :func:`meshtool.files.resolve.find_package_dir`).
    """
    if name in (".", "..") or "\x00" in name:
        return None
    for folder in [start, *start.parents]:
        if folder.name == name:
            return folder
        if folder != start and (folder / name).is_dir():
            return Path(os.path.realpath(folder / name))
        marker = folder / "package.xml"
        if marker.is_file():
            try:
                found = _PACKAGE_NAME.search(read_file(marker, 1 << 20))
            except ResolveError:
                found = None
            if found and found.group(1).decode("utf-8", "replace") == name:
                return folder
        if folder == top:
            break
    return None


def _real(path: Path) -> Path | None:
    try:
        return Path(os.path.realpath(path))
    except (OSError, ValueError):
        return None


def _tail_matches(parts: Sequence[str], target: Path) -> bool:
    if not parts:
        return False
    tail = target.parts[-len(parts) :]
    return len(tail) == len(parts) and all(a.casefold() == b.casefold() for a, b in zip(parts, tail, strict=True))


def _scale(text: str | None) -> Scale | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        return None
    if len(values) == 1:
        values = values * 3
    if len(values) != 3:
        return None
    return (values[0], values[1], values[2])


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text
