"""Consumer files: the URDF, SDF and MJCF files that use a mesh, and what they say about it.

A robot or world description that references an OBJ fixes two things the OBJ cannot say: its frame (URDF,
SDFormat and MJCF are all Z-up, and use the mesh's coordinates as they are) and its unit (the file's
``scale``: ``0.001`` means the mesh is in millimetres). :func:`find_consumers` reads the description files
beside the OBJ and in the folders above it up to its model root (or, without a model root, the OBJ's
folder and its parent), and returns every reference to the OBJ with its scale.

Description files are read with the standard XML parser after refusing DTDs and entities (no entity
expansion), and only up to :data:`MAX_BYTES`; a file that does not parse is skipped.
"""

from __future__ import annotations

import os
import re
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

from meshtool.errors import ResolveError
from meshtool.formats import DESCRIPTION_SUFFIXES
from meshtool.modelroot import ModelRoot
from meshtool.resolve import list_names
from meshtool.safeopen import read_file

#: Largest description file read, bytes.
MAX_BYTES = 4 * 1024 * 1024
#: Most description files read per OBJ.
MAX_FILES = 64
SUFFIXES = DESCRIPTION_SUFFIXES  # the formats registry's
_URI = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")


@dataclass(frozen=True, slots=True)
class ConsumerRef:
    """One reference to the mesh in a description file.

    Attributes:
        file: The description file, relative to the OBJ's folder (``../robot.urdf``).
        format: ``urdf``, ``sdf`` or ``mjcf``.
        scale: The (x, y, z) scale the file applies, or ``None`` when it gives none (that is 1 1 1).
        ref: The reference as written.
    """

    file: str
    format: str
    scale: tuple[float, float, float] | None
    ref: str

    def describe(self) -> str:
        """``robot.urdf (URDF, scale 0.001 0.001 0.001)``."""
        scale = " ".join(_num(s) for s in self.scale) if self.scale else "none"
        return f"{self.file} ({self.format.upper()}, scale {scale})"


def search_folders(obj_dir: Path, root: ModelRoot | None) -> list[Path]:
    """Folders searched for description files.

    The OBJ's folder up to the model root and the model root's subfolders (``urdf/``, ``robots/``); without
    a model root, the OBJ's folder, its parent (``model.xml`` beside ``assets/``) and the parent's
    subfolders (``robot/urdf/`` beside ``robot/meshes/``). The temporary folder, the home folder and ``/``
    are never searched (nor their subfolders) unless they hold the OBJ.
    """
    here = Path(os.path.realpath(obj_dir))
    chain = [here, *here.parents]
    inside_root = root is not None and root.folder in chain
    folders = chain[: chain.index(root.folder) + 1] if root is not None and inside_root else chain[:2]
    unsafe = {Path(os.path.realpath(tempfile.gettempdir())), Path(os.path.realpath(Path.home())), Path("/")}
    folders = [f for f in folders if f not in unsafe or f == here]
    top = root.folder if root is not None and inside_root else (chain[1] if len(chain) > 1 else None)
    if top is not None and top in folders:  # pkg/urdf/robot.urdf, robot/urdf/ beside robot/meshes/: subfolders
        subfolders = [top / n for n in list_names(top) if (top / n).is_dir()]
        folders.extend(f for f in subfolders if Path(os.path.realpath(f)) not in folders)
    return folders


def find_consumers(obj: Path, root: ModelRoot | None) -> list[ConsumerRef]:
    """Every reference to ``obj`` in the description files near it, nearest folder first.

    Args:
        obj: The OBJ file.
        root: Its model root, or ``None``.

    Returns:
        The references, in folder order (the OBJ's folder first), then file name order.
    """
    target = Path(os.path.realpath(obj))
    refs: list[ConsumerRef] = []
    read = 0
    for folder in search_folders(obj.parent, root):
        for name in list_names(folder):
            if not name.lower().endswith(SUFFIXES) or read >= MAX_FILES:
                continue
            path = folder / name
            tree = _parse(path)
            if tree is None:
                continue
            read += 1
            shown = Path(os.path.relpath(path, target.parent)).as_posix()
            refs.extend(_references(tree, path, shown, target))
    return refs


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


def _references(tree: ET.Element, path: Path, shown: str, target: Path) -> list[ConsumerRef]:
    tag = tree.tag.lower()
    if tag == "robot":
        return [
            ConsumerRef(shown, "urdf", _scale(m.get("scale")), m.get("filename", ""))
            for m in tree.iter("mesh")
            if _matches(m.get("filename", ""), path.parent, target)
        ]
    if tag == "sdf" or tag == "model":
        out = []
        for mesh in tree.iter("mesh"):
            uri = (mesh.findtext("uri") or "").strip()
            if _matches(uri, path.parent, target):
                out.append(ConsumerRef(shown, "sdf", _scale(mesh.findtext("scale")), uri))
        return out
    if tag == "mujoco":
        return _mjcf_references(tree, path, shown, target)
    return []


def _mjcf_references(tree: ET.Element, path: Path, shown: str, target: Path) -> list[ConsumerRef]:
    compiler = tree.find("compiler")
    base = path.parent
    if compiler is not None:
        folder = compiler.get("meshdir") or compiler.get("assetdir")
        if folder:
            base = base / folder
    defaults: dict[str, tuple[float, float, float] | None] = {}

    def walk(node: ET.Element, name: str, inherited: tuple[float, float, float] | None) -> None:
        mesh = node.find("mesh")
        own = _scale(mesh.get("scale")) if mesh is not None and mesh.get("scale") else inherited
        defaults[name] = own
        for child in node.findall("default"):
            walk(child, child.get("class", name), own)

    top = tree.find("default")
    if top is not None:
        walk(top, "main", None)
    out = []
    for asset in tree.iter("asset"):
        for mesh in asset.findall("mesh"):
            file = mesh.get("file", "")
            if not _matches(file, base, target):
                continue
            scale = _scale(mesh.get("scale")) if mesh.get("scale") else defaults.get(mesh.get("class", "main"))
            out.append(ConsumerRef(shown, "mjcf", scale, file))
    return out


def _matches(ref: str, base: Path, target: Path) -> bool:
    """Whether ``ref`` (relative, ``package://``, ``model://`` or ``file://``) names ``target``."""
    text = ref.strip()
    if not text:
        return False
    uri = _URI.match(text)
    if uri:
        scheme = uri.group(1).lower()
        rest = unquote(text[uri.end() :])
        parts = [p for p in rest.replace("\\", "/").split("/") if p]
        if scheme in ("package", "model"):
            parts = parts[1:]  # the package or model name; the rest is inside it
        return _suffix_matches(parts, target)
    normal = text.replace("\\", "/")
    candidate = Path(normal) if normal.startswith("/") else base / normal
    try:
        if Path(os.path.realpath(candidate)) == target:
            return True
    except (OSError, ValueError):
        return False
    return False


def _suffix_matches(parts: list[str], target: Path) -> bool:
    if not parts:
        return False
    tail = target.parts[-len(parts) :]
    return len(tail) == len(parts) and all(a.casefold() == b.casefold() for a, b in zip(parts, tail, strict=True))


def _scale(text: str | None) -> tuple[float, float, float] | None:
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
