"""URDF import: a robot's meshes through normalise -> hulls -> pack, and a MuJoCo model of the robot.

The URDF is parsed with yourdfpy from its bytes (so XML and encoding declarations and comments before
``<robot>`` are fine); every mesh it names (``package://NAME/...``, ``package:///...`` for the robot's
own package, relative or ``file://``; OBJ with its MTL and textures, STL/PLY/OFF/GLB/COLLADA through
trimesh with their colours and textures) is found inside the allowed folders, normalised with the link
frame kept (URDF meshes are Z-up; glTF is Y-up by its spec and turned, see
:func:`meshtool.read.placed_up`), scaled (a negative scale mirrors), given collision hulls and
packed as ``.mbin`` once per file and scale, however many links use it.

The model (:class:`meshtool.mjcf.model_desc.ModelDesc`) follows MuJoCo Menagerie: a ``visual`` class (group 2,
no contacts, massless) and a ``collision`` class (group 3, massless here: URDF inertials are the only
source of mass, and a link without one stays massless); one body per link, posed by its parent joint's
origin; a root link named ``world`` is MuJoCo's world body; hinge/slide joints with the URDF limits,
damping and friction; inertials as principal moments with the rotation to their axes (MuJoCo forbids
``fullinertia`` with a rotated frame), made physical like MuJoCo's ``balanceinertia`` with a warning
naming the link; ``mimic`` joints as joint equalities; optional motors with the effort limits.

:func:`write_import` hands the model to the installed MJCF builder, which compiles it before anything is
written.
"""

from __future__ import annotations

import dataclasses
import importlib
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.files.outdir import GENERATOR
from meshtool.files.resolve import Resolver
from meshtool.findings import Finding, warning
from meshtool.formats import suffix
from meshtool.hulls.compute import HullOptions
from meshtool.mjcf.model_desc import (
    MAX_BODY_DEPTH,
    BodyDesc,
    GeomDesc,
    InertialDesc,
    JointCouplingDesc,
    JointDesc,
    ModelDesc,
    MotorDesc,
    balance_inertia,
)
from meshtool.plugins import mjcf_files
from meshtool.repair.mesh import safe_identifier
from meshtool.urdf.geoms import LinkParts, fmt, quat, vec3
from meshtool.urdf.locate import UrdfError

WORLD = "world"
#: Density, kg/m^3, of the collision geoms of a moving link without ``<inertial>`` (MuJoCo's default).
GEOMETRY_DENSITY = 1000.0
#: Longest robot name in bytes: it names ``NAME.xml`` (most file systems allow 255 bytes per name).
MAX_NAME_BYTES = 200


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
        package_search: Look for ``package://NAME`` in folders named ``NAME`` above the URDF and beside them
            (by default only the robot's own package and ``package_dirs``; :mod:`meshtool.urdf.locate`).
    """

    package_dirs: tuple[tuple[str, Path], ...] = ()
    hulls: HullOptions = field(default_factory=HullOptions)
    actuators: bool = False
    free_base: bool = False
    allow_outside: bool = False
    package_search: bool = False


@dataclass(slots=True)
class UrdfImport:
    """An imported robot, in memory.

    Attributes:
        name: The robot's name (an identifier).
        model: The robot's model description (see :mod:`meshtool.mjcf.model_desc`).
        mbins: ``meshes/STEM.mbin`` to bytes, one per distinct mesh file and scale.
        findings: What was noticed and repaired: inertias, missing textures, the normaliser's and the hull
            builder's findings.
        links: Link names in body order (a ``world`` root link is not a body).
        joints: Moving joint names in model order.
        sources: Every file the import read (the URDF, each mesh, its MTL and textures): outputs may never
            replace one of them.
    """

    name: str
    model: ModelDesc
    mbins: dict[str, bytes]
    findings: list[Finding]
    links: list[str]
    joints: list[str]
    sources: list[Path] = field(default_factory=list)

    def mjcf(self) -> dict[str, bytes]:
        """``NAME.xml`` with its OBJ meshes and PNG textures, built and compiled by the MJCF builder.

        Raises:
            ModelError: No builder is installed, or MuJoCo refuses the model.
        """
        return mjcf_files(self.model)


def import_urdf(path: Path, options: UrdfOptions | None = None) -> UrdfImport:
    """Import the robot in ``path``.

    Raises:
        UrdfError: The XML is invalid, a mesh is missing or outside the allowed folders, a scale is zero,
            or a joint type has no MuJoCo equivalent.
        MeshtoolError: A mesh itself cannot be normalised (its own error, naming the mesh file).
    """
    import yourdfpy

    options = options or UrdfOptions()
    data = Resolver(path.parent).read_source(path)
    text = data.decode("utf-8", errors="replace")
    try:
        # Bytes, not text: lxml refuses a str that carries an encoding declaration (what xacro writes).
        robot = yourdfpy.URDF.load(io.BytesIO(data), build_scene_graph=False, load_meshes=False).robot
    except KeyError as exc:  # yourdfpy reads a required attribute that is not there
        raise _missing_attribute(data, str(exc.args[0]) if exc.args else "", path) from None
    except Exception as exc:  # yourdfpy raises lxml and ValueError variants for malformed files
        raise UrdfError(f"not a valid URDF: {str(exc).splitlines()[0]}", path=str(path)) from None
    return _Builder(path, text, options, element_lines(data)).build(robot)


#: Elements that must carry an attribute (URDF specification, ROS wiki "urdf/XML"), by attribute.
_REQUIRED = {
    "name": ("robot", "link", "joint"),
    "link": ("parent", "child"),
    "type": ("joint",),
    "joint": ("mimic",),
    "filename": ("mesh",),
}


def _missing_attribute(data: bytes, key: str, path: Path) -> UrdfError:
    """The error for a required attribute ``key`` that yourdfpy found missing, at the first element lacking it."""
    etree: Any = importlib.import_module("lxml.etree")
    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    tags = _REQUIRED.get(key, ())
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError:
        root = None
    for element in root.iter() if root is not None else ():
        if element.tag in tags and element.get(key) is None:
            return UrdfError(
                f"<{element.tag}> has no {key!r} attribute, which URDF requires",
                path=str(path),
                line=int(element.sourceline) if element.sourceline else None,
                hint=f'add {key}="..." to the <{element.tag}>',
            )
    return UrdfError(f"not a valid URDF: a required attribute {key!r} is missing", path=str(path))


def element_lines(data: bytes) -> dict[tuple[str, str], int]:
    """The 1-based source line of each ``<link>`` and ``<joint>`` of the robot (by name) and ``<mesh>`` (by file).

    Keys are ``("link", name)``, ``("joint", name)`` (children of ``<robot>`` only: a ``<transmission>``'s
    ``<joint>`` is a reference), ``("mesh", filename)`` and ``("robot", "")``; the first element wins. lxml
    (yourdfpy's parser) keeps each element's ``sourceline``; entities are not resolved and nothing is fetched.
    """
    etree: Any = importlib.import_module("lxml.etree")  # installed with yourdfpy; no type stubs

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError:
        return {}
    lines: dict[tuple[str, str], int] = {}
    if root.sourceline:
        lines[("robot", "")] = int(root.sourceline)
    for element in root:
        if element.tag in ("link", "joint") and element.get("name") is not None and element.sourceline:
            lines.setdefault((str(element.tag), str(element.get("name"))), int(element.sourceline))
    for mesh in root.iter("mesh"):
        if mesh.get("filename") is not None and mesh.sourceline:
            lines.setdefault(("mesh", str(mesh.get("filename"))), int(mesh.sourceline))
    return lines


class _Builder(LinkParts):
    def __init__(
        self, path: Path, text: str, options: UrdfOptions, lines: dict[tuple[str, str], int] | None = None
    ) -> None:
        super().__init__(path, text, options, lines)
        self.excludes: list[tuple[str, str]] = []

    # -- structure ------------------------------------------------------------------------------------

    def build(self, robot: Any) -> UrdfImport:
        name = safe_identifier(robot.name or self.path.stem, "robot")
        if len(name.encode()) > MAX_NAME_BYTES:  # NAME.xml must be a file name on every file system
            raise UrdfError(
                f"robot name is {len(name.encode())} bytes long; at most {MAX_NAME_BYTES} (it names the MJCF file)",
                path=str(self.path),
                line=self.lines.get(("robot", "")),
                hint="shorten the <robot name=...>",
            )
        self.materials = {m.name: m for m in (robot.materials or []) if m.name}
        for kind, items in (("link", robot.links), ("joint", robot.joints)):
            seen: set[str] = set()
            for item in items:
                if item.name in seen:  # MuJoCo names bodies and joints after them: they must be unique
                    raise UrdfError(
                        f"{kind} {item.name!r} is defined twice",
                        **self._element(kind, item.name),
                        hint=f"give every <{kind}> its own name",
                    )
                seen.add(item.name)
        links = {link.name: link for link in robot.links}
        children = {j.child for j in robot.joints}
        roots = [n for n in links if n not in children]
        if len(roots) != 1:
            raise UrdfError(f"expected one root link, found {len(roots)} ({', '.join(roots)})", path=str(self.path))
        by_parent: dict[str, list[Any]] = {}
        for joint in robot.joints:
            if joint.parent not in links or joint.child not in links:
                role = "parent" if joint.parent not in links else "child"
                missing = joint.parent if role == "parent" else joint.child
                what = f"names unknown link {missing!r} as its {role}" if missing else f"has a <{role}> without link="
                raise UrdfError(
                    f"joint {joint.name!r} {what}",
                    **self._element("joint", joint.name),
                    hint=f"name one of the robot's <link>s in <{role} link=...>",
                )
            by_parent.setdefault(joint.parent, []).append(joint)
        parent_of: dict[str, str] = {}
        for joint in robot.joints:
            if joint.child in parent_of:  # also every cycle: with one root, a cycle needs a link with two parents
                raise UrdfError(
                    f"link {joint.child!r} is the child of two joints ({parent_of[joint.child]!r} and {joint.name!r})",
                    **self._element("joint", joint.name),
                    hint="a URDF is a tree: give each link one parent joint",
                )
            parent_of[joint.child] = joint.name
        # bodies with an <inertial> keep it; the others are massless unless _mass_from_geometry gives them mass
        model = ModelDesc(name, inertia_from_geoms=True)
        order: list[str] = []
        moving: list[Any] = []
        root = links[roots[0]]
        if root.name == WORLD:
            # The world link is MuJoCo's world body: its geoms are fixed to the world, its children top level.
            if root.inertial is not None and root.inertial.mass:
                self.findings.append(
                    warning("urdf-world-mass", "the world link's inertial is ignored", **self._element("link", WORLD))
                )
            model.world_geoms = self._geoms_of(root)
            for joint in by_parent.get(root.name, []):
                model.bodies.append(self._body(links, by_parent, links[joint.child], joint, order, moving))
        else:
            model.bodies.append(self._body(links, by_parent, root, None, order, moving))
        reached = {roots[0], *order}
        unreached = [n for n in links if n not in reached]
        if unreached:  # a cycle of links not reachable from the root
            raise UrdfError(
                f"link {unreached[0]!r} is not connected to the root link {roots[0]!r} (its joints form a cycle)",
                **self._element("link", unreached[0]),
                hint="a URDF is a tree: connect every link to the root through one parent joint each",
            )
        model.excludes = self.excludes
        model.couplings = self._couplings(robot.joints, {j.name for j in moving})
        model.motors = self._motors(moving)
        self._assets(model)
        model.where = self._locations(links, robot.joints)
        model.generator = f"{GENERATOR} (meshtool urdf)"
        mbins = {f"meshes/{m.prefix}{suffix('mbin')}": m.mbin for m in self.meshes.values()}
        sources = sorted({Path(self.path), *self.sources}, key=str)
        return UrdfImport(name, model, mbins, self.findings, order, [j.name for j in moving], sources)

    def _body(
        self,
        links: dict[str, Any],
        by_parent: dict[str, list[Any]],
        link: Any,
        joint: Any,
        order: list[str],
        moving: list[Any],
    ) -> BodyDesc:
        """The body of ``link`` and its whole subtree, depth first without recursion (chains of any length).

        Bodies, moving joints and contact exclusions come out in the order of a depth-first walk: a link's
        children in the URDF's joint order, each child's exclusion with its parent after the child's subtree.
        """
        top = self._one_body(link, joint, order, moving)
        # Work items: ("visit", parent body, depth, link, joint), or ("exclude", parent body, ...) once the
        # subtree of the parent's last child is done.
        stack: list[tuple[str, BodyDesc, int, Any, Any]] = []

        def push_children(body: BodyDesc, depth: int, name: str) -> None:
            for child in reversed(by_parent.get(name, [])):
                stack.append(("exclude", body, depth, None, None))
                stack.append(("visit", body, depth + 1, links[child.child], child))

        push_children(top, 1, link.name)
        while stack:
            action, parent, depth, child_link, child_joint = stack.pop()
            if action == "exclude":
                self.excludes.append((parent.name, parent.children[-1].name))
                continue
            if depth > MAX_BODY_DEPTH:
                raise UrdfError(
                    f"link {child_link.name!r} is {depth} links deep; MuJoCo's XML reader nests bodies at most "
                    f"{MAX_BODY_DEPTH} deep",
                    **self._element("link", child_link.name),
                    hint="shorten the chain: merge links joined by fixed joints",
                )
            body = self._one_body(child_link, child_joint, order, moving)
            parent.children.append(body)
            push_children(body, depth, child_link.name)
        return top

    def _one_body(self, link: Any, joint: Any, order: list[str], moving: list[Any]) -> BodyDesc:
        """One link's body (pose, joint, inertial, geoms), without its children."""
        where = self._element("joint", joint.name) if joint is not None else self._element("link", link.name)
        what = f"the origin of joint {joint.name!r}" if joint is not None else "an origin"
        pos, quat = self._pose(joint.origin if joint is not None else None, what, where)
        body_name = link.name if link.name != WORLD else "world_link"
        body = BodyDesc(body_name, pos, quat)
        order.append(link.name)
        if joint is None or joint.type == "floating":
            if joint is not None and joint.parent != WORLD:
                raise UrdfError(
                    f"joint {joint.name!r} of type 'floating' is only supported from the world link",
                    **self._element("joint", joint.name),
                    hint="use --free-base for a floating root, or split the robot",
                )
            body.free = self.options.free_base or joint is not None
        else:
            described = self._joint(joint)
            if described is not None:
                body.joints.append(described)
                moving.append(joint)
        body.inertial = self._inertial(link)
        body.geoms = self._geoms_of(link)
        if body.inertial is None and (body.joints or body.free) and link.inertial is None:
            body.geoms = self._mass_from_geometry(link, body.geoms)
        return body

    def _mass_from_geometry(self, link: Any, geoms: list[GeomDesc]) -> list[GeomDesc]:
        """A moving link without ``<inertial>``: its collision geoms give it mass, as MuJoCo's URDF import does.

        MuJoCo refuses a moving body without mass; its own importer infers mass and inertia from the
        geometry at the default density, 1000 kg/m^3 (``inertiafromgeom="auto"``). The collision geoms here
        are convex hulls, so a concave mesh weighs somewhat more than MuJoCo's import of the mesh itself.
        """
        collision = [g for g in geoms if g.role == "collision"]
        if not collision:
            return geoms
        self.findings.append(
            warning(
                "urdf-mass-from-geometry",
                f"link {link.name!r} moves but has no <inertial>: mass and inertia from its {len(collision)} "
                f"collision geom(s) at {GEOMETRY_DENSITY:g} kg/m^3, as MuJoCo's URDF import does",
                **self._element("link", link.name),
            )
        )
        return [
            dataclasses.replace(g, contributes_mass=True, density=GEOMETRY_DENSITY) if g.role == "collision" else g
            for g in geoms
        ]

    def _joint(self, joint: Any) -> JointDesc | None:
        kind = joint.type
        if kind == "fixed":
            return None
        if kind == "planar":
            raise UrdfError(
                f"joint {joint.name!r} of type 'planar' is not supported",
                **self._element("joint", joint.name),
                hint="replace it by two prismatic joints and a revolute one",
            )
        where = self._element("joint", joint.name)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float).reshape(-1)
        if axis.size != 3 or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) == 0:
            shown = " ".join(f"{v:g}" for v in axis)
            zero = axis.size == 3 and np.all(axis == 0)
            raise UrdfError(
                f"joint {joint.name!r} has a zero axis"
                if zero
                else f"joint {joint.name!r} has axis {shown!r}; an axis is 3 finite numbers, not all zero",
                **where,
                hint="fix the <axis xyz=...> of the joint",
            )
        self._finite_values(joint, where)
        described = JointDesc(joint.name, "slide" if kind == "prismatic" else "hinge", vec3(axis))
        limit = joint.limit
        if kind in ("revolute", "prismatic") and limit is not None and limit.lower is not None:
            lower, upper = float(limit.lower), float(limit.upper if limit.upper is not None else limit.lower)
            if lower < upper:
                described.range = (lower, upper)
            else:  # exporters write lower = upper = 0 for "not set"; MuJoCo refuses an empty range
                self.findings.append(
                    warning(
                        "urdf-empty-range",
                        f"joint {joint.name!r}: limits [{lower:g}, {upper:g}] leave no motion; imported unlimited",
                        **self._element("joint", joint.name),
                    )
                )
        if limit is not None and limit.effort:
            described.actuator_force_range = (-abs(float(limit.effort)), abs(float(limit.effort)))
        if joint.dynamics is not None:
            described.damping = float(joint.dynamics.damping or 0.0)
            described.frictionloss = float(joint.dynamics.friction or 0.0)
        return described

    def _finite_values(self, joint: Any, where: dict[str, Any]) -> None:
        """Limits and dynamics of a moving joint: finite, and damping and friction >= 0."""
        limit, dynamics = joint.limit, joint.dynamics
        values = [
            ("<limit lower>", getattr(limit, "lower", None), False),
            ("<limit upper>", getattr(limit, "upper", None), False),
            ("<limit effort>", getattr(limit, "effort", None), False),  # its magnitude is used
            ("<limit velocity>", getattr(limit, "velocity", None), False),
            ("<dynamics damping>", getattr(dynamics, "damping", None), True),
            ("<dynamics friction>", getattr(dynamics, "friction", None), True),
        ]
        for what, value, positive in values:
            if value is None:
                continue
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise UrdfError(
                    f"joint {joint.name!r}: {what} is {value!r}, not a number", **where, hint=f"fix the {what}"
                ) from None
            if not math.isfinite(number) or (positive and number < 0):
                need = "a finite number >= 0" if positive else "a finite number"
                raise UrdfError(
                    f"joint {joint.name!r}: {what} is {number:g}; it must be {need}",
                    **where,
                    hint=f"fix the {what} of the joint",
                )

    def _inertial(self, link: Any) -> InertialDesc | None:
        """Principal moments and axes of the link's inertial; ``None`` when massless."""
        inertial = link.inertial
        if inertial is None or inertial.mass is None:
            return None
        mass = float(inertial.mass)
        if not math.isfinite(mass) or mass < 0:
            raise UrdfError(
                f"link {link.name!r} has mass {inertial.mass!r}; a mass must be a finite number >= 0 (kilograms)",
                **self._element("link", link.name),
                hint="fix the <mass value=...> of the link",
            )
        if mass == 0:
            return None
        tensor = np.asarray(inertial.inertia if inertial.inertia is not None else np.zeros((3, 3)), dtype=float)
        origin = np.asarray(inertial.origin if inertial.origin is not None else np.eye(4), dtype=float)
        if not (np.all(np.isfinite(tensor)) and np.all(np.isfinite(origin))):
            raise UrdfError(
                f"link {link.name!r} has an inertia or inertial origin that is not finite",
                **self._element("link", link.name),
                hint="fix the <inertia> and <origin> of the link's <inertial>",
            )
        tensor = (tensor + tensor.T) / 2
        try:
            moments, axes = np.linalg.eigh(tensor)
        except np.linalg.LinAlgError:
            moments = axes = np.full((3, 3), np.nan)
        if not (np.all(np.isfinite(moments)) and np.all(np.isfinite(axes))):  # entries near 1e308 overflow
            raise UrdfError(
                f"link {link.name!r} has an inertia whose principal moments cannot be computed "
                f"(entries up to {np.max(np.abs(tensor)):.3g} kg m^2)",
                **self._element("link", link.name),
                hint="give the <inertia> in kg m^2",
            )
        if np.linalg.det(axes) < 0:
            axes[:, 2] *= -1
        balanced, changed = balance_inertia(moments)
        if changed:
            self.findings.append(
                warning(
                    "urdf-inertia-fixed",
                    f"link {link.name!r}: principal moments {fmt(moments)} kg m^2 are not physical "
                    f"(MuJoCo needs all > 0 and A + B >= C); replaced by {fmt(balanced)} as balanceinertia does",
                    **self._element("link", link.name),
                )
            )
        rotation = origin[:3, :3] @ axes
        return InertialDesc(mass, vec3(origin[:3, 3]), quat(rotation), vec3(balanced))

    def _couplings(self, joints: list[Any], moving: set[str]) -> list[JointCouplingDesc]:
        """Joint equalities of the ``<mimic>`` elements; those MuJoCo's importer ignores are ignored with a warning.

        A ``<mimic>`` on a joint that does not move (``fixed``: exporters leave them), or naming a joint that
        does not exist or does not move, cannot couple anything: MuJoCo's URDF import loads such robots and
        drops the ``<mimic>`` (talos, alex_psyonic_hands of example-robot-data).
        """
        couplings = []
        names = {j.name for j in joints}
        for joint in joints:
            mimic = joint.mimic
            if mimic is None:
                continue
            if joint.name not in moving or mimic.joint not in moving:
                if joint.name not in moving:
                    why = f"joint {joint.name!r} is {joint.type!r}, not a moving joint"
                elif mimic.joint not in names:
                    why = f"it names joint {mimic.joint!r}, which does not exist"
                else:
                    why = f"joint {mimic.joint!r} does not move"
                self.findings.append(
                    warning(
                        "urdf-mimic-ignored",
                        f"the <mimic> of joint {joint.name!r} is ignored: {why}",
                        **self._element("joint", joint.name),
                    )
                )
                continue
            offset = float(mimic.offset or 0.0)
            multiplier = float(mimic.multiplier if mimic.multiplier is not None else 1.0)
            couplings.append(JointCouplingDesc(joint.name, mimic.joint, offset, multiplier))
        return couplings

    def _motors(self, moving: list[Any]) -> list[MotorDesc]:
        if not self.options.actuators:
            return []
        motors = []
        for joint in moving:
            effort = abs(float(joint.limit.effort)) if joint.limit is not None and joint.limit.effort else 0.0
            motors.append(MotorDesc(joint.name, joint.name, (-effort, effort) if effort > 0 else None))
        return motors

    def _locations(self, links: dict[str, Any], joints: list[Any]) -> dict[str, tuple[str, int | None]]:
        where: dict[str, tuple[str, int | None]] = {}
        for kind, names in (("joint", [j.name for j in joints]), ("link", list(links))):
            for name in names:  # a link's line wins over a joint of the same name (MuJoCo names bodies after links)
                where[name] = (str(self.path), self._element(kind, name).get("line"))
        return where

    # -- geometry -------------------------------------------------------------------------------------


__all__ = ["UrdfError", "UrdfImport", "UrdfOptions", "element_lines", "import_urdf"]
