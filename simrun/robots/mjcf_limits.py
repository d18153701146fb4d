"""What one MJCF model may hold (:class:`Limits`) and the counting and checks that enforce it.

The model reader (:mod:`simrun.robots.mjcf_read`, steps 2 and 6 of its description) runs them: elements by kind
and their nesting counted while each XML file streams (bounded memory, before any tree is kept), bodies and
geoms with ``<replicate>``, ``<composite>`` and ``<flexcomp>`` counts multiplied in, what a height field or a
file-less texture asks MuJoCo to allocate, and a NaN or infinity in any numeric attribute; each refused with
one line naming the element, the count and the limit (docs/limits.md, "MJCF models").
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from meshtool.files.mjcf_xml import (
    MjcfReadError,
    XmlNode,
    etree,
    pull_parser,
    syntax_error,
    tagged,
    walk,
)
from meshtool.files.safeopen import printable

MIB = 1 << 20
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


class _LimitChecks:
    """The counting and checks of :class:`Limits`, run by the model reader (:mod:`simrun.robots.mjcf_read`).

    Attributes (set by the reader): ``limits``; ``counts``, what the model holds so far; ``xml_files``, the XML
    files read, by index (where each element came from).
    """

    limits: Limits
    counts: dict[str, int]
    xml_files: list[Path]

    def _where(self, node: XmlNode) -> dict[str, Any]:
        return {"path": printable(self.xml_files[node.file]), "line": node.line}

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
