"""The parts of a URDF link: geometry (primitives and meshes), materials, origins, and element locations.

:class:`LinkParts` is the base of the URDF importer's builder (:mod:`meshtool.urdf.import_robot`): it turns a link's
``<visual>``/``<collision>`` into :class:`~meshtool.mjcf.model_desc.GeomDesc` (primitive sizes and origins checked, a
mesh found, read race-free and packed once per file and scale, :mod:`meshtool.urdf.meshes`), and locates every
element in the URDF text for errors and findings.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding
from meshtool.hulls.compute import HullOptions
from meshtool.mjcf.model_desc import GeomDesc, ModelDesc
from meshtool.urdf.locate import FoundMesh, MeshLocator, UrdfError
from meshtool.urdf.meshes import LoadedMesh, load_mesh, mesh_prefix, mesh_sources, parse_scale


class LinkParts:
    """Geometry, materials and element locations of one URDF import.

    Args:
        path: The URDF.
        text: Its text (for locations).
        options: The import's options (``package_dirs``, ``allow_outside``, ``package_search``, ``hulls``).
        lines: :func:`meshtool.urdf.import_robot.element_lines` of the URDF.
    """

    def __init__(self, path: Path, text: str, options: Any, lines: dict[tuple[str, str], int] | None = None) -> None:
        self.path, self.text, self.options = path, text, options
        self.lines = lines or {}
        self.hulls: HullOptions = options.hulls
        self.locator = MeshLocator(
            path,
            dict(options.package_dirs),
            allow_outside=options.allow_outside,
            package_search=options.package_search,
        )
        self.read: dict[str, FoundMesh] = {}
        self.meshes: dict[tuple[str, tuple[float, float, float]], LoadedMesh] = {}
        self.used: dict[str, set[str]] = {}
        self.findings: list[Finding] = []
        self.prefixes: set[str] = set()
        self.materials: dict[str, Any] = {}
        self.sources: set[Path] = set()

    # -- geometry -------------------------------------------------------------------------------------

    def _geoms_of(self, link: Any) -> list[GeomDesc]:
        geoms: list[GeomDesc] = []
        for item in link.visuals:
            geoms += self._geoms("visual", item, link.name)
        for item in link.collisions:
            geoms += self._geoms("collision", item, link.name)
        return geoms

    def _geoms(self, role: Literal["visual", "collision"], item: Any, link: str) -> list[GeomDesc]:
        where = self._element("link", link)
        pos, quat = self._pose(item.origin, f"the origin of a {role} of link {link!r}", where)
        geometry = item.geometry
        rgba = self._rgba(getattr(item, "material", None)) if role == "visual" else None
        common: dict[str, Any] = {"pos": pos, "quat": quat, "contributes_mass": False}
        if geometry.box is not None:
            size = self._sizes(geometry.box.size, 3, f"<box size> of a {role} of link {link!r}", where)
            return [GeomDesc(role, "box", tuple(v / 2 for v in size), rgba=rgba, **common)]
        if geometry.cylinder is not None:
            c = geometry.cylinder
            shape = f"<cylinder> of a {role} of link {link!r}"
            radius, length = self._sizes([c.radius, c.length], 2, f"{shape} radius and length", where)
            return [GeomDesc(role, "cylinder", (radius, length / 2), rgba=rgba, **common)]
        if geometry.sphere is not None:
            shape = f"<sphere radius> of a {role} of link {link!r}"
            return [
                GeomDesc(role, "sphere", self._sizes([geometry.sphere.radius], 1, shape, where), rgba=rgba, **common)
            ]
        if geometry.mesh is None:
            raise UrdfError(f"a {role} of link {link!r} has no geometry", **self._element("link", link))
        loaded = self._mesh(geometry.mesh)
        self.used[loaded.prefix].add(role)
        parts = loaded.parts.visual if role == "visual" else loaded.parts.collision
        if not parts:
            raise UrdfError(f"{role} mesh {geometry.mesh.filename!r} gave no geoms", **self._element("link", link))
        out = []
        for part in parts:
            material = part.material if (loaded.own_materials or rgba is None) else None
            out.append(
                GeomDesc(role, "mesh", mesh=part.mesh, material=material, rgba=None if material else rgba, **common)
            )
        return out

    def _pose(
        self, matrix: Any, what: str, where: dict[str, Any]
    ) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        """:func:`_pose` of an ``<origin>``, refused with ``what`` and ``where`` when it is not finite."""
        if matrix is not None and not np.all(np.isfinite(np.asarray(matrix, dtype=float))):
            raise UrdfError(f"{what} is not finite", **where, hint="fix the xyz and rpy of the <origin>")
        return pose(matrix)

    def _sizes(self, values: Any, count: int, what: str, where: dict[str, Any]) -> tuple[float, ...]:
        """``count`` sizes in metres, each finite and > 0 (MuJoCo refuses others without naming the element)."""
        try:
            sizes = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            sizes = np.array([])
        if sizes.size != count or not (np.all(np.isfinite(sizes)) and np.all(sizes > 0)):
            shown = " ".join(str(v) for v in np.asarray(values, dtype=object).reshape(-1)) if values is not None else ""
            raise UrdfError(
                f"{what} is {shown!r}; {count} finite number(s) > 0 (metres) are needed",
                **where,
                hint="fix the size of the shape",
            )
        return tuple(float(v) for v in sizes)

    def _rgba(self, material: Any) -> tuple[float, float, float, float] | None:
        if material is None:
            return None
        color = material.color
        if color is None and material.name in self.materials:
            color = self.materials[material.name].color
        if color is None or color.rgba is None:
            return None
        rgba = np.asarray(color.rgba, dtype=float).reshape(-1)
        if rgba.size != 4 or not np.all(np.isfinite(rgba)):
            shown = " ".join(f"{v:g}" for v in rgba)
            raise UrdfError(
                f"material {material.name!r} has rgba {shown!r}; a colour is 4 finite numbers (red green blue alpha)",
                **self._where(f'name="{material.name}"') if material.name else {"path": str(self.path)},
                hint="fix the <color rgba=...> of the material",
            )
        r, g, b, a = (float(v) for v in rgba)
        return (r, g, b, a)

    def _assets(self, model: ModelDesc) -> None:
        """The model assets of the mesh roles used: visual parts, collision hulls, or both."""
        for loaded in self.meshes.values():
            roles = self.used[loaded.prefix]
            hulls = {g.mesh for g in loaded.parts.collision}
            for mesh in loaded.parts.meshes:
                if ("collision" in roles and mesh.name in hulls) or ("visual" in roles and mesh.name not in hulls):
                    model.meshes.append(mesh)
            if "visual" in roles:
                model.materials += loaded.parts.materials
                model.textures += loaded.parts.textures

    def _mesh(self, mesh: Any) -> LoadedMesh:
        ref = str(mesh.filename)
        scale = parse_scale(mesh.scale)
        if scale is None:
            raise UrdfError(
                f"mesh {ref!r} has scale {fmt(mesh.scale)}; a scale must be finite and not zero",
                **self._element("mesh", ref),
                hint="fix the scale attribute",
            )
        found = self.read.get(ref.strip())
        if found is None:
            found = self.read[ref.strip()] = self.locator.read(ref, self._element("mesh", ref))
        key = (str(found.path), scale)
        if key not in self.meshes:
            prefix = mesh_prefix(found.path, self.prefixes)
            loaded, findings = load_mesh(found, scale, prefix, self.hulls)
            self.findings += findings
            self.sources |= mesh_sources(found.path, found.root, loaded.mbin)
            self.meshes[key] = loaded
            self.used[prefix] = set()
        return self.meshes[key]

    def _where(self, needle: str) -> dict[str, Any]:
        """``path`` and the 1-based line where ``needle`` first appears in the URDF text."""
        for number, line in enumerate(self.text.splitlines(), 1):
            if needle and needle in line:
                return {"path": str(self.path), "line": number}
        return {"path": str(self.path)}

    def _element(self, kind: str, name: str) -> dict[str, Any]:
        """``path`` and ``line`` of the ``<link>``/``<joint>`` named ``name``, or of ``<mesh filename=name>``."""
        line = self.lines.get((kind, name))
        if line is not None:
            return {"path": str(self.path), "line": line}
        return self._where(name) if kind == "mesh" else self._at(name)

    def _at(self, name: str) -> dict[str, Any]:
        """``path`` and ``line`` of the element whose ``name="..."`` is ``name`` (for findings)."""
        for quote in ('"', "'"):
            found = self._where(f"name={quote}{name}{quote}")
            if "line" in found:
                return found
        return {"path": str(self.path)}  # no line rather than the first line that happens to hold the text


def pose(matrix: Any) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """Position and quaternion (wxyz, w >= 0) of a 4x4 homogeneous transform (identity for ``None``)."""
    if matrix is None:
        return (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)
    m = np.asarray(matrix, dtype=float)
    return vec3(m[:3, 3]), quat(m[:3, :3])


def quat(rotation: Any) -> tuple[float, float, float, float]:
    """The unit quaternion (wxyz, w >= 0) of a 3x3 rotation matrix."""
    import trimesh  # loaded on first use: importing meshtool.urdf.import_robot (as simrun does) stays light

    m = np.eye(4)
    m[:3, :3] = rotation
    raw = trimesh.transformations.quaternion_from_matrix(m)  # type: ignore[no-untyped-call]
    q: npt.NDArray[np.float64] = np.array(raw, dtype=np.float64)
    if q[0] < 0:
        q = -q
    q /= np.linalg.norm(q)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def vec3(values: Any) -> tuple[float, float, float]:
    """The first three values as a tuple of floats."""
    v = np.asarray(values, dtype=float).ravel()
    return (float(v[0]), float(v[1]), float(v[2]))


def fmt(values: Any) -> str:
    """Numbers as ``(a, b, c)`` with 6 significant digits, for messages."""
    return "(" + ", ".join(f"{float(v):.6g}" for v in np.atleast_1d(np.asarray(values, dtype=float))) + ")"


__all__ = ["LinkParts", "fmt", "pose", "quat", "vec3"]
