"""A neutral description of a MuJoCo model, and the signatures of the plugins that compile it.

meshtool never imports MuJoCo: ``meshtool mjcf`` and ``meshtool urdf`` describe the model they want
(:class:`ModelDesc`: bodies, joints, inertials, geoms, meshes as arrays, PNG textures, materials,
equalities, motors) and hand it to the *MJCF builder*, a callable registered under the entry-point group
``meshtool.mjcf`` with the name ``builder``. simrun registers :func:`simrun.export.mjcf_builder.build_files`,
which builds a ``mujoco.MjSpec``, writes the XML with its OBJ meshes and PNG textures, and compiles
the written folder before returning it. Without simrun installed, :func:`meshtool.plugins.mjcf_files`
raises :class:`ModelError` with the hint to install it. The same group's ``check`` plugin
(:func:`simrun.export.mjcf_builder.check_model`) only compiles a model in memory:
:func:`meshtool.plugins.check_model` is how ``obj2bin`` asks whether MuJoCo accepts what it packed. The
plugins are found and called in :mod:`meshtool.plugins` only; this module holds the types they share.

Frames and units: metres, radians, kilograms; every pose is relative to the parent body, positions
``(3,)`` and quaternions ``(4,)`` as ``(w, x, y, z)``. Mesh texture coordinates follow OBJ (``v = 0`` at
the image bottom); the builder converts them to MuJoCo's convention.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np
import numpy.typing as npt

from meshtool.errors import MeshtoolError

#: Deepest chain of bodies a model may nest. MuJoCo reads MJCF with tinyxml2, which refuses documents nesting
#: more than 500 elements (``TINYXML2_MAX_ELEMENT_DEPTH``, "XML parse error 18"): a flat MJCF holds 496
#: bodies in one chain; 16 levels are left for the bodies a scene puts around an imported robot.
MAX_BODY_DEPTH = 480

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int32]
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


class ModelError(MeshtoolError, ValueError):
    """A model cannot be written: MuJoCo refuses it, or no MJCF builder is installed."""


@dataclass(slots=True)
class MeshDesc:
    """A triangle mesh given as arrays.

    Attributes:
        name: Unique mesh name (also the stem of its ``.obj`` file).
        vertices: ``(n, 3)`` positions in metres, in the frame of the geoms that use it.
        faces: ``(k, 3)`` vertex indices, counter-clockwise seen from outside.
        normals: ``(n, 3)`` unit vertex normals, or ``None``.
        uvs: ``(n, 2)`` texture coordinates (OBJ convention), or ``None``.
        inertia: ``"shell"`` (visual surfaces) or ``"convex"`` (collision hulls).
        max_hull_vertices: MuJoCo's ``maxhullvert`` (-1: no limit).
    """

    name: str
    vertices: FloatArray
    faces: IntArray
    normals: FloatArray | None = None
    uvs: FloatArray | None = None
    inertia: Literal["shell", "convex"] = "shell"
    max_hull_vertices: int = -1


@dataclass(slots=True)
class TextureDesc:
    """A 2-D texture: ``png`` holds the image file's bytes; written as ``NAME.png``."""

    name: str
    png: bytes


@dataclass(slots=True)
class MaterialDesc:
    """A material: ``rgba`` in 0..1 (multiplied with the texture), and an optional texture name."""

    name: str
    rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)
    texture: str | None = None


@dataclass(slots=True)
class GeomDesc:
    """A geom.

    Attributes:
        role: ``"visual"`` (group 2, no contacts, massless) or ``"collision"`` (group 3).
        type: ``"mesh"``, ``"box"``, ``"sphere"`` or ``"cylinder"``.
        size: MuJoCo sizes in metres (box half-extents; sphere radius; cylinder radius and half-length).
        mesh: Mesh name for ``type == "mesh"``.
        material: Material name, or ``None``.
        rgba: Colour when there is no material, or ``None`` for the default.
        pos: Position in the body frame, metres.
        quat: Orientation in the body frame.
        density: kg/m^3 (``None``: MuJoCo's default); ignored when ``mass`` is given.
        mass: kg, or ``None``.
        contributes_mass: ``False`` makes the geom massless whatever its role.
        name: Geom name, or empty.
    """

    role: Literal["visual", "collision"]
    type: Literal["mesh", "box", "sphere", "cylinder"]
    size: tuple[float, ...] = ()
    mesh: str | None = None
    material: str | None = None
    rgba: tuple[float, float, float, float] | None = None
    pos: Vec3 = (0.0, 0.0, 0.0)
    quat: Quat = IDENTITY
    density: float | None = None
    mass: float | None = None
    contributes_mass: bool = True
    name: str = ""


@dataclass(slots=True)
class InertialDesc:
    """Mass (kg), centre of mass ``pos`` and principal axes ``quat`` in the body frame, principal moments (kg m^2)."""

    mass: float
    pos: Vec3
    quat: Quat
    diaginertia: Vec3


@dataclass(slots=True)
class JointDesc:
    """A hinge (``axis`` turns, radians) or slide (along ``axis``, metres) joint at the body origin.

    Attributes:
        range: ``(lower, upper)`` or ``None`` for unlimited.
        actuator_force_range: ``(lower, upper)`` in N or N m, or ``None``.
    """

    name: str
    type: Literal["hinge", "slide"]
    axis: Vec3
    range: tuple[float, float] | None = None
    damping: float = 0.0
    frictionloss: float = 0.0
    actuator_force_range: tuple[float, float] | None = None


@dataclass(slots=True)
class BodyDesc:
    """A body, posed relative to its parent, with its joints, inertial, geoms and child bodies."""

    name: str
    pos: Vec3 = (0.0, 0.0, 0.0)
    quat: Quat = IDENTITY
    free: bool = False
    joints: list[JointDesc] = field(default_factory=list)
    inertial: InertialDesc | None = None
    geoms: list[GeomDesc] = field(default_factory=list)
    children: list[BodyDesc] = field(default_factory=list)


@dataclass(slots=True)
class JointCouplingDesc:
    """``joint1 = offset + multiplier * joint2`` (a URDF ``mimic``), as a joint equality."""

    joint1: str
    joint2: str
    offset: float = 0.0
    multiplier: float = 1.0


@dataclass(slots=True)
class MotorDesc:
    """A motor on ``joint``; ``ctrl_range`` ``(lower, upper)`` or ``None`` for unlimited."""

    name: str
    joint: str
    ctrl_range: tuple[float, float] | None = None


@dataclass(slots=True)
class ModelDesc:
    """A whole model.

    Attributes:
        name: Model name; also the XML file's stem.
        meshes, textures, materials: Assets, each name unique within its kind.
        world_geoms: Geoms fixed to the world (a URDF ``world`` link).
        bodies: Bodies under the world body.
        couplings: Joint equalities.
        motors: Motors.
        excludes: Body pairs that never collide (links joined by a joint touch by design).
        inertia_from_geoms: Bodies without an inertial get mass from their geoms (``False``: none, as in
            URDF, where a link without ``<inertial>`` is massless).
        where: Element name to ``(file, line)`` of its source, for error messages.
        generator: Who writes the model (``meshtool 0.1.0``), or empty. When set, the builder writes it as a
            comment at the top of the XML followed by the folder's other files and their SHA-256
            (:data:`STAMP_FILES`), so a later write can tell its own files from the user's
            (:func:`stamped_files`).
    """

    name: str
    meshes: list[MeshDesc] = field(default_factory=list)
    textures: list[TextureDesc] = field(default_factory=list)
    materials: list[MaterialDesc] = field(default_factory=list)
    world_geoms: list[GeomDesc] = field(default_factory=list)
    bodies: list[BodyDesc] = field(default_factory=list)
    couplings: list[JointCouplingDesc] = field(default_factory=list)
    motors: list[MotorDesc] = field(default_factory=list)
    excludes: list[tuple[str, str]] = field(default_factory=list)
    inertia_from_geoms: bool = True
    where: dict[str, tuple[str, int | None]] = field(default_factory=dict)
    generator: str = ""


class MjcfBuilder(Protocol):
    """The signature of the ``meshtool.mjcf`` builder plugin."""

    def __call__(self, model: ModelDesc) -> dict[str, bytes]:
        """The files of the compiled-and-checked model: ``NAME.xml``, ``*.obj`` and ``*.png``, flat.

        Raises:
            ModelError: MuJoCo refuses the model (its message and the element at fault).
        """
        ...


class ModelChecker(Protocol):
    """The signature of the ``meshtool.mjcf`` ``check`` plugin."""

    def __call__(self, model: ModelDesc) -> None:
        """Compile ``model`` in memory (no files, no simulation).

        Raises:
            ModelError: MuJoCo refuses the model (its message and the element at fault).
        """
        ...


def balance_inertia(moments: FloatArray) -> tuple[FloatArray, bool]:
    """Principal moments that satisfy the triangle inequality, as MuJoCo's ``balanceinertia`` makes them.

    MuJoCo requires every principal moment positive and ``A + B >= C`` for every ordering. Like
    ``compiler balanceinertia="true"``, moments that break it are all replaced by their mean; moments
    that are all zero or negative become ``1e-9`` kg m^2 (well above MuJoCo's ``mjMINVAL``).

    Returns:
        The moments ``(3,)`` and whether they were changed.
    """
    m = np.asarray(moments, dtype=np.float64).copy()
    ordered = np.sort(m)
    ok = bool(np.all(m > 0) and ordered[0] + ordered[1] >= ordered[2] * (1 - 1e-12))
    if ok:
        return m, False
    mean = float(np.mean(np.clip(m, 0.0, None)))
    return np.full(3, mean if mean > 1e-9 else 1e-9), True


#: The line that starts the file list in an MJCF comment of :attr:`ModelDesc.generator`.
STAMP_FILES = "files (name sha256):"


def stamp_text(generator: str, files: dict[str, bytes]) -> str:
    """The comment text of a stamped MJCF: ``generator``, then one ``NAME SHA256`` line per file, sorted.

    ``-`` and ``%`` in names are written as ``%2D`` and ``%25`` (an XML comment may not hold ``--``).
    """
    import hashlib

    lines = [generator, STAMP_FILES]
    for name in sorted(files):
        quoted = name.replace("%", "%25").replace("-", "%2D")
        lines.append(f"  {quoted} {hashlib.sha256(files[name]).hexdigest()}")
    return "\n".join(lines)


def stamped_files(xml: bytes, generators: tuple[str, ...]) -> dict[str, str] | None:
    """The files (name -> SHA-256) an MJCF's stamp lists, when its generator starts with one of ``generators``.

    Returns:
        ``None`` when the XML carries no such stamp (the user's file, or another tool's).
    """
    import re

    text = xml.decode("utf-8", errors="replace")
    found = re.match(r"\s*(?:<\?xml[^>]*\?>\s*)?<mujoco\b[^>]*>\s*<!--(.*?)-->", text, re.DOTALL)
    if found is None:
        return None
    lines = found.group(1).splitlines()
    if not lines or not lines[0].startswith(generators) or STAMP_FILES not in lines[1:2]:
        return None
    listed: dict[str, str] = {}
    for line in lines[2:]:
        parts = line.split()
        if len(parts) == 2 and re.fullmatch(r"[0-9a-f]{64}", parts[1]):
            listed[parts[0].replace("%2D", "-").replace("%25", "%")] = parts[1]
    return listed
