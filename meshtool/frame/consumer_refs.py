"""What one description file (URDF, SDFormat, MJCF) says about the meshes it uses: file, format, scale.

The per-format readers of the consumer index (:mod:`meshtool.frame.consumer_index`). Each reference is
resolved as its consumer resolves it: URDF and SDFormat relative to the file, ``file://`` as an absolute path,
``package://NAME`` / ``model://NAME`` in the ancestor folder named ``NAME`` (or whose ``package.xml`` names it,
or beside one), else kept by the path's tail (matched by the index); MJCF as MuJoCo does
(:mod:`meshtool.files.mjcf_xml`, the reader simrun uses too): ``<include>`` files spliced in MuJoCo's order, a
mesh ``file`` relative to ``<compiler meshdir>`` (``assetdir`` where no ``meshdir`` is given), beside the
included file it came from when not found there, ``strippath`` honoured, with ``<default>`` classes' mesh
``scale``. An include that is missing, unparsable, repeated or past :data:`MAX_INCLUDES` is dropped (MuJoCo
would refuse the model; the rest of it still says which meshes it uses).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import unquote

from meshtool.errors import ResolveError
from meshtool.files.mjcf_xml import (
    MjcfReadError,
    XmlNode,
    asset_file,
    compiler_dirs,
    find_include,
    splice_includes,
    tagged,
    to_nodes,
)
from meshtool.files.safeopen import read_file

#: Most ``<include>`` files spliced into one MJCF (nested ones count).
MAX_INCLUDES = 256
_URI = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")
_PACKAGE_NAME = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")

#: A consumer's (x, y, z) scale of a mesh (``0.001``: the mesh is in millimetres).
Scale = tuple[float, float, float]
#: Reads a description file of the same index root (an MJCF's ``<include>``): its parsed root, or ``None``.
ReadXml = Callable[[Path], Any]


@dataclass(frozen=True, slots=True)
class Use:
    """One mesh reference of a description file, resolved (``mesh``) or, for an unknown package, by tail.

    Attributes:
        file: The description file (absolute).
        format: ``urdf``, ``sdf`` or ``mjcf``.
        scale: The (x, y, z) scale it applies, or ``None`` when it gives none.
        ref: The reference as written.
        mesh: The mesh file it names (symbolic links resolved), or ``None`` when only its tail is known.
        tail: The path's parts inside an unknown package (``("meshes", "m.obj")``).
    """

    file: Path
    format: str
    scale: Scale | None
    ref: str
    mesh: Path | None
    tail: tuple[str, ...] = ()


def description_uses(tree: Any, path: Path, top: Path, read: ReadXml) -> list[Use]:
    """Every mesh reference of the description file ``path`` (parsed: ``tree``), in document order.

    Args:
        tree: Its parsed root (lxml, :func:`meshtool.files.mjcf_xml.parse_xml`); never changed.
        path: The file (absolute).
        top: The index root: ``package://`` folders are looked for up to it.
        read: Reads an included file (MJCF ``<include>``) of the same root.

    Returns:
        The uses; ``[]`` for ``<mujocoinclude>`` and other fragments (read as part of the files that include them).
    """
    tag = tree.tag.lower() if isinstance(tree.tag, str) else ""
    if tag == "robot":
        return [
            _resolved(path, "urdf", parse_scale(m.get("scale")), m.get("filename", ""), path.parent, top)
            for m in tree.iter("mesh")
            if m.get("filename", "").strip()
        ]
    if tag in ("sdf", "model"):
        out = []
        for mesh in tree.iter("mesh"):
            uri = (mesh.findtext("uri") or "").strip()
            if uri:
                out.append(_resolved(path, "sdf", parse_scale(mesh.findtext("scale")), uri, path.parent, top))
        return out
    if tag == "mujoco":
        return _mjcf_uses(tree, path, read)
    return []


#: The top-level MJCF sections that say which mesh files a model reads and at what scale (``<asset>`` and
#: ``<compiler>`` stand only at the top; ``<default>`` gives mesh scales; ``<include>`` brings more of them):
#: bodies, keyframes and actuators of a large model are never converted.
ASSET_SECTIONS = frozenset({"asset", "compiler", "default", "include"})


def _mjcf_uses(tree: Any, path: Path, read: ReadXml) -> list[Use]:
    """MuJoCo's reading: includes spliced in, each ``<asset><mesh file>`` where MuJoCo reads it, its scale."""
    try:
        root = to_nodes(tree, 0, None, str(path), ASSET_SECTIONS)
    except MjcfReadError:  # a namespace: not MJCF (MuJoCo refuses it)
        return []
    main = _real(path)
    main_dir = main.parent if main is not None else path.parent
    seen = {main}
    count = 0

    def include(node: XmlNode, depth: int) -> list[XmlNode] | None:
        nonlocal count
        if node.tag != "include":  # <Include>: MuJoCo refuses it; an element naming nothing here
            return None
        name = node.attrib.get("file", "").strip()
        found = find_include(path.parent, node.include_dir or main_dir, name) if name else None
        real = _real(found) if found is not None else None
        if real is None or real in seen or count >= MAX_INCLUDES:
            return []
        seen.add(real)
        count += 1
        included = read(real)
        if included is None:
            return []
        try:
            return to_nodes(included, 0, real.parent, str(real), ASSET_SECTIONS).children
        except MjcfReadError:
            return []

    splice_includes(root, include)
    dirs = compiler_dirs(root)
    defaults: dict[str, Scale | None] = {}

    def walk(node: XmlNode, name: str, inherited: Scale | None) -> None:
        mesh = next((c for c in node.children if c.tag == "mesh"), None)
        own = parse_scale(mesh.attrib.get("scale")) if mesh is not None and mesh.attrib.get("scale") else inherited
        defaults[name] = own
        for child in node.children:
            if child.tag == "default":
                walk(child, child.attrib.get("class", name), own)

    for top in root.children:
        if top.tag == "default":
            walk(top, top.attrib.get("class", "main"), None)
    out = []
    for asset in tagged(root, "asset"):
        for mesh in asset.children:
            file = mesh.attrib.get("file", "").strip() if mesh.tag == "mesh" else ""
            if not file:
                continue
            given = mesh.attrib.get("scale")
            scale = parse_scale(given) if given else defaults.get(mesh.attrib.get("class", "main"))
            where = asset_file(path.parent, dirs.folder("mesh"), file.replace("\\", "/"), mesh.include_dir, dirs.strip)
            out.append(Use(path, "mjcf", scale, file, _real(where)))
    return out


def _resolved(path: Path, fmt: str, scale: Scale | None, ref: str, base: Path, top: Path) -> Use:
    """A URDF/SDF reference as its file names it: relative, ``file://``, ``package://`` or ``model://``."""
    text = ref.strip()
    uri = _URI.match(text)
    if uri is None:
        normal = text.replace("\\", "/")
        return Use(path, fmt, scale, ref, _real(Path(normal) if normal.startswith("/") else base / normal))
    scheme = uri.group(1).lower()
    rest = unquote(text[uri.end() :]).replace("\\", "/")
    parts = [p for p in rest.split("/") if p]
    if scheme == "file":
        return Use(path, fmt, scale, ref, _real(Path("/" + "/".join(parts))))
    if scheme in ("package", "model"):
        name, _, inner = rest.partition("/")
        parts = [p for p in inner.split("/") if p]  # package:///x: the robot's own package, by the tail
        folder = _named_ancestor(path.parent, name, top) if name else None
        if folder is not None:
            return Use(path, fmt, scale, ref, _real(folder.joinpath(*parts)))
    return Use(path, fmt, scale, ref, None, tuple(parts))


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


def parse_scale(text: str | None) -> Scale | None:
    """A ``scale`` attribute (one number or three) as (x, y, z); ``None`` when absent or malformed."""
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
