"""MJCF files as MuJoCo reads them, without MuJoCo: the one bounded XML parse, include splice and asset lookup.

Two readers use it: simrun's model reader (:mod:`simrun.robots.mjcf_read`: every file read confined, counted and
handed to MuJoCo as bytes) and meshtool's consumer index (:mod:`meshtool.frame.consumer_refs`: which meshes an
MJCF uses, and at which scale). What is MuJoCo's rule lives here once:

- Parsing (:func:`parse_xml`): lxml with no DTD, no entities and no network; a ``DOCTYPE`` or ``ENTITY`` is
  refused (:func:`refuse_declarations` on the bytes, again on the parsed document for UTF-16 files), comments
  and processing instructions dropped. :func:`to_nodes` turns the tree into :class:`XmlNode` (iteratively;
  namespaces are refused: they are not MJCF).
- ``<include>`` (:func:`splice_includes`, :func:`find_include`): each is replaced by the children of the included
  file's root, in MuJoCo's ``mjIncludeXML`` order (``src/xml/xml.cc``: the spliced children are looked at next);
  a relative name is looked for in the main model's folder first, then in the folder of the file that holds the
  ``<include>``. What a refused, missing or repeated include means is the caller's (simrun refuses, the consumer
  index drops it).
- Asset files (:func:`compiler_dirs`, :func:`asset_file`): a mesh, skin, height field or ``<flexcomp>`` ``file``
  relative to ``<compiler meshdir>``, a texture and its cube faces relative to ``texturedir``; per
  ``<compiler>`` element in document order, ``assetdir`` sets both and then ``meshdir`` / ``texturedir`` set
  their own (``src/xml/xml_native_reader.cc``); those folders relative to the main model's folder unless
  absolute; an element of an included file whose file is not found there is looked for beside that included
  file; ``strippath="true"`` keeps the file name alone.
- Confinement (:func:`root_holding`): a file may be read when its real path (symbolic links followed) is a root
  or lies below one.

MuJoCo-free (``tests/test_layering.py``: meshtool never imports simrun or mujoco).
"""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

etree: Any = importlib.import_module("lxml.etree")  # installed with the project (pycollada, yourdfpy); no stubs

#: Attributes that name a file MuJoCo opens.
FILE_ATTRS = ("file", "fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")
#: Elements whose ``file`` is an asset, and the compiler folder (``mesh`` or ``texture``) it is relative to.
ASSET_FOLDER = {"mesh": "mesh", "skin": "mesh", "hfield": "mesh", "flexcomp": "mesh", "texture": "texture"}
#: The refusal of a ``DOCTYPE`` or ``ENTITY`` declaration.
DTD_REFUSED = "a DOCTYPE or ENTITY declaration is not read (entities could read or expand files)"
#: lxml's settings: no DTD, entities or network; long attribute values (inline vertices) are genuine, the
#: depth is bounded by the caller while counting.
PARSER_OPTIONS: dict[str, bool] = {
    "huge_tree": True,
    "resolve_entities": False,
    "no_network": True,
    "load_dtd": False,
    "remove_comments": True,
    "remove_pis": True,
}


class MjcfReadError(ValueError):
    """An MJCF model (or a file it names) is refused: one line ``PATH:LINE: <element> 'name': what; hint``.

    Attributes:
        message: What is wrong.
        path: The XML file the element is in (as the model names it), if known.
        line: 1-based line of the element in ``path``, if known.
        element: The element (``mesh 'arm'``, ``<include>``, ``<option>``), if any.
        hint: How to fix it.
    """

    def __init__(
        self, message: str, *, path: str | None = None, line: int | None = None, element: str = "", hint: str = ""
    ) -> None:
        self.message, self.path, self.line, self.element, self.hint = message, path, line, element, hint
        where = f"{path}:{line}" if path and line else path or ""
        text = ": ".join(x for x in (where, element, message) if x)
        super().__init__((text + (f"; {hint}" if hint else "")).replace("\n", " "))


@dataclass(slots=True, eq=False)
class XmlNode:
    """An XML element of an MJCF model, includes spliced in.

    Attributes:
        tag: The element's name as written.
        attrib: Its attributes, in document order.
        children: Its child elements.
        file: Which XML file it came from (an index into the caller's list of files).
        line: 1-based line in that file (0: unknown).
        include_dir: Folder of the included file it came from (``None``: the main file).
    """

    tag: str
    attrib: dict[str, str]
    children: list[XmlNode]
    file: int
    line: int
    include_dir: Path | None


@dataclass(frozen=True, slots=True)
class CompilerDirs:
    """The asset folders of a spliced model: ``mesh`` and ``texture`` as written (``""``: none), ``strip``."""

    mesh: str = ""
    texture: str = ""
    strip: bool = False

    def folder(self, tag: str) -> str:
        """The folder an element's file is relative to (``mesh`` for meshes, skins, height fields, flexcomps)."""
        return self.texture if ASSET_FOLDER.get(tag) == "texture" else self.mesh


# -- parsing ---------------------------------------------------------------------------------------------------


def pull_parser(events: tuple[str, ...]) -> Any:
    """A streaming lxml parser with :data:`PARSER_OPTIONS` (for counting before any tree is kept)."""
    return etree.XMLPullParser(events=events, **PARSER_OPTIONS)


def refuse_declarations(data: bytes, shown: str) -> None:
    """Refuse a file whose bytes hold a ``DOCTYPE`` or ``ENTITY`` declaration.

    Raises:
        MjcfReadError: It does.
    """
    if b"<!DOCTYPE" in data or b"<!ENTITY" in data:
        raise MjcfReadError(DTD_REFUSED, path=shown, hint="remove the declaration; MJCF needs none")


def parse_xml(data: bytes, shown: str) -> Any:
    """The lxml tree of one XML file (call :func:`refuse_declarations` first, and bound ``data``).

    Args:
        data: The file's bytes.
        shown: The file as messages name it.

    Raises:
        MjcfReadError: Not well-formed XML, or a declaration the byte check missed (a UTF-16 file).
    """
    try:
        root = etree.fromstring(data, parser=etree.XMLParser(**PARSER_OPTIONS))
    except etree.XMLSyntaxError as exc:
        raise syntax_error(exc, shown) from None
    docinfo = root.getroottree().docinfo
    if docinfo.doctype or docinfo.internalDTD is not None:
        raise MjcfReadError(DTD_REFUSED, path=shown, hint="remove the declaration; MJCF needs none")
    return root


def syntax_error(exc: Any, shown: str) -> MjcfReadError:
    """The parser's syntax error as one line; a tag mismatch in tinyxml2's words (MuJoCo's reader says it so)."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    mismatch = re.match(r"Opening and ending tag mismatch: (\S+)", text)
    hint = "fix that element (the XML is not well-formed)"
    if mismatch:
        return MjcfReadError(
            "XML_ERROR_MISMATCHED_ELEMENT", path=shown, line=exc.lineno, element=f"<{mismatch[1]}>", hint=hint
        )
    if "Excessive depth" in text:
        text = "elements nested more than 2,048 deep"
    text = re.sub(r", line \d+, column \d+$", "", text)
    return MjcfReadError(f"not well-formed XML: {text}", path=shown, line=exc.lineno, hint=hint)


def to_nodes(root: Any, file: int, include_dir: Path | None, shown: str, keep: frozenset[str] | None = None) -> XmlNode:
    """The lxml tree ``root`` as :class:`XmlNode` (iteratively); text is dropped.

    Args:
        root: An element of :func:`parse_xml`.
        file: The index its nodes carry.
        include_dir: The folder of the included file it is (``None``: the main file).
        shown: The file as messages name it.
        keep: Only the root's children with these tags (lower case) and their subtrees (``None``: all): a reader
            that needs the assets only skips the bodies, keyframes and actuators of a large model.

    Raises:
        MjcfReadError: An XML namespace (not MJCF) or an entity reference left unresolved.
    """

    def node(element: Any) -> XmlNode:
        tag = element.tag
        if not isinstance(tag, str) or tag.startswith("{") or any(a.startswith("{") for a in element.attrib):
            raise MjcfReadError(
                "XML namespaces are not MJCF",
                path=shown,
                line=element.sourceline,
                element=f"<{etree.QName(element).localname}>",
                hint="remove the namespace prefix",
            )
        return XmlNode(tag, dict(element.attrib), [], file, element.sourceline or 0, include_dir)

    top = node(root)
    stack = [(root, top)]
    while stack:
        element, mine = stack.pop()
        for child in element:
            if not isinstance(child.tag, str):  # an entity reference left unresolved
                raise MjcfReadError(DTD_REFUSED, path=shown, line=child.sourceline, hint="write the text itself")
            if keep is not None and mine is top and child.tag.lower() not in keep:
                continue
            made = node(child)
            mine.children.append(made)
            stack.append((child, made))
    return top


# -- includes --------------------------------------------------------------------------------------------------


def include_candidates(model_dir: Path, including_dir: Path, name: str) -> list[Path]:
    """Where MuJoCo looks for ``<include file=name>``, in order.

    As given if absolute, else in the main model's folder first, then in the folder of the file holding the
    ``<include>``.
    """
    if Path(name).is_absolute():
        return [Path(name)]
    return [Path(model_dir) / name, Path(including_dir) / name]


def find_include(model_dir: Path, including_dir: Path, name: str) -> Path | None:
    """The first of :func:`include_candidates` that exists (a ``stat``: nothing is opened), or ``None``."""
    return next((c for c in include_candidates(model_dir, including_dir, name) if exists(c)), None)


#: An include handler: given an ``<include>``-named node (any letter case) and the depth of its parent (the root
#: is 1), the nodes that replace it (``[]``: dropped), or ``None`` to keep it as an element.
IncludeHandler = Callable[[XmlNode, int], "list[XmlNode] | None"]


def splice_includes(root: XmlNode, include: IncludeHandler) -> None:
    """Replace ``<include>`` elements below ``root`` in MuJoCo's reading order.

    Document order, the spliced children looked at next (so nested includes come in where they stand).

    Args:
        root: The main file's root (changed in place).
        include: Called for every element whose tag is ``include`` in any letter case; it reads the file
            (:func:`find_include`) and returns its root's children (themselves not yet spliced), ``[]`` to drop
            the element, or ``None`` to keep it; it may raise to refuse the model.
    """
    stack: list[tuple[XmlNode, int, int]] = [(root, 0, 1)]  # parent, next child index, depth of parent
    while stack:
        parent, k, depth = stack.pop()
        if k >= len(parent.children):
            continue
        child = parent.children[k]
        replaced = include(child, depth) if child.tag.lower() == "include" else None
        if replaced is None:
            stack.append((parent, k + 1, depth))
            stack.append((child, 0, depth + 1))
            continue
        parent.children[k : k + 1] = replaced  # then the spliced children are looked at from index k
        stack.append((parent, k, depth))


# -- assets ----------------------------------------------------------------------------------------------------


def compiler_dirs(root: XmlNode) -> CompilerDirs:
    """The asset folders of the spliced model.

    Every ``<compiler>`` in document order, each setting ``assetdir`` (both folders) first, then ``meshdir``
    and ``texturedir``; the last ``strippath`` given wins.
    """
    mesh = texture = ""
    strip = False
    for node in tagged(root, "compiler"):
        if "assetdir" in node.attrib:
            mesh = texture = node.attrib["assetdir"]
        mesh = node.attrib.get("meshdir", mesh)
        texture = node.attrib.get("texturedir", texture)
        if "strippath" in node.attrib:
            strip = node.attrib["strippath"].strip().lower() == "true"
    return CompilerDirs(mesh, texture, strip)


def asset_file(model_dir: Path, folder: str, value: str, include_dir: Path | None, strip: bool) -> Path:
    """Where MuJoCo reads an asset file written ``value`` (not normalised: ``..`` and links as written).

    Args:
        model_dir: The main model's folder.
        folder: The compiler folder for the element (:meth:`CompilerDirs.folder`), relative to ``model_dir``
            unless absolute.
        value: The element's file attribute.
        include_dir: The folder of the included file the element came from (``None``: the main file): a
            relative file not found under ``model_dir / folder`` is read beside it.
        strip: ``<compiler strippath="true">``: the file name alone.
    """
    if include_dir is not None and not Path(value).is_absolute() and not exists(Path(model_dir) / folder / value):
        value = str(include_dir / value)  # MuJoCo then reads it beside the included file
    if strip:
        value = re.split(r"[/\\]", value)[-1]
    return Path(model_dir) / folder / value


def root_holding(real: Path, roots: Sequence[Path]) -> Path | None:
    """The first of ``roots`` that is ``real`` or holds it (both with symbolic links resolved), or ``None``."""
    return next((r for r in roots if real == r or r in real.parents), None)


def exists(path: Path) -> bool:
    """Whether MuJoCo would find something at ``path`` (a ``stat``: nothing is opened)."""
    try:
        os.stat(path)
    except (OSError, ValueError):
        return False
    return True


# -- walking ---------------------------------------------------------------------------------------------------


def walk(root: XmlNode) -> Iterable[XmlNode]:
    """Every node in document order (iteratively)."""
    stack = [root]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(reversed(node.children))


def tagged(root: XmlNode, tag: str) -> Iterable[XmlNode]:
    """Every node named ``tag`` in document order."""
    return (n for n in walk(root) if n.tag == tag)
