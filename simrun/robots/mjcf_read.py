"""The one reader of an MJCF model and of every file it names (issue 42).

MuJoCo's own loader (:meth:`mujoco.MjSpec.from_file`) opens every ``<include>``, mesh, texture, height field,
skin and ``<flexcomp>`` file itself, by path, from anywhere: FIFOs block it, ``/dev/zero`` fills memory,
``/proc/self/environ`` is read, and its parse grows about quadratically with the elements of a model. Here
the project reads them all itself and hands MuJoCo only bytes:

1. The MJCF file and each included file are read whole, bounded (:class:`Limits`), as regular files only;
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

import math
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
    etree,
    find_include,
    include_candidates,
    parse_xml,
    pull_parser,
    refuse_declarations,
    root_holding,
    splice_includes,
    syntax_error,
    tagged,
    to_nodes,
    walk,
)
from meshtool.files.safeopen import printable, read_beneath, read_file

__all__ = ["FILE_ATTRS", "Limits", "MjcfModel", "MjcfReadError", "ReadFile", "allowed_roots", "read_mjcf"]

MIB = 1 << 20
#: Environment variable of folders (``os.pathsep``-separated) MJCF files may read from besides the scene's
#: and the model's own (``simrun check/play/test/serve/export --allow-root DIR`` sets it for its runs).
ALLOW_ROOTS_ENV = "SIMRUN_ALLOW_ROOTS"
#: Attributes whose values are names or words, never numbers (a joint may be called ``inf``).
_WORDS = frozenset(
    (
        "name class childclass model prefix sep target plugin instance key value objname objtype refname reftype "
        "mesh hfield material texture joint joint1 joint2 jointinparent body body1 body2 site site1 site2 slidersite "
        "cranksite tendon tendon1 tendon2 actuator geom geom1 geom2 camera light flex sensor content_type meshdir "
        "texturedir assetdir type mode"
    ).split()
)
_CHUNK = 4096  # bytes fed to the counting parser at a time (at most ~1,400 levels of nesting)
_SUSPECT = re.compile(r"(?i)nan|inf|e\+?\d{3}")
_PNG = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True, slots=True)
class Limits:
    """What one MJCF model may hold before MuJoCo sees it (docs/limits.md, "MJCF models").

    Attributes:
        xml_bytes: Largest MJCF or included file, bytes.
        total_xml_bytes: All XML files of one model together, bytes.
        includes: ``<include>`` files followed (nested ones count).
        elements: XML elements of the model with its includes spliced in.
        depth: Nesting of XML elements, the root counting as 1 (MuJoCo's tinyxml2 refuses 500).
        bodies: Bodies (``<replicate>`` and ``<composite>``/``<flexcomp>`` counts multiplied in); the world's
            own limit (:data:`simrun.world.world.MAX_BODIES`).
        geoms: Geoms, counted the same way.
        meshes: ``<mesh>`` assets.
        keyframes: ``<key>`` elements, or ``<size nkey>`` where larger.
        user: Each ``<size nuser_*>`` (user numbers per body, geom, joint...).
        asset_bytes: Largest asset file, bytes, by kind (``mesh``, ``skin``, ``flexcomp``, ``texture``,
            ``hfield``).
        total_asset_bytes: All asset files of one model together, bytes.
        image_pixels: Pixels of a PNG texture or height field, from its header (decoded by MuJoCo), and
            what an element asks MuJoCo to allocate: a height field's ``nrow`` x ``ncol``, a texture's
            ``width`` x ``height`` without a file (6 x ``width``² for a ``cube`` or ``skybox``).
    """

    xml_bytes: int = 64 * MIB
    total_xml_bytes: int = 256 * MIB
    includes: int = 4096
    elements: int = 50_000
    depth: int = 480
    bodies: int = 10_000
    geoms: int = 20_000
    meshes: int = 10_000
    keyframes: int = 10_000
    user: int = 1_000
    asset_bytes: tuple[tuple[str, int], ...] = (
        ("mesh", 256 * MIB),
        ("skin", 256 * MIB),
        ("flexcomp", 256 * MIB),
        ("texture", 64 * MIB),
        ("hfield", 64 * MIB),
    )
    total_asset_bytes: int = 1024 * MIB
    image_pixels: int = 8192 * 8192

    def for_asset(self, kind: str) -> int:
        """Largest file of an asset kind, bytes."""
        return dict(self.asset_bytes).get(kind, 64 * MIB)


DEFAULT_LIMITS = Limits()


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


class _Reader:
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

    def _where(self, node: XmlNode) -> dict[str, Any]:
        return {"path": printable(self.xml_files[node.file]), "line": node.line}

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

    def _count_stream(self, data: bytes, shown: str, depth: int) -> None:
        """Count elements by kind and their nesting while streaming, keeping no tree (bounded memory)."""
        parser = pull_parser(("start", "end"))
        counts = self.counts
        tally = {"body": 0, "geom": 0, "mesh": 0, "key": 0}
        names = {"body": "bodies", "geom": "geoms", "mesh": "meshes", "key": "keyframes"}
        limits = {"body": self.limits.bodies, "geom": self.limits.geoms}
        limits |= {"mesh": self.limits.meshes, "key": self.limits.keyframes}
        level = depth
        defaults = 0  # open <default> elements: what is inside them is no body, geom or mesh of the model
        first_over: dict[str, int] = {}
        try:
            for start in range(0, len(data), _CHUNK):  # small: the depth is seen before libxml2's own 2,048
                parser.feed(data[start : start + _CHUNK])
                for event, element in parser.read_events():
                    if event == "end":
                        level -= 1
                        defaults -= element.tag == "default"
                        element.clear()  # keep no tree: counting only
                        parent = element.getparent()
                        while parent is not None and element.getprevious() is not None:
                            del parent[0]  # the siblings already counted
                        continue
                    level += 1
                    counts["elements"] += 1
                    if level > self.limits.depth:
                        raise MjcfReadError(
                            f"elements nested {level} deep, more than the limit of {self.limits.depth} "
                            "(docs/limits.md)",
                            path=shown,
                            line=element.sourceline,
                            element=f"<{element.tag}>",
                            hint="flatten the model",
                        )
                    if counts["elements"] > self.limits.elements:
                        over = next(iter(first_over), None)  # a kind already over its own limit says more
                        if over is not None:
                            raise MjcfReadError(
                                f"at least {counts[names[over]] + tally[over]:,} {names[over]} (<{over}>), more "
                                f"than the limit of {limits[over]:,} (docs/limits.md; counting stopped at the "
                                f"limit of {self.limits.elements:,} XML elements)",
                                path=shown,
                                line=first_over[over],
                                element=f"<{over}>",
                                hint="split the model or use fewer of them",
                            )
                        raise MjcfReadError(
                            f"more than {self.limits.elements:,} XML elements in the model (the limit; "
                            f"docs/limits.md){_so_far(tally, names)}",
                            path=shown,
                            line=element.sourceline,
                            element=f"<{element.tag}>",
                            hint="split the model or simplify it",
                        )
                    tag = element.tag
                    defaults += tag == "default"
                    if tag in tally and not defaults:
                        tally[tag] += 1
                        if counts[names[tag]] + tally[tag] > limits[tag] and tag not in first_over:
                            first_over[tag] = element.sourceline or 0
            parser.close()
        except etree.XMLSyntaxError as exc:
            raise syntax_error(exc, shown) from None
        for tag, line in first_over.items():
            total = counts[names[tag]] + tally[tag]
            raise MjcfReadError(
                f"{total:,} {names[tag]} (<{tag}>), more than the limit of {limits[tag]:,} (docs/limits.md)",
                path=shown,
                line=line,
                element=f"<{tag}>",
                hint="split the model or use fewer of them",
            )
        for tag, n in tally.items():
            counts[names[tag]] += n

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

    # -- counting ------------------------------------------------------------------------------------------

    def _count_tree(self, root: XmlNode) -> None:
        """Bodies and geoms with ``<replicate>``/``<composite>``/``<flexcomp>`` multiplied in; sizes."""
        limits = self.limits
        bodies = geoms = meshes = keys = 0
        depth = 0
        over: dict[str, tuple[XmlNode, int]] = {}
        stack: list[tuple[XmlNode, int, int]] = [(root, 1, 1)]
        while stack:
            node, times, level = stack.pop()
            depth = max(depth, level)
            tag = node.tag
            if tag == "default":  # defaults, not elements of the model
                continue
            if tag == "replicate":
                times *= max(_int(node.attrib.get("count"), 1), 0)
            elif tag == "body":
                bodies += times
            elif tag == "geom":
                geoms += times
            elif tag == "mesh":
                meshes += 1
            elif tag == "key":
                keys += 1
            elif tag in ("hfield", "texture"):
                self._check_pixels(node)
            elif tag in ("composite", "flexcomp"):
                made = math.prod(max(v, 1) for v in _ints(node.attrib.get("count", "1")) or [1]) * times
                bodies, geoms = bodies + made, geoms + made
            elif tag == "size":
                keys = _int(node.attrib.get("nkey"), 0)
                if keys > limits.keyframes:
                    over["keyframes"] = (node, keys)
                for key, value in node.attrib.items():
                    if key.startswith("nuser_") and _int(value, 0) > limits.user:
                        raise MjcfReadError(
                            f"{key} = {_int(value, 0):,}, more than the limit of {limits.user:,} (docs/limits.md)",
                            element="<size>",
                            hint="use fewer user numbers",
                            **self._where(node),
                        )
            if bodies > limits.bodies and "bodies" not in over:
                over["bodies"] = (node, 0)
            if geoms > limits.geoms and "geoms" not in over:
                over["geoms"] = (node, 0)
            stack.extend((c, times, level + 1) for c in reversed(node.children))
        self.counts |= {"bodies": bodies, "geoms": geoms, "meshes": meshes, "keyframes": keys, "depth": depth}
        for kind, (node, n) in over.items():
            total = {"bodies": bodies, "geoms": geoms}.get(kind, n)
            limit = getattr(limits, kind)
            how = "<size nkey>" if kind == "keyframes" else "with <replicate>, <composite> and <flexcomp> counts"
            raise MjcfReadError(
                f"{total:,} {kind} ({how}), more than the limit of {limit:,} (docs/limits.md)",
                element=f"<{node.tag}>",
                hint="split the model or use fewer of them",
                **self._where(node),
            )
        sizes = [_int(n.attrib.get("nkey"), 0) for n in tagged(root, "size")]
        self.counts["keyframes"] = max([self.counts["keyframes"], *sizes])

    def _check_pixels(self, node: XmlNode) -> None:
        """Refuse a height field's ``nrow`` x ``ncol`` or a file-less texture's size over the pixel limit.

        MuJoCo allocates what they ask for while compiling: an hfield of 65536² crashed it (segmentation fault),
        100000² raised ``RuntimeError`` (``bad_alloc``), 20000² ran past the fuzzer's 10 s (``make fuzz``).
        """
        at = node.attrib
        if node.tag == "hfield":
            rows, cols = max(_int(at.get("nrow"), 0), 0), max(_int(at.get("ncol"), 0), 0)
            pixels, size = rows * cols, f"nrow x ncol = {rows:,} x {cols:,}"
        elif any(a.startswith("file") for a in at):
            return
        else:
            width, height = max(_int(at.get("width"), 0), 0), max(_int(at.get("height"), 0), 0)
            cube = at.get("type", "").strip() in ("cube", "skybox")
            pixels = 6 * width * width if cube else width * height
            size = f"6 faces of width {width:,}" if cube else f"width x height = {width:,} x {height:,}"
        if pixels > self.limits.image_pixels:
            name = at.get("name")
            raise MjcfReadError(
                f"{size}, {pixels:,} pixels, more than the limit of {self.limits.image_pixels:,} (docs/limits.md)",
                element=f"<{node.tag}>" + (f" {name!r}" if name else ""),
                hint="ask for fewer rows and columns" if node.tag == "hfield" else "ask for a smaller texture",
                **self._where(node),
            )

    def _check_numbers(self, root: XmlNode) -> None:
        """A NaN or infinity in any numeric attribute is refused, with the element and the attribute."""
        for node in walk(root):
            for key, value in node.attrib.items():
                if key in _WORDS or key.startswith("file") or (key == "data" and node.tag == "text"):
                    continue
                if not _SUSPECT.search(value):
                    continue
                bad = next((t for t in value.split() if _non_finite(t)), None)
                if bad is not None:
                    name = node.attrib.get("name")
                    element = f"<{node.tag}>" + (f" {name!r}" if name else "")
                    raise MjcfReadError(
                        f"attribute {key!r} is not finite ({bad!r} in {_short(value)!r}); MuJoCo would run with it",
                        element=element,
                        hint="write a finite number",
                        **self._where(node),
                    )

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


def _so_far(tally: dict[str, int], names: dict[str, str]) -> str:
    found = ", ".join(f"{n:,} {names[t]}" for t, n in tally.items() if n)
    return f"; in this file so far: {found}" if found else ""


def _non_finite(token: str) -> bool:
    try:
        return not math.isfinite(float(token))
    except ValueError:
        return False


def _int(text: str | None, default: int) -> int:
    try:
        return int(str(text).strip())
    except ValueError:
        return default


def _ints(text: str) -> list[int]:
    return [_int(t, 1) for t in text.split()]


def _short(value: str) -> str:
    return value if len(value) <= 40 else value[:37] + "..."


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
