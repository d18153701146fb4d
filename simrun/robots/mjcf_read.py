"""The one reader of an MJCF model and of every file it names (issue 42).

MuJoCo's own loader (:meth:`mujoco.MjSpec.from_file`) opens every ``<include>``, mesh, texture, height field,
skin and ``<flexcomp>`` file itself, by path, from anywhere: FIFOs block it, ``/dev/zero`` fills memory,
``/proc/self/environ`` is read, and its parse grows about quadratically with the elements of a model. Here
the project reads them all itself and hands MuJoCo only bytes:

1. The MJCF file and each included file are read whole, bounded (:class:`~simrun.robots.mjcf_limits.Limits`;
   the counting and checks of steps 2 and 6 live in :mod:`simrun.robots.mjcf_limits`), as regular files only;
   included files through :func:`meshtool.files.safeopen.read_beneath` (``openat`` from a root, ``O_NOFOLLOW``,
   ``fstat`` before reading), like every asset below.
2. Each XML file is parsed by lxml with no DTD, no entities and no network (a ``DOCTYPE`` or ``ENTITY`` is
   refused), counted as it streams (elements, nesting depth, bodies, geoms, meshes, keyframes: refused over
   the limits with the count and the limit named, before any tree is kept), then parsed into a tree.
3. ``<include>`` elements are replaced by the children of the included file's root, as MuJoCo's
   ``mjIncludeXML`` does (``src/xml/xml.cc``): a relative name is looked for in the main model's folder
   first, then in the folder of the file that holds the ``<include>``; a file included twice is refused (a
   cycle included).
4. Asset files are found as MuJoCo finds them (``src/xml/xml_util.cc``, ``ResolveFilePath``, and the
   compiler): a mesh, skin, height field or ``<flexcomp>`` ``file`` relative to ``<compiler meshdir>``, a
   texture and its cube faces relative to ``texturedir`` (``assetdir`` sets both where the element does not
   give them; the last ``<compiler>`` in the spliced model wins), those folders relative to the main model's
   folder unless absolute; an element of an included file whose file is not found there is looked for beside
   that included file; ``strippath`` keeps the file name alone.
5. Every file must lie, after following symbolic links, inside a root: the scene's folder, the MJCF's own
   folder or a folder the user allowed (:func:`allowed_roots`: the entity's ``allow_roots``, ``simrun ...
   --allow-root DIR``, ``SIMRUN_ALLOW_ROOTS``). Anything else is refused with one line naming the element and
   the path; nothing outside the roots is opened (``tests/test_mjcf_hostile.py`` traces the system calls).
6. Numbers: a NaN or infinity in any numeric attribute is refused with the element and the attribute
   (MuJoCo reads ``nan`` and ``inf`` and runs with them). ``<replicate count>``, ``<composite count>``,
   ``<flexcomp count>`` and ``<size nkey>`` count towards the limits as the bodies, geoms and keyframes
   they make.
7. The result (:class:`MjcfModel`) is one include-free MJCF document whose file attributes name in-memory
   files (``PREFIX<k>_<name>``: unique per model, as MuJoCo caches meshes by file name), the files' bytes,
   the list of every file read (the model, its includes, its assets: the run bundle's list) and, per line of
   the document, the file and line the element came from, so MuJoCo's messages can name the real file.
   :meth:`MjcfModel.spec` hands both to :meth:`mujoco.MjSpec.from_string` (``include``: what the parser reads,
   the flexcomp files, and an empty stand-in for every other name it only looks up; ``assets``: what the
   compiler reads), so MuJoCo opens nothing by path and looks nothing up on disk.
"""

from __future__ import annotations

import os
import re
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco

from meshtool.errors import ResolveError
from meshtool.files.mjcf_xml import (
    ASSET_FOLDER,
    FILE_ATTRS,
    MjcfReadError,
    XmlNode,
    asset_file,
    compiler_dirs,
    find_include,
    include_candidates,
    parse_xml,
    refuse_declarations,
    root_holding,
    splice_includes,
    tagged,
    to_nodes,
    walk,
)
from meshtool.files.safeopen import printable, read_beneath, read_file
from simrun.robots.mjcf_limits import DEFAULT_LIMITS, Limits, _LimitChecks

__all__ = ["FILE_ATTRS", "MjcfModel", "MjcfReadError", "ReadFile", "allowed_roots", "read_mjcf"]

#: Environment variable of folders (``os.pathsep``-separated) MJCF files may read from besides the scene's
#: and the model's own (``simrun check/play/test/serve/export --allow-root DIR`` sets it for its runs).
ALLOW_ROOTS_ENV = "SIMRUN_ALLOW_ROOTS"
_PNG = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True, slots=True)
class ReadFile:
    """One file the reader read for a model.

    Attributes:
        kind: ``model``, ``include``, ``mesh``, ``skin``, ``hfield``, ``flexcomp`` or ``texture``.
        name: The asset's name in the model (``""`` for the model and its includes).
        path: Where MuJoCo would read it (as MuJoCo builds the name: symbolic links not followed).
        real: The file read (symbolic links resolved, inside a root).
        vfs: Its in-memory name in :attr:`MjcfModel.files` (``""`` for the model and its includes).
        face: For a cube texture's face file, its index in ``fileright ... fileback``; else ``None``.
    """

    kind: str
    name: str
    path: Path
    real: Path
    vfs: str = ""
    face: int | None = None


@dataclass(slots=True)
class MjcfModel:
    """An MJCF model as the reader hands it to MuJoCo.

    Attributes:
        path: The main MJCF file (as given).
        xml: The model with its includes spliced in and every file attribute naming an in-memory file.
        files: In-memory files, name to bytes (meshes, textures, height fields, skins, flexcomp files).
        read: Every file read, in reading order: the model, its includes, then its assets.
        counts: What the model holds: ``elements``, ``depth``, ``bodies``, ``geoms``, ``meshes``,
            ``keyframes``, ``includes``, ``xml_bytes``, ``asset_bytes``.
        origins: For line ``k`` of :attr:`xml`, ``origins[k - 1]`` is the file and line its element came from.
    """

    path: Path
    xml: str
    files: dict[str, bytes]
    read: list[ReadFile]
    counts: dict[str, int]
    origins: list[tuple[Path, int]] = field(repr=False)

    def spec(self) -> mujoco.MjSpec:
        """The model parsed by MuJoCo from :attr:`xml` and :attr:`files` (it opens no file).

        Raises:
            ValueError: MuJoCo refuses the model (its message names a line of :attr:`xml`: :meth:`origin`).
        """
        # The parser reads flexcomp files and looks every other name up (on disk, relative to the working folder,
        # where it is not in ``include``): those get an empty stand-in, the compiler reads ``assets``.
        parsed = {name: b"" for name in self.files} | {
            f.vfs: self.files[f.vfs] for f in self.read if f.kind == "flexcomp"
        }
        return mujoco.MjSpec.from_string(self.xml, include=parsed, assets=dict(self.files))

    def origin(self, line: int) -> tuple[Path, int] | None:
        """The file and line of the element at ``line`` of :attr:`xml`, ``None`` when there is none."""
        return self.origins[line - 1] if 1 <= line <= len(self.origins) else None

    def sources(self) -> set[Path]:
        """The real paths of every file read (what a run bundle must hold)."""
        return {f.real for f in self.read}


def allowed_roots(base_dir: Path, extra: Iterable[str] = ()) -> list[Path]:
    """The folders an MJCF may read from besides its own: the scene's folder, ``extra``, ``SIMRUN_ALLOW_ROOTS``.

    Args:
        base_dir: The scene's (the world's) folder; relative entries of ``extra`` are relative to it.
        extra: Folders the scene allows (the entity's ``allow_roots``).
    """
    env = [p for p in os.environ.get(ALLOW_ROOTS_ENV, "").split(os.pathsep) if p]
    return [Path(base_dir), *(Path(base_dir) / p for p in extra), *(Path(p) for p in env)]


def read_mjcf(
    path: Path,
    roots: Sequence[Path] = (),
    prefix: str = "mjcf_",
    limits: Limits = DEFAULT_LIMITS,
    *,
    assets: bool = True,
) -> MjcfModel:
    """Read the MJCF at ``path`` and every file it names, inside ``roots`` and the model's own folder.

    Args:
        path: The main MJCF file (a regular file; symbolic links followed: the scene named it).
        roots: Folders files may be read from besides the model's own (symbolic links resolved here).
        prefix: Start of the in-memory file names (unique per model in one world).
        limits: The bounds (:class:`Limits`).
        assets: ``False``: check where the asset files are but do not read them (their in-memory files are
            empty), except ``<flexcomp>`` files, which MuJoCo reads while parsing (to read the options only).

    Raises:
        MjcfReadError: The model or a file it names is refused (one line naming the element and the path).
    """
    return _Reader(Path(path), roots, prefix, limits, assets).run()


# -- the reader ------------------------------------------------------------------------------------------------


class _Reader(_LimitChecks):
    def __init__(self, path: Path, roots: Sequence[Path], prefix: str, limits: Limits, assets: bool) -> None:
        self.path = path
        self.model_dir = Path(os.path.abspath(path)).parent
        own = Path(os.path.realpath(self.model_dir))
        self.roots = list(dict.fromkeys([own, *(Path(os.path.realpath(r)) for r in roots)]))
        self.prefix, self.limits, self.assets = prefix, limits, assets
        self.xml_files: list[Path] = []
        self.read: list[ReadFile] = []
        self.files: dict[str, bytes] = {}
        self.taken: dict[Path, str] = {}
        self.counts = {"elements": 0, "depth": 0, "bodies": 0, "geoms": 0, "meshes": 0, "keyframes": 0}
        self.counts |= {"includes": 0, "xml_bytes": 0, "asset_bytes": 0}

    # -- driving -------------------------------------------------------------------------------------------

    def run(self) -> MjcfModel:
        shown = printable(self.path)
        try:
            data = read_file(self.path, self.limits.xml_bytes, shown)
        except ResolveError as exc:
            raise MjcfReadError(f"cannot read the MJCF file: {exc.message}", path=shown) from None
        real = Path(os.path.realpath(self.path))
        self.read.append(ReadFile("model", "", self.path, real))
        self.counts["xml_bytes"] += len(data)
        root = self._parse(data, self.path, 0, None)
        if root.tag != "mujoco":
            hint = "use UrdfRobot for a URDF" if root.tag == "robot" else "an MJCF model starts with <mujoco>"
            raise MjcfReadError(f"<{root.tag}> is not an MJCF model", path=shown, line=root.line, hint=hint)
        self._splice(root, real)
        self._count_tree(root)
        self._resolve_assets(root)
        self._check_numbers(root)
        xml, origins = self._serialise(root)
        return MjcfModel(self.path, xml, self.files, self.read, dict(self.counts), origins)

    # -- XML -----------------------------------------------------------------------------------------------

    def _parse(self, data: bytes, path: Path, depth: int, include_dir: Path | None) -> XmlNode:
        """Count, then parse one XML file into nodes (``depth``: nesting of the element it goes into)."""
        shown = printable(path)
        index = len(self.xml_files)
        self.xml_files.append(path)
        if not data.strip():
            raise MjcfReadError("the file is empty", path=shown, hint="an MJCF file holds a <mujoco> element")
        refuse_declarations(data, shown)
        self._count_stream(data, shown, depth)
        return to_nodes(parse_xml(data, shown), index, include_dir, shown)

    # -- includes ------------------------------------------------------------------------------------------

    def _splice(self, root: XmlNode, main_real: Path) -> None:
        """Replace every ``<include>`` by the children of its file's root, in MuJoCo's reading order."""
        seen = {main_real}

        def include(child: XmlNode, depth: int) -> list[XmlNode]:
            if child.tag != "include":
                raise MjcfReadError(
                    "MuJoCo reads an include written this way but then refuses it",
                    element=f"<{child.tag}>",
                    hint="write <include>",
                    **self._where(child),
                )
            return self._include(child, depth, seen)

        splice_includes(root, include)

    def _include(self, node: XmlNode, depth: int, seen: set[Path]) -> list[XmlNode]:
        where = self._where(node)
        name = node.attrib.get("file")
        if node.children:
            raise MjcfReadError("an <include> element cannot have children", element="<include>", **where)
        if name is None:
            raise MjcfReadError("an <include> element needs a file attribute", element="<include>", **where)
        element = f"<include file={name!r}>"
        self.counts["includes"] += 1
        if self.counts["includes"] > self.limits.includes:
            raise MjcfReadError(
                f"more than {self.limits.includes:,} included files (the limit; docs/limits.md)",
                element=element,
                hint="include fewer files",
                **where,
            )
        including_dir = self.xml_files[node.file].parent
        target = find_include(self.model_dir, including_dir, name)
        if target is None:
            tried = " or ".join(printable(c) for c in include_candidates(self.model_dir, including_dir, name))
            raise MjcfReadError(f"{tried} does not exist", element=element, hint="check the file name", **where)
        target = Path(os.path.abspath(target))
        real, data = self._read_confined(target, "include", self.limits.xml_bytes, element, where)
        if real in seen:
            raise MjcfReadError(
                f"{printable(target)} is already included (MuJoCo refuses a file included twice)",
                element=element,
                hint="include each file once",
                **where,
            )
        seen.add(real)
        self.counts["xml_bytes"] += len(data)
        if self.counts["xml_bytes"] > self.limits.total_xml_bytes:
            raise MjcfReadError(
                f"the model's XML files hold {self.counts['xml_bytes']:,} bytes, more than the limit of "
                f"{self.limits.total_xml_bytes:,} (docs/limits.md)",
                element=element,
                hint="split the model",
                **where,
            )
        self.read.append(ReadFile("include", "", target, real))
        root = self._parse(data, target, depth - 1, target.parent)  # its root's children go in at ``depth``
        children = root.children
        if not children:
            raise MjcfReadError(
                f"{printable(target)} holds no element inside its root (MuJoCo refuses an empty include)",
                element=element,
                hint="fill it or remove the <include>",
                **where,
            )
        return children

    # -- assets --------------------------------------------------------------------------------------------

    def _resolve_assets(self, root: XmlNode) -> None:
        """Find, check and read every asset file; point the elements at their in-memory names."""
        dirs = compiler_dirs(root)  # MuJoCo's rule, meshtool.files.mjcf_xml
        for node in walk(root):
            named = [a for a in FILE_ATTRS if a in node.attrib]
            if not named:
                continue
            if node.tag == "model":
                raise MjcfReadError(
                    f"a <model> asset (file {node.attrib.get('file', '')!r}) is not read by simrun",
                    element="<model>",
                    hint="attach that model as its own MjcfRobot entity",
                    **self._where(node),
                )
            if node.tag not in ASSET_FOLDER or (node.tag != "texture" and named != ["file"]):
                raise MjcfReadError(
                    f"attribute {named[0]!r} names a file, which MJCF reads only for meshes, textures, height "
                    "fields, skins and flexcomps",
                    element=f"<{node.tag}>",
                    hint="remove the attribute",
                    **self._where(node),
                )
            for attr in named:
                face = None if attr == "file" else FILE_ATTRS.index(attr) - 1
                node.attrib[attr] = self._asset(node, attr, dirs.folder(node.tag), dirs.strip, face)
        for node in tagged(root, "compiler"):  # the in-memory names have no folder
            for key in ("meshdir", "texturedir", "assetdir"):
                node.attrib.pop(key, None)

    def _asset(self, node: XmlNode, attr: str, folder: str, strip: bool, face: int | None) -> str:
        value = node.attrib[attr]
        where = self._where(node)
        name = node.attrib.get("name", "")
        if not name and attr == "file":  # MuJoCo names it after the file; the in-memory name must not rename it
            name = node.attrib["name"] = re.split(r"[/\\]", value)[-1].rsplit(".", 1)[0]
        element = f"{node.tag} {name!r}" if name else f"<{node.tag}>"
        path = Path(os.path.abspath(asset_file(self.model_dir, folder, value, node.include_dir, strip)))
        if node.tag == "flexcomp" or self.assets:
            limit = self.limits.for_asset(node.tag)
            real, data = self._read_confined(path, node.tag, limit, element, where, shown=node.attrib[attr])
        else:
            real, data = self._confined(path, element, where, node.attrib[attr]), b""
        vfs = self.taken.get(real)
        if vfs is None:
            self._check_image(node.tag, data, element, where, path)
            self.counts["asset_bytes"] += len(data)
            if self.counts["asset_bytes"] > self.limits.total_asset_bytes:
                raise MjcfReadError(
                    f"the model's asset files hold {self.counts['asset_bytes']:,} bytes, more than the limit of "
                    f"{self.limits.total_asset_bytes:,} (docs/limits.md)",
                    element=element,
                    hint="use smaller meshes and textures",
                    **where,
                )
            safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in path.name)
            vfs = self.taken[real] = f"{self.prefix}{len(self.taken)}_{safe}"
            self.files[vfs] = data
        self.read.append(ReadFile(node.tag, name, path, real, vfs, face))
        return vfs

    def _check_image(self, kind: str, data: bytes, element: str, where: dict[str, Any], path: Path) -> None:
        if kind not in ("texture", "hfield") or not data.startswith(_PNG) or len(data) < 24:
            return
        width, height = struct.unpack(">II", data[16:24])
        if width * height > self.limits.image_pixels:
            raise MjcfReadError(
                f"{printable(path)} is a {width} x {height} PNG image, more than the limit of "
                f"{self.limits.image_pixels:,} pixels (docs/limits.md); not decoded",
                element=element,
                hint="use a smaller image",
                **where,
            )

    # -- confined reads ------------------------------------------------------------------------------------

    def _confined(self, path: Path, element: str, where: dict[str, Any], written: str) -> Path:
        """The real path of ``path`` and the root holding it, or the one-line refusal (nothing opened)."""
        real = Path(os.path.realpath(path))
        if root_holding(real, self.roots) is None:
            shown = printable(path) if printable(real) == printable(path) else f"{printable(path)} ({real})"
            roots = ", ".join(printable(r) for r in self.roots)
            raise MjcfReadError(
                f"file {written!r} is {shown}, outside the scene's folder and the model's ({roots}); not read",
                element=element,
                hint=f"allow its folder with --allow-root DIR or the entity's allow_roots ({ALLOW_ROOTS_ENV})",
                **where,
            )
        return real

    def _read_confined(
        self, path: Path, kind: str, limit: int, element: str, where: dict[str, Any], shown: str | None = None
    ) -> tuple[Path, bytes]:
        """Read ``path`` walking down from its root without following links (regular files, bounded)."""
        real = self._confined(path, element, where, shown if shown is not None else printable(path))
        root = root_holding(real, self.roots)
        assert root is not None  # _confined refused it otherwise
        try:
            return real, read_beneath(root, real.relative_to(root).parts, limit, printable(path))
        except ResolveError as exc:
            reason = exc.message
            hint = exc.hint or ("put the file there" if "does not exist" in reason else "")
            raise MjcfReadError(
                f"cannot read {printable(path)}: {reason}", element=element, hint=hint, **where
            ) from None

    # -- writing -------------------------------------------------------------------------------------------

    def _serialise(self, root: XmlNode) -> tuple[str, list[tuple[Path, int]]]:
        """The model as one document, each element's start tag on its own line (``origins``: where it came from)."""
        out: list[str] = []
        origins: list[tuple[Path, int]] = []
        stack: list[XmlNode | str] = [root]
        while stack:
            item = stack.pop()
            if isinstance(item, str):
                out.append(item)
                continue
            if origins:
                out.append("\n")
            origins.append((self.xml_files[item.file], item.line))
            attrs = "".join(f' {k}="{_escape(v)}"' for k, v in item.attrib.items())
            if item.children:
                out.append(f"<{item.tag}{attrs}>")
                stack.append(f"</{item.tag}>")
                stack.extend(reversed(item.children))
            else:
                out.append(f"<{item.tag}{attrs}/>")
        return "".join(out), origins


def _escape(value: str) -> str:
    return (
        value.replace("&", "&amp;")
        .replace("<", "&lt;")
        .replace(">", "&gt;")
        .replace('"', "&quot;")
        .replace("\n", "&#10;")
        .replace("\r", "&#13;")
        .replace("\t", "&#9;")
    )
