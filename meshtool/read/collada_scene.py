"""COLLADA geometry and visual scene, read by meshtool itself from a bounded parse of the XML.

pycollada builds its scene graph recursively, expands every ``<instance_node>`` while iterating the scene
(a few KB of node fan-out, a "billion laughs" without a DTD, becomes billions of bound geometries) and
reads index and float text with ``numpy.fromstring``, which wraps negative indices, stops silently at a bad
token and turns NaN into 0. So the COLLADA reader uses pycollada for ``<asset>``, images, effects and
materials only; this module and the two it uses read the rest:

- :func:`~meshtool.read.collada_xml.parse_xml`: lxml with no DTD, no entities and no network, at most
  :data:`~meshtool.read.collada_xml.MAX_ELEMENTS` elements and 2,048 levels of nesting (libxml2's own
  limit).
- :func:`~meshtool.read.collada_geometry.read_geometry`: ``<source>`` (``count``, ``stride``,
  ``offset`` checked against the data), ``<triangles>``, ``<polylist>``, ``<polygons>``, ``<tristrips>``
  and ``<trifans>`` (triangulated as pycollada does: fans, strips in its order); every index is checked
  against its source, and a damaged primitive is an error naming the element and its line.
- :class:`SceneWalk` (here): the node graph walked without recursion; cycles are refused; the triangles,
  vertices and instances the scene expands to are counted per node (memoised, with multiplicities) and
  charged to the :class:`~meshtool.read.budget.ExpansionBudget` *before* any instance is placed, at most
  :data:`~meshtool.read.budget.MAX_INSTANCES` instances (``MESHTOOL_MAX_INSTANCES``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from meshtool.errors import FormatError
from meshtool.findings import Finding, warning
from meshtool.read.budget import INSTANCES_ENV, MAX_INSTANCES, ExpansionBudget, limit_from_env
from meshtool.read.collada_geometry import Geometry, floats, read_geometry
from meshtool.read.collada_xml import DAMAGED, children, fail, local

_CAP = 1 << 62  # counts saturate here: a deep fan-out never builds integers of thousands of digits
_TRANSFORM_SIZES = {"translate": 3, "rotate": 4, "scale": 3, "matrix": 16, "lookat": 9}


def _name(node: Any) -> str:
    """A ``<node>``'s name, else its id, for messages."""
    return str(node.get("name") or node.get("id") or "?")[:60]


@dataclass(slots=True)
class Instance:
    """A geometry placed in the scene: its matrix (float32, as pycollada composes it) and bound materials."""

    geometry: Geometry
    matrix: Any
    materials: dict[str, Any]
    line: int  # of the <instance_geometry>


@dataclass(slots=True)
class _Node:
    matrix: Any  # float32 (4, 4)
    entries: list[tuple[str, Any, Any]] = field(default_factory=list)  # ("geometry", (Geometry, materials), el)
    #                                                                    or ("node", element, via element)


class SceneWalk:
    """The visual scene's node graph, read and counted without recursion.

    Args:
        root: The ``COLLADA`` element.
        path: File name for messages.
        materials: pycollada's materials by id (those it could read).
        findings: Where repairs are recorded.
    """

    def __init__(self, root: Any, path: str, materials: Mapping[str, Any], findings: list[Finding]) -> None:
        self.root = root
        self.path = path
        self.materials = materials
        self.findings = findings
        self.nodes: dict[str, Any] = {}
        for element in root.iter("{*}node"):
            self.nodes.setdefault(element.get("id") or "", element)
        self.geometry_elements: dict[str, Any] = {}
        for element in root.iter("{*}geometry"):
            self.geometry_elements.setdefault(element.get("id") or "", element)
        self.material_ids = {m.get("id") for m in root.iter("{*}material")}
        self.geometries: dict[str, Geometry | None] = {}
        self.info: dict[Any, _Node] = {}
        #: Line primitives the scene instances (each instance counted), set by :meth:`place`.
        self.lines = 0

    def scene_roots(self) -> list[Any] | None:
        """The top-level nodes of the instanced visual scene, ``None`` when there is none."""
        instance = self.root.find("./{*}scene/{*}instance_visual_scene")
        if instance is None:
            return None
        url = instance.get("url") or ""
        for scene in self.root.iter("{*}visual_scene"):
            if url.startswith("#") and scene.get("id") == url[1:]:
                return list(children(scene, "node"))
        return None

    def place(self, roots: list[Any], budget: ExpansionBudget) -> list[Instance]:
        """Count what the scene expands to, charge it, then place every geometry instance (document order).

        Raises:
            FormatError: A cycle of ``<instance_node>``, a damaged node or geometry, or an expansion beyond
                the budget or :data:`~meshtool.read.budget.MAX_INSTANCES` (code ``expansion-limit``), before
                anything is placed.
        """
        order = self._post_order(roots)
        tri: dict[Any, int] = {}
        vert: dict[Any, int] = {}
        cost: dict[Any, int] = {}  # nodes with geometry below, plus primitives, placed
        lines: dict[Any, int] = {}
        for element in order:  # children first; a fan-out of any depth saturates at _CAP
            t = v = c = n = 0
            for kind, payload, _ in self.info[element].entries:
                if kind == "geometry":
                    g = payload[0]
                    t, v, c, n = t + g.triangles, v + g.vertices, c + len(g.prims), n + g.lines
                else:
                    t, v, c, n = t + tri[payload], v + vert[payload], c + cost[payload], n + lines[payload]
            tri[element], vert[element], lines[element] = min(t, _CAP), min(v, _CAP), min(n, _CAP)
            cost[element] = min(c + 1, _CAP) if c else 0
        self.lines = sum(lines[element] for element in roots)
        limit = limit_from_env(INSTANCES_ENV, MAX_INSTANCES)
        placed = 0
        for element in roots:
            what = f"node '{_name(element)}'"
            placed += cost[element]
            if placed > limit:
                raise FormatError(
                    f"the visual scene expands to more than {limit:,} node and primitive instances (at least "
                    f"{placed:,} with {what}); not read",
                    path=self.path,
                    line=element.sourceline,
                    hint=f"check the file; for a genuine scene this large set {INSTANCES_ENV}",
                    code="expansion-limit",
                )
            try:
                budget.charge(tri[element], vert[element], what)
            except FormatError as exc:
                raise FormatError(
                    exc.message, path=self.path, line=element.sourceline, hint=exc.hint, code=exc.code
                ) from None
        out: list[Instance] = []
        for element in roots:
            if cost[element]:
                self._expand(element, cost, out)
        return out

    def _post_order(self, roots: list[Any]) -> list[Any]:
        """Every node reachable from ``roots``, children before parents; a cycle is an error."""
        state: dict[Any, int] = {}  # 1: on the path from a root, 2: done
        order: list[Any] = []
        for root in roots:
            if root in state:
                continue
            state[root] = 1
            stack = [(root, iter(self._info(root).entries))]
            while stack:
                element, entries = stack[-1]
                for kind, target, via in entries:
                    if kind != "node":
                        continue
                    seen = state.get(target, 0)
                    if seen == 1:
                        name = f"node '{_name(target)}' (line {target.sourceline})"
                        how = (
                            f"<instance_node url='{via.get('url', '')[:60]}'> instances {name} inside itself"
                            if local(via) == "instance_node"
                            else f"{name} is placed inside itself: node '{_name(element)}' contains it and is "
                            "instanced below it"
                        )
                        raise FormatError(
                            f"{how}: the node graph has a cycle", path=self.path, line=via.sourceline, hint=DAMAGED
                        )
                    if seen == 0:
                        state[target] = 1
                        stack.append((target, iter(self._info(target).entries)))
                        break
                else:
                    state[element] = 2
                    order.append(element)
                    stack.pop()
        return order

    def _expand(self, root: Any, cost: Mapping[Any, int], out: list[Instance]) -> None:
        """Place the geometry under ``root`` depth first in document order, as pycollada's ``objects``."""
        top = self.info[root]
        stack = [(top.matrix, iter(top.entries))]
        while stack:
            matrix, entries = stack[-1]
            for kind, payload, via in entries:
                if kind == "geometry":
                    if payload[0].prims:
                        out.append(Instance(payload[0], matrix, payload[1], via.sourceline or 0))
                elif cost[payload]:
                    node = self.info[payload]
                    with np.errstate(all="ignore"):
                        placed = np.dot(matrix, node.matrix)
                    if not np.isfinite(placed).all():
                        raise FormatError(
                            f"node '{_name(payload)}' is placed by a non-finite transform (its matrices overflow)",
                            path=self.path,
                            line=via.sourceline,
                            hint=DAMAGED,
                        )
                    stack.append((placed, iter(node.entries)))
                    break
            else:
                stack.pop()

    def _info(self, element: Any) -> _Node:
        """A node's matrix and entries (read once)."""
        if element in self.info:
            return self.info[element]
        from collada import scene as dae_scene

        transforms: list[Any] = []
        node = _Node(np.identity(4, dtype=np.float32))
        for item in element:
            name = local(item)
            if name in _TRANSFORM_SIZES:
                transforms.append(_transform(item, name, self.path, dae_scene))
            elif name == "skew":
                self._warn("collada-unsupported", f"<skew> (line {item.sourceline}) is not supported: ignored")
            elif name == "node":
                node.entries.append(("node", item, item))
            elif name == "instance_node":
                target = self._target(item, self.nodes, "node")
                if target is not None:
                    node.entries.append(("node", target, item))
            elif name == "instance_geometry":
                geometry = self._geometry(item)
                if geometry is not None:
                    node.entries.append(("geometry", (geometry, self._bind(item)), item))
        with np.errstate(all="ignore"):
            node.matrix = dae_scene.Node(element.get("id"), [], transforms, xmlnode=element).matrix
        if not np.isfinite(node.matrix).all():
            raise FormatError(
                f"node '{_name(element)}' has a non-finite transform",
                path=self.path,
                line=element.sourceline,
                hint=DAMAGED,
            )
        self.info[element] = node
        return node

    def _target(self, item: Any, table: Mapping[str, Any], what: str) -> Any:
        url = item.get("url") or ""
        found = table.get(url[1:]) if url.startswith("#") else None
        if found is None:
            self._warn(
                "collada-instance-missing",
                f"<{local(item)} url='{url[:60]}'> (line {item.sourceline}) names no {what} in this file: skipped",
            )
        return found

    def _geometry(self, item: Any) -> Geometry | None:
        element = self._target(item, self.geometry_elements, "geometry")
        if element is None:
            return None
        key = element.get("id") or ""
        if key not in self.geometries:
            self.geometries[key] = read_geometry(element, self.path)
            if self.geometries[key] is None:
                self._warn(
                    "collada-unsupported",
                    f"geometry '{key}' (line {element.sourceline}) has no <mesh> (a spline, B-rep or convex "
                    "mesh): skipped",
                )
        return self.geometries[key]

    def _bind(self, item: Any) -> dict[str, Any]:
        """``<instance_material>`` symbols -> pycollada materials; one that cannot be bound is left out."""
        out: dict[str, Any] = {}
        for bound in item.iterfind("./{*}bind_material/{*}technique_common/{*}instance_material"):
            symbol, target = bound.get("symbol") or "", bound.get("target") or ""
            key = target[1:] if target.startswith("#") else target
            material = self.materials.get(key)
            if material is not None:
                out[symbol] = material
                continue
            why = (
                "cannot be read (its effect is missing or damaged)"
                if key in self.material_ids
                else "is not in the file"
            )
            self._warn(
                "collada-material-missing",
                f"<instance_material symbol='{symbol[:40]}' target='{target[:60]}'> (line {bound.sourceline}): "
                f"material '{key[:60]}' {why}; its triangles keep no material",
            )
        return out

    def _warn(self, code: str, message: str) -> None:
        self.findings.append(warning(code, message, self.path))


def _transform(item: Any, name: str, path: str, dae_scene: Any) -> Any:
    """The pycollada transform for ``<translate>``, ``<rotate>``... (float32, as it computes them)."""
    values = floats(item, path)
    if values.size != _TRANSFORM_SIZES[name]:
        raise fail(f"<{name}> holds {values.size} number(s); it needs {_TRANSFORM_SIZES[name]}", path, item)
    with np.errstate(over="ignore"):
        f = values.astype(np.float32)
    if not np.isfinite(f).all():
        raise fail(f"<{name}> holds a non-finite number ({values.tolist()})", path, item)
    with np.errstate(all="ignore"):
        if name == "translate":
            return dae_scene.TranslateTransform(f[0], f[1], f[2], item)
        if name == "rotate":
            return dae_scene.RotateTransform(f[0], f[1], f[2], f[3], item)
        if name == "scale":
            return dae_scene.ScaleTransform(f[0], f[1], f[2], item)
        if name == "matrix":
            return dae_scene.MatrixTransform(f, item)
        return dae_scene.LookAtTransform(f[0:3], f[3:6], f[6:9], item)


__all__ = ["Instance", "SceneWalk"]
