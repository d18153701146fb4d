"""The one MJCF builder: a :class:`meshtool.mjcf.model_desc.ModelDesc` or a world's spec to a compiled MJCF folder.

Everything MJCF that meshtool or simrun writes goes through here, on ``mujoco.MjSpec``:

- :func:`spec_from_model` turns meshtool's neutral description into a spec (meshes from arrays, PNG
  textures in the spec's virtual file system, Menagerie's ``visual``/``collision`` default classes);
- :func:`folder_files` turns any spec into the files of a self-contained folder: the XML, one ``.obj``
  per mesh (Wavefront OBJ: vertices, normals, texture coordinates, faces) and one PNG per texture,
  all flat beside the XML and referenced by plain file names, so the folder loads from wherever it is
  moved; the written folder is compiled again before it is returned, and must give the same model;
- :func:`build_files` is the ``meshtool.mjcf`` entry point (``meshtool mjcf``, ``meshtool urdf``);
- :func:`check_model` is the ``meshtool.mjcf`` ``check`` entry point: a compile in memory (``obj2bin``);
- :func:`export_world_mjcf` writes a world (``simrun export --mjcf``).

A model MuJoCo refuses raises :class:`meshtool.mjcf.model_desc.ModelError` with MuJoCo's message and the element
at fault (with the source file and line when the description knows them).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from meshtool.formats import check_suffix, mesh_suffixes, output_named, suffix
from meshtool.mjcf.model_desc import MAX_BODY_DEPTH, GeomDesc, ModelDesc, ModelError, stamp_text
from simrun.errors import SimrunError
from simrun.outfile import GENERATOR, check_output, refuse_inputs, write_bytes

_ELEMENT = re.compile(r"Element name '([^']*)'(?:, id (\d+))?")
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")
_GEOM_TYPES = {
    "mesh": mujoco.mjtGeom.mjGEOM_MESH,
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
}


def spec_from_model(model: ModelDesc, texture_prefix: str = "") -> tuple[mujoco.MjSpec, dict[str, bytes]]:
    """A spec of ``model`` and the PNG files its textures name (``texture_prefix + NAME.png``).

    The PNGs are also set as the spec's ``assets``, so the spec compiles as it is.
    """
    spec = mujoco.MjSpec()
    spec.modelname = model.name
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.compiler.inertiafromgeom = (
        mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
        if model.inertia_from_geoms
        else mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    )
    visual = spec.add_default("visual", spec.default)
    visual.geom.group, visual.geom.contype, visual.geom.conaffinity = 2, 0, 0
    visual.geom.density = 0.0
    collision = spec.add_default("collision", spec.default)
    collision.geom.group = 3
    files: dict[str, bytes] = {}
    for texture in model.textures:
        file = f"{texture_prefix}{texture.name}{suffix('png')}"
        files[file] = texture.png
        spec.add_texture(name=texture.name, type=mujoco.mjtTexture.mjTEXTURE_2D, file=file)
    for material in model.materials:
        mat = spec.add_material(name=material.name, rgba=list(material.rgba))
        if material.texture is not None:
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = material.texture
    for mesh in model.meshes:
        added = spec.add_mesh(name=mesh.name)
        added.uservert = np.asarray(mesh.vertices, np.float64).ravel()
        added.userface = np.asarray(mesh.faces, np.int32).ravel()
        if mesh.normals is not None:
            added.usernormal = np.asarray(mesh.normals, np.float64).ravel()
        if mesh.uvs is not None:
            uv = np.asarray(mesh.uvs, np.float64).copy()
            uv[:, 1] = 1.0 - uv[:, 1]  # OBJ's v = 0 at the image bottom; MuJoCo's texcoords start at the top
            added.usertexcoord = uv.ravel()
        added.inertia = (
            mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX
            if mesh.inertia == "convex"
            else mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        )
        added.maxhullvert = mesh.max_hull_vertices
    classes = {"visual": visual, "collision": collision}
    for geom in model.world_geoms:
        _add_geom(spec.worldbody, geom, classes)
    stack = [(spec.worldbody, body) for body in reversed(model.bodies)]
    while stack:
        parent, desc = stack.pop()
        body = parent.add_body(name=desc.name, pos=list(desc.pos), quat=list(desc.quat))
        if desc.free:
            body.add_freejoint(name=f"{desc.name}_free")
        for joint in desc.joints:
            kind = mujoco.mjtJoint.mjJNT_HINGE if joint.type == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE
            added_joint = body.add_joint(name=joint.name, type=kind, axis=list(joint.axis))
            if joint.range is not None:
                added_joint.range = list(joint.range)
                added_joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            added_joint.damping = [joint.damping, 0.0, 0.0]  # MuJoCo 4: linear, quadratic, cubic
            added_joint.frictionloss = joint.frictionloss
            if joint.actuator_force_range is not None:
                added_joint.actfrcrange = list(joint.actuator_force_range)
                added_joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
        if desc.inertial is not None:
            body.explicitinertial = True
            body.mass = desc.inertial.mass
            body.ipos = list(desc.inertial.pos)
            body.iquat = list(desc.inertial.quat)
            body.inertia = list(desc.inertial.diaginertia)
        for geom in desc.geoms:
            _add_geom(body, geom, classes)
        stack.extend((body, child) for child in reversed(desc.children))
    for coupling in model.couplings:
        equality = spec.add_equality(
            type=mujoco.mjtEq.mjEQ_JOINT,
            name1=coupling.joint1,
            name2=coupling.joint2,
            objtype=mujoco.mjtObj.mjOBJ_JOINT,
        )
        data = np.asarray(equality.data, dtype=np.float64).copy()
        data[:5] = (coupling.offset, coupling.multiplier, 0.0, 0.0, 0.0)  # polycoef: joint1 = c0 + c1 * joint2
        equality.data = data
    for first, second in model.excludes:
        spec.add_exclude(bodyname1=first, bodyname2=second)
    for motor in model.motors:
        actuator = spec.add_actuator(name=motor.name, target=motor.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if motor.ctrl_range is not None:
            actuator.ctrlrange = list(motor.ctrl_range)
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    spec.assets = dict(files)
    return spec, files


def _add_geom(body: Any, geom: GeomDesc, classes: dict[str, Any]) -> None:
    added = body.add_geom(classes[geom.role])
    added.name = geom.name
    added.type = _GEOM_TYPES[geom.type]
    if geom.size:
        added.size = [*geom.size, *([0.0] * (3 - len(geom.size)))]
    if geom.mesh is not None:
        added.meshname = geom.mesh
    if geom.material is not None:
        added.material = geom.material
    if geom.rgba is not None:
        added.rgba = list(geom.rgba)
    added.pos, added.quat = list(geom.pos), list(geom.quat)
    if not geom.contributes_mass:
        added.density = 0.0
    elif geom.mass is not None:
        added.mass = geom.mass
    elif geom.density is not None:
        added.density = geom.density


def compile_spec(spec: mujoco.MjSpec, model: ModelDesc | None = None) -> mujoco.MjModel:
    """``spec.compile()``, MuJoCo's refusal as one :class:`ModelError` naming the element at fault."""
    try:
        return spec.compile()
    except ValueError as exc:
        raise _refusal(str(exc), model) from None


def _refusal(text: str, model: ModelDesc | None) -> ModelError:
    lines = [line.strip() for line in text.replace("Error:", "").splitlines() if line.strip()]
    message = lines[0] if lines else "unknown error"
    if message.startswith("XML parse error 18"):  # tinyxml2's XML_ELEMENT_DEPTH_EXCEEDED
        message = f"the MJCF nests more than 500 elements (bodies at most {MAX_BODY_DEPTH} deep)"
    found = _ELEMENT.search(text)
    element = found.group(1) if found else ""
    where = model.where.get(element) if model is not None and element else None
    detail = f" (element {element!r})" if element else ""
    return ModelError(
        f"MuJoCo refuses the model: {message}{detail}",
        path=where[0] if where else None,
        line=where[1] if where else None,
        hint="fix that element in the source",
    )


def folder_files(
    spec: mujoco.MjSpec,
    xml_name: str,
    vfs: dict[str, bytes] | None = None,
    base_dir: Path | None = None,
    generator: str = "",
    compiled_inertials: bool = False,
) -> dict[str, bytes]:
    """The files of a self-contained MJCF folder for ``spec``: ``xml_name``, ``*.obj`` and ``*.png``.

    Meshes given as arrays, and MuJoCo's legacy binary ``.msh`` meshes (:func:`msh_arrays`), become Wavefront
    ``.obj`` files (:func:`_obj`; other tools read them, as ``mujoco-usd-converter``, where ``.msh`` is read
    by MuJoCo alone); other meshes and textures that name files are copied from ``vfs`` (the spec's
    in-memory files) or from ``base_dir``. Every file name is made unique (MuJoCo caches meshes by file
    name). The result is written to a scratch folder and compiled there with ``MjModel.from_xml_path``; it
    must give the same counts, numbers and mesh arrays as the spec itself (a refusal names the first body,
    joint or geom that differs and the field). A ``generator`` is written as a comment at the top of the XML
    with the other files and their SHA-256 (:func:`meshtool.mjcf.model_desc.stamp_text`).

    Args:
        spec: The model (not changed: a copy is written).
        xml_name: File name of the XML in the folder.
        vfs: In-memory files the spec names (default: the spec's ``assets``).
        base_dir: Where files the spec names and ``vfs`` lacks are read from.
        generator: Written in the XML's stamp comment (none when empty).
        compiled_inertials: Write every body's compiled mass, centre of mass and principal inertia as its
            ``<inertial>`` (MuJoCo's ``compiler saveinertial``). A world's spec needs it: the models it
            attached keep their own ``<compiler>`` settings (``boundmass``, ``boundinertia``,
            ``balanceinertia``, ``inertiafromgeom``, ``inertiagrouprange``, ``settotalmass``) per element,
            which one ``<compiler>`` in the written file cannot say.

    Raises:
        ModelError: MuJoCo refuses the spec, a referenced file is missing, or the written folder loads
            differently.
    """
    vfs = dict(vfs if vfs is not None else spec.assets)
    reference = compile_spec(spec)
    out = spec.copy()
    files: dict[str, bytes] = {}
    used = {xml_name.lower()}

    def claim(stem: str, ext: str) -> str:
        base = _UNSAFE.sub("_", stem) or "asset"
        name = f"{base}{ext}"
        while name.lower() in used:
            base += "_"
            name = f"{base}{ext}"
        used.add(name.lower())
        return name

    msh = output_named("msh").suffixes
    for mesh in out.meshes:
        if mesh.file and mesh.file.lower().endswith(msh):  # MuJoCo's own format: written as OBJ
            _set_arrays(mesh, msh_arrays(_referenced(mesh.file, vfs, base_dir, spec), mesh.file))
            mesh.file = ""
            mesh.content_type = ""
        if mesh.file:
            name = claim(Path(mesh.file).stem, Path(mesh.file).suffix.lower())
            files[name] = _referenced(mesh.file, vfs, base_dir, spec)
        else:
            name = claim(mesh.name, suffix("obj"))
            files[name] = _obj(mesh)
            mesh.uservert, mesh.userface = [], []
            mesh.usernormal, mesh.usertexcoord = [], []
        mesh.file = name
    for texture in out.textures:
        if texture.file:
            name = claim(Path(texture.file).stem, Path(texture.file).suffix.lower())
            files[name] = _referenced(texture.file, vfs, base_dir, spec)
            texture.file = name
        if any(texture.cubefiles):
            raise ModelError(f"texture {texture.name!r}: cube textures from files are not exported")
    out.compiler.meshdir = ""
    out.compiler.texturedir = ""
    out.compiler.saveinertial = compiled_inertials
    if generator:
        out.comment = stamp_text(generator, files)
    out.assets = dict(files)  # to_xml compiles the copy: it reads the new files from memory
    try:
        with exact_numbers():
            files[xml_name] = out.to_xml().encode("utf-8")
    except ValueError as exc:
        raise _refusal(str(exc), None) from None
    _check_folder(files, xml_name, reference)
    return files


@contextlib.contextmanager
def exact_numbers() -> Iterator[None]:
    """Within the block, MuJoCo's XML writer prints every number as the shortest text that reads back the same.

    MuJoCo writes 6 significant digits by default (masses, poses and limits would change on reload); its
    writer has a precision switch (``xml_numeric_format.h``, precision 0 = exact) that the Python bindings do
    not expose, so it is called in ``libmujoco`` directly. Without it the folder check still catches a change.
    """
    lib = _libmujoco()
    if lib is None:
        yield
        return
    previous = int(lib._mjPRIVATE__get_xml_precision())
    lib._mjPRIVATE__set_xml_precision(0)
    try:
        yield
    finally:
        lib._mjPRIVATE__set_xml_precision(previous)


@functools.cache
def _libmujoco() -> Any:
    for path in sorted(Path(mujoco.__file__).parent.glob("libmujoco.so*")) + sorted(
        Path(mujoco.__file__).parent.glob("*mujoco*.dylib")
    ):
        try:
            lib = ctypes.CDLL(str(path))
            lib._mjPRIVATE__get_xml_precision.restype = ctypes.c_int
            lib._mjPRIVATE__set_xml_precision.argtypes = [ctypes.c_int]
            return lib
        except (OSError, AttributeError):
            continue
    return None


def msh_arrays(data: bytes, name: str) -> dict[str, np.ndarray]:
    """The arrays of a MuJoCo ``.msh`` file (MuJoCo's legacy binary mesh; ``name`` names it in errors).

    ``vert`` (n, 3), ``normal`` (n, 3) or (0, 3), ``texcoord`` (n, 2) or (0, 2) float32 and ``face`` (k, 3)
    int32 (vertex indices). The format MuJoCo reads (``user_mesh.cc``, ``LoadMSH``): four little-endian int32
    counts (vertices, normals, texture coordinates, faces; normals and texture coordinates are none or one per
    vertex), then the float32 vertices, normals and texture coordinates and the int32 vertex indices of faces.

    Raises:
        ModelError: The bytes are not such a file (``name`` says which).
    """
    header = np.frombuffer(data[:16], dtype="<i4") if len(data) >= 16 else np.zeros(0, np.int32)
    if len(header) == 4:
        nv, nn, nt, nf = (int(v) for v in header)
        sizes_ok = nv >= 4 and nn in (0, nv) and nt in (0, nv) and nf >= 0
        if sizes_ok and len(data) == 16 + 12 * (nv + nn + nf) + 8 * nt:
            floats = np.frombuffer(data, dtype="<f4", count=3 * nv + 3 * nn + 2 * nt, offset=16)
            faces = np.frombuffer(data, dtype="<i4", count=3 * nf, offset=16 + 4 * len(floats))
            if faces.size == 0 or (faces.min() >= 0 and faces.max() < nv):
                return {
                    "vert": floats[: 3 * nv].reshape(-1, 3),
                    "normal": floats[3 * nv : 3 * (nv + nn)].reshape(-1, 3),
                    "texcoord": floats[3 * (nv + nn) :].reshape(-1, 2),
                    "face": faces.reshape(-1, 3),
                }
    raise ModelError(f"mesh file {name!r} is not a MuJoCo .msh mesh (counts and size disagree)", hint="check the asset")


def _set_arrays(mesh: Any, arrays: dict[str, np.ndarray]) -> None:
    """Give a spec mesh the arrays of a ``.msh`` file (its scale, inertia and other settings stay)."""
    mesh.uservert = arrays["vert"].astype(np.float64).ravel()
    mesh.usernormal = arrays["normal"].astype(np.float64).ravel()
    mesh.usertexcoord = arrays["texcoord"].astype(np.float64).ravel()
    mesh.userface = arrays["face"].astype(np.int32).ravel()


def _referenced(file: str, vfs: dict[str, bytes], base_dir: Path | None, spec: mujoco.MjSpec) -> bytes:
    if file in vfs:
        return vfs[file]
    folder = base_dir if base_dir is not None else Path(".")
    meshes = (*mesh_suffixes(), *output_named("msh").suffixes)
    path = folder / spec.compiler.meshdir / file if file.lower().endswith(meshes) else folder / file
    for candidate in (path, folder / file):
        try:
            return candidate.read_bytes()
        except OSError:
            continue
    raise ModelError(f"the model names {file!r}, which is neither in memory nor on disk", hint="check the asset")


def _obj(mesh: Any) -> bytes:
    """A mesh given as arrays as Wavefront OBJ text: ``v``, ``vn``, ``vt`` and ``f`` lines, 1-based indices.

    Every number is the shortest decimal that reads back as the same float32 (MuJoCo's mesh precision), so
    the folder compiles to the same mesh. Normals and texture coordinates are per vertex, as in the spec (a
    face's corners use the same index for all three). MuJoCo's OBJ reader flips ``v`` (OBJ puts the image
    origin bottom left), so ``1 - v`` is written for each texture coordinate.
    """
    if len(mesh.userfacenormal) or len(mesh.userfacetexcoord):
        raise ModelError(f"mesh {mesh.name!r} has per-corner normal or texture indices, which the export cannot hold")
    v = np.asarray(mesh.uservert, dtype=np.float32).reshape(-1, 3)
    n = np.asarray(mesh.usernormal, dtype=np.float32).reshape(-1, 3)
    t = np.asarray(mesh.usertexcoord, dtype=np.float32).reshape(-1, 2).copy()
    f = np.asarray(mesh.userface, dtype=np.int64).reshape(-1, 3) + 1
    t[:, 1] = np.float32(1.0) - t[:, 1]
    lines = [f"# {GENERATOR}: mesh {mesh.name}, {len(v)} vertices, {len(f)} faces"]  # recognised as ours
    for tag, rows in (("v", v), ("vn", n), ("vt", t)):
        lines.extend(f"{tag} " + " ".join(_short(x) for x in row) for row in rows)
    same = len(n) == len(v), len(t) == len(v)
    for face in f:
        if same == (True, True):
            corners = [f"{i}/{i}/{i}" for i in face]
        elif same[0]:
            corners = [f"{i}//{i}" for i in face]
        elif same[1]:
            corners = [f"{i}/{i}" for i in face]
        else:
            corners = [str(i) for i in face]
        lines.append("f " + " ".join(corners))
    return ("\n".join(lines) + "\n").encode("ascii")


def _short(x: np.float32) -> str:
    """The shortest decimal text that reads back as the float32 ``x``."""
    text = np.format_float_positional(np.float32(x), unique=True, trim="-")
    return "0" if text == "-0" else text


def _check_folder(files: dict[str, bytes], xml_name: str, reference: mujoco.MjModel) -> None:
    """Write ``files`` to a scratch folder and load the XML from there alone; compare with ``reference``."""
    with tempfile.TemporaryDirectory(prefix="simrun-mjcf-") as tmp:
        try:
            for name, data in files.items():
                (Path(tmp) / name).write_bytes(data)
        except OSError as exc:  # a file name the file system refuses (too long), a full scratch disk
            raise ModelError(
                f"the MJCF cannot be written to a scratch folder to check it: {exc.strerror or exc}",
                hint="shorten the model's names, or free space in the temporary folder",
            ) from None
        try:
            loaded = mujoco.MjModel.from_xml_path(str(Path(tmp) / xml_name))
        except ValueError as exc:
            raise _refusal(str(exc), None) from None
    counts = ("nbody", "njnt", "ngeom", "nmesh", "ntex", "nmat", "nu", "neq", "nmeshvert", "nmeshface")
    differ = [c for c in counts if getattr(loaded, c) != getattr(reference, c)]
    if differ:
        what = ", ".join(f"{c} {getattr(loaded, c)} != {getattr(reference, c)}" for c in differ)
        raise ModelError(f"the written MJCF loads differently from the model ({what})")
    for field in _CHECKED:  # exact numbers in the XML; mesh inertias may differ in the last bits (summation order)
        a, b = np.asarray(getattr(loaded, field)), np.asarray(getattr(reference, field))
        if not len(a):  # no joints (a model of bodies and geoms only)
            continue
        if field == "geom_size":  # the sizes a type does not use are not written (a capsule's third)
            used = np.array([_SIZES_USED.get(int(t), 3) for t in reference.geom_type])
            a, b = (np.where(np.arange(3) < used[:, None], x, 0.0) for x in (a, b))
        close = np.isclose(a, b, rtol=1e-9, atol=1e-15).reshape(len(a), -1).all(axis=1)
        if not close.all():
            k = int(np.argmin(close))
            kind = field.partition("_")[0]
            element = {"body": reference.body, "jnt": reference.joint, "geom": reference.geom}[kind](k)
            label = {"body": "body", "jnt": "joint", "geom": "geom"}[kind]
            raise ModelError(
                f"the written MJCF loads differently from the model: {label} {element.name or k!r} {field} "
                f"{_numbers(a[k])} where the model has {_numbers(b[k])}",
                hint="a setting of the model that the MJCF writer cannot say; please report it",
            )
    for field in ("mesh_vert", "mesh_face", "mesh_normal", "mesh_facetexcoord"):
        if not np.array_equal(getattr(loaded, field), getattr(reference, field)):  # float32 numbers written exactly
            raise ModelError(f"the written MJCF loads differently from the model: {field} of its meshes differ")
    # MuJoCo's OBJ reader flips v as 1 - v in float32, whose spacing near 1 is 2**-24 to 2**-23: a v near 0
    # (finer there) cannot come back exactly (0.06472757 reads back as 0.064727545, a .msh fruit fly's)
    if not np.allclose(loaded.mesh_texcoord, reference.mesh_texcoord, rtol=0.0, atol=2.0**-23):
        raise ModelError("the written MJCF loads differently from the model: mesh_texcoord of its meshes differ")


#: How many of ``geom_size``'s three numbers a geom type uses (the others: 3).
_SIZES_USED = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE): 1,
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): 2,
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): 2,
}
#: Per-element numbers the written folder must reproduce (first index: the body, joint or geom).
_CHECKED = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_iquat",
    "body_pos",
    "body_quat",
    "jnt_range",
    "jnt_axis",
    "jnt_limited",
    "geom_size",
    "geom_pos",
    "geom_quat",
)


def _numbers(values: Any) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.atleast_1d(values))


def build_files(model: ModelDesc) -> dict[str, bytes]:
    """The ``meshtool.mjcf`` builder: ``model`` compiled and written as a flat MJCF folder's files.

    Raises:
        ModelError: MuJoCo refuses the model (its message and the element at fault).
    """
    spec, files = spec_from_model(model)
    compile_spec(spec, model)
    return folder_files(spec, f"{model.name}{suffix('mjcf')}", files, generator=model.generator)


def check_model(model: ModelDesc) -> None:
    """The ``meshtool.mjcf`` check: ``model`` compiled in memory, nothing written, nothing simulated.

    Raises:
        ModelError: MuJoCo refuses the model (its message and the element at fault).
    """
    spec, _ = spec_from_model(model)
    compile_spec(spec, model)


def export_world_mjcf(world: Any, out: Path) -> list[Path]:
    """Write ``world`` as ``out`` (an ``.xml``) with its meshes and PNG textures beside it.

    Returns:
        Every file written (the XML last).

    Raises:
        SimrunError: ``out`` does not end in ``.xml``, or the model cannot be written.
    """
    wrong = check_suffix(out, "mjcf")
    if wrong is not None:
        raise SimrunError(f"{out}: {wrong}")
    world.compile()
    try:
        files = folder_files(world.spec, out.name, base_dir=world.base_dir, compiled_inertials=True)
    except ModelError as exc:
        raise SimrunError(f"{out}: {exc.one_line()}") from None
    targets = {out.parent / name: files[name] for name in sorted(files, key=lambda n: (n == out.name, n))}
    refuse_inputs(targets, world=world)  # every file checked before the first is written
    for target, data in targets.items():
        check_output(target, data=data, world=world)
    for target, data in targets.items():
        write_bytes(target, data, world=world)
    return list(targets)
