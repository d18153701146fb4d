"""URDF import: a robot's meshes through normalise -> hulls -> pack, and a MuJoCo MJCF of the robot.

The URDF is parsed with yourdfpy; every mesh it names (``package://``, relative or ``file://``; OBJ with
its MTL and textures, or STL/PLY/DAE through trimesh) is found inside the allowed folders, run through the
same normaliser as ``obj2bin`` with the link frame kept as it is (URDF meshes are already Z-up; no up-axis
rotation), given collision hulls, and packed as ``.mbin``. The MJCF follows MuJoCo Menagerie: a
``visual`` class (group 2, no contacts, massless) and a ``collision`` class (group 3); one body per link,
posed by its parent joint's origin; hinge/slide joints with the URDF limits, damping and friction;
inertials from the URDF; mimic joints as joint equalities; optional motors with the effort limits.

Nothing here writes files except :func:`write_import`, and only inside the output folder.
"""

from __future__ import annotations

import io
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import numpy.typing as npt
import trimesh

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding
from meshtool.hulls import HullOptions, compute_hulls, quality
from meshtool.mesh import safe_identifier
from meshtool.mjcf import mesh_fragment
from meshtool.normalise import NormaliseOptions, prepare, safe_file_stem
from meshtool.outdir import write_file
from meshtool.packfile import pack
from meshtool.packfile.read import parse
from meshtool.resolve import Resolver, find_package_dir, is_file

MESH_TYPES = (".obj", ".stl", ".ply", ".dae", ".off", ".glb")


class UrdfError(MeshtoolError, ValueError):
    """The URDF cannot be imported (bad XML, a missing or escaping mesh, an unsupported construct)."""


@dataclass(frozen=True, slots=True)
class UrdfOptions:
    """Options of ``meshtool urdf``.

    Attributes:
        package_dirs: ``(name, folder)`` pairs for ``package://name/...``; others are searched for upwards
            from the URDF's folder.
        hulls: How collision hulls of collision meshes are made.
        actuators: Add a ``motor`` per moving joint, its control range the URDF effort limit.
        free_base: Give the root link a free joint (a mobile robot); else it is fixed to the world.
        allow_outside: Let relative mesh paths leave the URDF's package folder.
    """

    package_dirs: tuple[tuple[str, Path], ...] = ()
    hulls: HullOptions = field(default_factory=HullOptions)
    actuators: bool = False
    free_base: bool = False
    allow_outside: bool = False


@dataclass(slots=True)
class UrdfImport:
    """An imported robot, in memory.

    Attributes:
        name: The robot's name (an identifier).
        mjcf: File name to bytes: ``NAME.xml`` with its ``.msh`` meshes and PNG textures.
        mbins: ``meshes/STEM.mbin`` to bytes, one per distinct mesh file and scale.
        findings: The normaliser's and the hull builder's findings, per mesh.
        links: Link names in MJCF body order.
        joints: Moving joint names in MJCF order.
    """

    name: str
    mjcf: dict[str, bytes]
    mbins: dict[str, bytes]
    findings: list[Finding]
    links: list[str]
    joints: list[str]


def import_urdf(path: Path, options: UrdfOptions | None = None) -> UrdfImport:
    """Import the robot in ``path``.

    Raises:
        UrdfError: The XML is invalid, a mesh is missing or outside the allowed folders, a scale is not
            uniform and positive, or a joint type has no MuJoCo equivalent.
        MeshtoolError: A mesh itself cannot be normalised (its own error, naming the mesh file).
    """
    import yourdfpy

    options = options or UrdfOptions()
    resolver = Resolver(path.parent)
    text = resolver.read_source(path).decode("utf-8", errors="replace")
    try:
        robot = yourdfpy.URDF.load(io.StringIO(text), build_scene_graph=False, load_meshes=False).robot
    except Exception as exc:  # yourdfpy raises lxml and ValueError variants for malformed files
        raise UrdfError(f"not a valid URDF: {str(exc).splitlines()[0]}", path=str(path)) from None
    builder = _Builder(path, text, options)
    return builder.build(robot)


def write_import(result: UrdfImport, out_dir: Path) -> list[Path]:
    """Write the MJCF, its meshes and textures, and ``meshes/*.mbin`` under ``out_dir`` atomically."""
    written = []
    for name, data in sorted({**result.mjcf, **result.mbins}.items()):
        target = out_dir / name
        write_file(target, data)
        written.append(target)
    return written


class _Builder:
    def __init__(self, path: Path, text: str, options: UrdfOptions) -> None:
        self.path, self.text, self.options = path, text, options
        self.urdf_dir = Path(path).resolve().parent
        self.packages = {name: Path(folder).resolve() for name, folder in options.package_dirs}
        self.meshes: dict[tuple[str, float], tuple[str, Any]] = {}
        self.used: dict[str, set[str]] = {}
        self.mbins: dict[str, bytes] = {}
        self.findings: list[Finding] = []
        self.names: set[str] = set()
        self.primitive_count = 0

    # -- structure ------------------------------------------------------------------------------------

    def build(self, robot: Any) -> UrdfImport:
        name = safe_identifier(robot.name or self.path.stem, "robot")
        links = {link.name: link for link in robot.links}
        children = {j.child for j in robot.joints}
        roots = [n for n in links if n not in children]
        if len(roots) != 1:
            raise UrdfError(f"expected one root link, found {len(roots)} ({', '.join(roots)})", path=str(self.path))
        by_parent: dict[str, list[Any]] = {}
        for joint in robot.joints:
            if joint.parent not in links or joint.child not in links:
                missing = joint.parent if joint.parent not in links else joint.child
                raise UrdfError(f"joint {joint.name!r} names unknown link {missing!r}", **self._where(joint.name))
            by_parent.setdefault(joint.parent, []).append(joint)
        body_lines: list[str] = []
        order: list[str] = []
        moving: list[Any] = []
        self._body(links, by_parent, links[roots[0]], None, 2, body_lines, order, moving)
        extras = self._equalities(robot.joints) + self._actuators(moving)
        files, assets = self._used_assets()
        xml = "\n".join(
            [
                f'<mujoco model="{name}">',
                '  <compiler angle="radian" meshdir="." texturedir="." autolimits="true"/>',
                "  <default>",
                '    <default class="visual"><geom group="2" contype="0" conaffinity="0" mass="0"/></default>',
                '    <default class="collision"><geom group="3"/></default>',
                "  </default>",
                "  <asset>",
                *(f"    {a}" for a in assets),
                "  </asset>",
                "  <worldbody>",
                *body_lines,
                "  </worldbody>",
                *extras,
                "</mujoco>",
                "",
            ]
        )
        files[f"{name}.xml"] = xml.encode("utf-8")
        return UrdfImport(name, files, dict(self.mbins), self.findings, order, [j.name for j in moving])

    def _body(
        self,
        links: dict[str, Any],
        by_parent: dict[str, list[Any]],
        link: Any,
        joint: Any,
        depth: int,
        out: list[str],
        order: list[str],
        moving: list[Any],
    ) -> None:
        pad = " " * depth
        pose = _pose(joint.origin) if joint is not None else ""
        out.append(f"{pad}<body name={quoteattr(link.name)}{pose}>")
        order.append(link.name)
        inner = pad + "  "
        if joint is None:
            if self.options.free_base:
                out.append(f"{inner}<freejoint name={quoteattr(link.name + '_free')}/>")
        else:
            line = self._joint(joint)
            if line:
                out.append(inner + line)
                moving.append(joint)
        if link.inertial is not None and link.inertial.mass and link.inertial.mass > 0:
            out.append(inner + _inertial(link.inertial))
        for kind, items in (("visual", link.visuals), ("collision", link.collisions)):
            for item in items:
                out.extend(inner + g for g in self._geoms(kind, item, link.name))
        for child in by_parent.get(link.name, []):
            self._body(links, by_parent, links[child.child], child, depth + 2, out, order, moving)
        out.append(f"{pad}</body>")

    def _joint(self, joint: Any) -> str:
        kind = joint.type
        if kind == "fixed":
            return ""
        if kind in ("floating", "planar"):
            raise UrdfError(
                f"joint {joint.name!r} of type {kind!r} is not supported inside a robot",
                **self._where(joint.name),
                hint="use --free-base for a floating root, or split the robot",
            )
        mj_type = "slide" if kind == "prismatic" else "hinge"
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        attrs = [f"name={quoteattr(joint.name)}", f'type="{mj_type}"', f'axis="{_vec(axis)}"']
        limit = joint.limit
        if kind in ("revolute", "prismatic") and limit is not None and limit.lower is not None:
            upper = limit.upper if limit.upper is not None else limit.lower
            attrs.append(f'range="{_num(limit.lower)} {_num(upper)}"')
        if limit is not None and limit.effort:
            attrs.append(f'actuatorfrcrange="{_num(-limit.effort)} {_num(limit.effort)}"')
        if joint.dynamics is not None:
            if joint.dynamics.damping:
                attrs.append(f'damping="{_num(joint.dynamics.damping)}"')
            if joint.dynamics.friction:
                attrs.append(f'frictionloss="{_num(joint.dynamics.friction)}"')
        return f"<joint {' '.join(attrs)}/>"

    def _equalities(self, joints: list[Any]) -> list[str]:
        lines = []
        for joint in joints:
            mimic = joint.mimic
            if mimic is None:
                continue
            offset, multiplier = (
                float(mimic.offset or 0.0),
                float(mimic.multiplier if mimic.multiplier is not None else 1.0),
            )
            lines.append(
                f"    <joint joint1={quoteattr(joint.name)} joint2={quoteattr(mimic.joint)} "
                f'polycoef="{_num(offset)} {_num(multiplier)} 0 0 0"/>'
            )
        return ["  <equality>", *lines, "  </equality>"] if lines else []

    def _actuators(self, moving: list[Any]) -> list[str]:
        if not self.options.actuators:
            return []
        lines = []
        for joint in moving:
            effort = float(joint.limit.effort) if joint.limit is not None and joint.limit.effort else 0.0
            limits = f' ctrlrange="{_num(-effort)} {_num(effort)}"' if effort > 0 else ""
            lines.append(f"    <motor name={quoteattr(joint.name)} joint={quoteattr(joint.name)}{limits}/>")
        return ["  <actuator>", *lines, "  </actuator>"] if lines else []

    # -- geometry -------------------------------------------------------------------------------------

    def _geoms(self, kind: str, item: Any, link: str) -> list[str]:
        pose = _pose(item.origin)
        geometry = item.geometry
        cls = f'class="{kind}"'
        rgba = ""
        material = getattr(item, "material", None)
        if material is not None and material.color is not None and material.color.rgba is not None:
            rgba = f' rgba="{_vec(material.color.rgba)}"'
        if geometry.box is not None:
            return [f'<geom {cls} type="box" size="{_vec(np.asarray(geometry.box.size) / 2)}"{pose}{rgba}/>']
        if geometry.cylinder is not None:
            c = geometry.cylinder
            return [f'<geom {cls} type="cylinder" size="{_num(c.radius)} {_num(c.length / 2)}"{pose}{rgba}/>']
        if geometry.sphere is not None:
            return [f'<geom {cls} type="sphere" size="{_num(geometry.sphere.radius)}"{pose}{rgba}/>']
        if geometry.mesh is None:
            raise UrdfError(f"a {kind} of link {link!r} has no geometry", **self._where(link))
        prefix, fragment = self._mesh(geometry.mesh, link)
        self.used[prefix].add(kind)
        geoms = fragment.visual if kind == "visual" else fragment.collision
        if not geoms:
            raise UrdfError(f"{kind} mesh {geometry.mesh.filename!r} gave no geoms", **self._where(link))
        if kind == "visual" and rgba and not any("material=" in g for g in geoms):
            return [f"<geom {g}{pose}{rgba}/>" for g in geoms]
        return [f"<geom {g}{pose}/>" for g in geoms]

    def _used_assets(self) -> tuple[dict[str, bytes], list[str]]:
        """The files and asset elements of the mesh roles used: visual parts, collision hulls, or both."""
        files: dict[str, bytes] = {}
        assets: list[str] = []
        for prefix, fragment in self.meshes.values():
            roles = self.used[prefix]
            for element in fragment.assets:
                is_hull = f'name="{prefix}_collision_' in element
                if ("collision" in roles and is_hull) or ("visual" in roles and not is_hull):
                    assets.append(element)
            for name, data in fragment.files.items():
                is_hull = name.startswith(f"{prefix}_collision_")
                if ("collision" in roles and is_hull) or ("visual" in roles and not is_hull):
                    files[name] = data
        return files, assets

    def _mesh(self, mesh: Any, link: str) -> tuple[str, Any]:
        ref = str(mesh.filename)
        scale = _uniform_scale(mesh.scale)
        if scale is None:
            raise UrdfError(
                f"mesh {ref!r} has scale {mesh.scale!r}; only a uniform positive scale is supported",
                **self._where(ref),
                hint="scale the mesh file itself",
            )
        found, root = self._locate(ref)
        key = (str(found), scale)
        if key in self.meshes:
            return self.meshes[key]
        stem = safe_file_stem(found.stem) or "mesh"
        prefix = safe_identifier(stem, "mesh")
        while prefix in self.names:
            prefix += "_"
        self.names.add(prefix)
        normalise = NormaliseOptions(up="z", scale=scale, name=stem, search_paths=(root,))
        hull_options = self.options.hulls
        is_obj = found.suffix.lower() == ".obj"
        asset = prepare(found, normalise) if is_obj else self._foreign(found, root, normalise)
        hull_set = compute_hulls(asset.mesh, hull_options, found.name)
        report = quality(asset.mesh, hull_set.hulls) if hull_set.hulls else None
        self.findings += [*asset.findings, *hull_set.findings]
        data = pack(asset, False, {"urdf_scale": scale, "hulls": hull_options.fingerprint()}, hull_set.hulls, report)
        self.mbins[f"meshes/{prefix}.mbin"] = data
        fragment = mesh_fragment(parse(data, f"{prefix}.mbin"), prefix, hull_options.max_hull_vertices)
        self.meshes[key] = (prefix, fragment)
        self.used[prefix] = set()
        return prefix, fragment

    def _foreign(self, found: Path, root: Path, normalise: NormaliseOptions) -> Any:
        """STL/PLY/DAE/OFF/GLB through trimesh, handed to the normaliser as an OBJ in a scratch folder."""
        data = Resolver(root).read(found)
        try:
            loaded = trimesh.load(io.BytesIO(data), file_type=found.suffix.lower()[1:], force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise UrdfError(f"trimesh cannot read it: {exc}", path=str(found)) from None
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise UrdfError("has no triangles", path=str(found))
        text = trimesh.exchange.obj.export_obj(loaded, include_normals=False, include_texture=False)  # type: ignore[no-untyped-call]
        with tempfile.TemporaryDirectory(prefix="meshtool-urdf-") as tmp:
            scratch = Path(tmp) / f"{normalise.name}.obj"
            write_file(scratch, str(text).encode("utf-8"))
            return prepare(scratch, normalise)

    def _locate(self, ref: str) -> tuple[Path, Path]:
        """The mesh file and the folder it may reference files in (its package, or the URDF's folder)."""
        text = ref.strip()
        if text.startswith("package://"):
            package, _, rest = text[len("package://") :].partition("/")
            root = self.packages.get(package) or find_package_dir(self.urdf_dir, package)
            if root is None:
                raise UrdfError(
                    f"package {package!r} of mesh {ref!r} not found",
                    **self._where(ref),
                    hint=f"pass --package-dir {package}=FOLDER",
                )
            candidate = root / rest
        else:
            if text.startswith("file://"):
                text = text[len("file://") :]
            root = self._package_root()
            candidate = Path(text) if Path(text).is_absolute() else self.urdf_dir / text
        resolved = candidate.resolve()
        if not self.options.allow_outside and not Resolver(root).inside(resolved):
            raise UrdfError(
                f"mesh {ref!r} is outside the robot's folder {root}",
                **self._where(ref),
                hint="move it into the package, or pass --allow-outside",
            )
        if not is_file(resolved):
            raise UrdfError(f"mesh {ref!r} not found (looked for {resolved})", **self._where(ref))
        if resolved.suffix.lower() not in MESH_TYPES:
            raise UrdfError(f"mesh {ref!r}: unsupported type {resolved.suffix!r}", **self._where(ref))
        return resolved, (root if not self.options.allow_outside else resolved.parent)

    def _package_root(self) -> Path:
        """The package a URDF lives in (``pkg/urdf/x.urdf`` gives ``pkg``), else the URDF's folder."""
        if self.urdf_dir.name in ("urdf", "robots", "xacro") and self.urdf_dir.parent != self.urdf_dir:
            return self.urdf_dir.parent
        return self.urdf_dir

    def _where(self, needle: str) -> dict[str, Any]:
        """``path`` and the 1-based line where ``needle`` first appears in the URDF text."""
        for number, line in enumerate(self.text.splitlines(), 1):
            if needle and needle in line:
                return {"path": str(self.path), "line": number}
        return {"path": str(self.path)}


def _uniform_scale(scale: Any) -> float | None:
    if scale is None:
        return 1.0
    values = np.atleast_1d(np.asarray(scale, dtype=float))
    if values.size not in (1, 3) or not np.all(values > 0) or not np.all(np.isfinite(values)):
        return None
    if np.ptp(values) > 1e-12 * float(np.max(values)):
        return None
    return float(values[0])


def _pose(matrix: Any) -> str:
    """``pos``/``quat`` attributes (wxyz, w >= 0) of a 4x4 homogeneous transform; empty for identity."""
    if matrix is None:
        return ""
    m = np.asarray(matrix, dtype=float)
    pos = m[:3, 3]
    raw = trimesh.transformations.quaternion_from_matrix(m)  # type: ignore[no-untyped-call]
    quat: npt.NDArray[np.float64] = np.array(raw, dtype=np.float64)
    if quat[0] < 0:
        quat = quat * -1.0
    text = ""
    if np.any(pos != 0):
        text += f' pos="{_vec(pos)}"'
    if not np.allclose(quat, (1.0, 0.0, 0.0, 0.0), rtol=0.0, atol=1e-15):
        text += f' quat="{_vec(quat)}"'
    return text


def _inertial(inertial: Any) -> str:
    i = np.asarray(inertial.inertia, dtype=float)
    full = (i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])
    pose = _pose(inertial.origin) or ' pos="0 0 0"'
    return f'<inertial mass="{_num(inertial.mass)}" fullinertia="{_vec(full)}"{pose}/>'


def _vec(values: Any) -> str:
    return " ".join(_num(float(v)) for v in np.asarray(values, dtype=float).ravel())


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


__all__ = ["MESH_TYPES", "UrdfError", "UrdfImport", "UrdfOptions", "import_urdf", "write_import"]
