"""USD export of a whole world from its compiled MuJoCo model, with UsdPhysics schemas.

Bodies become nested ``Xform`` prims under ``/World`` following the kinematic tree, each prim named by the
last part of its body name and carrying the full name (``robot/wheel``) in a ``simrun:name`` string
attribute, placed by their local pose; geoms become ``Cube``/``Sphere``/``Capsule``/
``Cylinder``/``Mesh`` prims (planes a thin ``Cube``); colliding geoms get ``CollisionAPI`` (meshes with a
``convexHull`` approximation); bodies with a free joint get ``RigidBodyAPI`` and ``MassAPI``; hinge and
slide joints become ``RevoluteJoint``/``PrismaticJoint`` with their limits. Z-up, metres, a physics scene
with the world's gravity.
"""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simrun.compiled_mesh import compiled_mesh
from simrun.errors import SimrunError
from simrun.outfile import stamp_usd, write_bytes
from simrun.world import World

_UNSAFE = re.compile(r"[^A-Za-z0-9_]")


def _ident(name: str, fallback: str) -> str:
    text = _UNSAFE.sub("_", name) or fallback
    return text if not text[0].isdigit() else f"_{text}"


def export_world_usd(world: World, out: Path) -> None:
    """Write the world (at its initial state) as ``.usda``/``.usdc``.

    Raises:
        SimrunError: An unsupported extension or a failed write.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

    if out.suffix.lower() not in (".usda", ".usdc", ".usd"):
        raise SimrunError(f"{out}: USD output must end in .usda, .usdc or .usd")
    model = world.model
    with tempfile.TemporaryDirectory(prefix="simrun-usd-") as tmp:
        scratch = Path(tmp) / out.name
        stage = Usd.Stage.CreateNew(str(scratch))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        root = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(root.GetPrim())
        scene = UsdPhysics.Scene.Define(stage, "/PhysicsScene")
        gravity = np.asarray(model.opt.gravity, dtype=float)
        magnitude = float(np.linalg.norm(gravity))
        if magnitude > 0:
            scene.CreateGravityDirectionAttr(Gf.Vec3f(*(gravity / magnitude).tolist()))
        scene.CreateGravityMagnitudeAttr(magnitude)
        paths = {0: "/World"}
        for b in range(1, model.nbody):
            name = model.body(b).name or f"body{b}"
            parent = int(model.body_parentid[b])
            path = f"{paths[parent]}/{_ident(name.rsplit('/', 1)[-1], f'body{b}')}"
            while stage.GetPrimAtPath(path):
                path += "_"
            paths[b] = path
            xform = UsdGeom.Xform.Define(stage, path)
            # Prim paths follow the kinematic tree; the full entity/body name travels as an attribute.
            xform.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(name)
            _place(xform, model.body_pos[b], model.body_quat[b], Gf)
            free = any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for j in _joints(model, b))
            if free or model.body_mocapid[b] >= 0:
                rigid = UsdPhysics.RigidBodyAPI.Apply(xform.GetPrim())
                if model.body_mocapid[b] >= 0:
                    rigid.CreateKinematicEnabledAttr(True)
                UsdPhysics.MassAPI.Apply(xform.GetPrim()).CreateMassAttr(float(model.body_subtreemass[b]))
            for j in _joints(model, b):
                _joint(stage, model, j, paths[parent], path, UsdPhysics, Gf)
        for g in range(model.ngeom):
            _geom(stage, model, g, paths[int(model.geom_bodyid[g])], UsdGeom, UsdPhysics, Gf, Vt, Sdf)
        stamp_usd(stage.GetRootLayer())  # how a later export knows this file is simrun's to replace
        stage.GetRootLayer().Save()
        try:
            data = scratch.read_bytes()
        except OSError as exc:
            raise SimrunError(f"{out}: usd-core did not write the stage ({exc.strerror})") from None
    write_bytes(out, data)


def _joints(model: mujoco.MjModel, body: int) -> range:
    first = int(model.body_jntadr[body])
    return range(first, first + int(model.body_jntnum[body])) if first >= 0 else range(0)


def _place(xform: Any, pos: Any, quat: Any, Gf: Any) -> None:
    xform.AddTranslateOp().Set(Gf.Vec3d(*(float(v) for v in pos)))
    w, x, y, z = (float(v) for v in quat)
    xform.AddOrientOp().Set(Gf.Quatf(w, x, y, z))


def _joint(stage: Any, model: mujoco.MjModel, j: int, parent: str, child: str, UsdPhysics: Any, Gf: Any) -> None:
    kind = int(model.jnt_type[j])  # plain ints: `in` on numpy ints vs. the enum tuple is unreliable
    if kind not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
        return
    path = f"{child}/joint_{_ident(model.joint(j).name.rsplit('/', 1)[-1], str(j))}"
    body = int(model.jnt_bodyid[j])
    if kind == mujoco.mjtJoint.mjJNT_HINGE:
        joint = UsdPhysics.RevoluteJoint.Define(stage, path)
    else:
        joint = UsdPhysics.PrismaticJoint.Define(stage, path)
    axis = np.asarray(model.jnt_axis[j], dtype=float)
    # USD joints turn about X of their joint frames; rotate those frames so X is MuJoCo's axis.
    joint.CreateAxisAttr("X")
    to_axis = _x_to(axis / np.linalg.norm(axis))
    in_parent_rot = np.zeros(4)
    mujoco.mju_mulQuat(in_parent_rot, np.asarray(model.body_quat[body], dtype=float), to_axis)
    joint.CreateBody0Rel().SetTargets([parent])
    joint.CreateBody1Rel().SetTargets([child])
    anchor = np.asarray(model.jnt_pos[j], dtype=float)  # in the child body's frame
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(model.body_quat[body], dtype=float))
    in_parent = np.asarray(model.body_pos[body], dtype=float) + rotation.reshape(3, 3) @ anchor
    joint.CreateLocalPos0Attr(Gf.Vec3f(*(float(v) for v in in_parent)))
    joint.CreateLocalPos1Attr(Gf.Vec3f(*(float(v) for v in anchor)))
    joint.CreateLocalRot0Attr(Gf.Quatf(*(float(v) for v in in_parent_rot)))
    joint.CreateLocalRot1Attr(Gf.Quatf(*(float(v) for v in to_axis)))
    if model.jnt_limited[j]:
        low, high = (float(v) for v in model.jnt_range[j])
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            low, high = math.degrees(low), math.degrees(high)
        joint.CreateLowerLimitAttr(low)
        joint.CreateUpperLimitAttr(high)


def _x_to(axis: np.ndarray) -> np.ndarray:
    """The shortest rotation (wxyz) taking +X onto the unit vector ``axis``."""
    x = np.array([1.0, 0.0, 0.0])
    dot = float(np.dot(x, axis))
    if dot < -1.0 + 1e-12:
        return np.array([0.0, 0.0, 0.0, 1.0])  # half a turn about Z
    quat: np.ndarray = np.array([1.0 + dot, *np.cross(x, axis)])
    quat /= np.linalg.norm(quat)
    return quat


def _geom(
    stage: Any,
    model: mujoco.MjModel,
    g: int,
    body_path: str,
    UsdGeom: Any,
    UsdPhysics: Any,
    Gf: Any,
    Vt: Any,
    Sdf: Any,
) -> None:
    name = _ident(model.geom(g).name.rsplit("/", 1)[-1] or f"geom{g}", f"geom{g}")
    path = f"{body_path}/{name}"
    while stage.GetPrimAtPath(path):
        path += "_"
    kind, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=float)
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        prim = UsdGeom.Cube.Define(stage, path)
        prim.CreateSizeAttr(1.0)
        scale = (2 * size).tolist()
    elif kind == mujoco.mjtGeom.mjGEOM_PLANE:
        prim = UsdGeom.Cube.Define(stage, path)
        prim.CreateSizeAttr(1.0)
        half = float(size[0]) if size[0] > 0 else 50.0
        scale = [2 * half, 2 * (float(size[1]) if size[1] > 0 else 50.0), 0.001]
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        prim = UsdGeom.Sphere.Define(stage, path)
        prim.CreateRadiusAttr(float(size[0]))
        scale = None
    elif kind in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
        cls = UsdGeom.Capsule if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else UsdGeom.Cylinder
        prim = cls.Define(stage, path)
        prim.CreateRadiusAttr(float(size[0]))
        prim.CreateHeightAttr(float(2 * size[1]))
        prim.CreateAxisAttr(UsdGeom.Tokens.z)
        scale = None
    elif kind == mujoco.mjtGeom.mjGEOM_MESH:
        vertices, faces = compiled_mesh(model, int(model.geom_dataid[g]))
        prim = UsdGeom.Mesh.Define(stage, path)
        prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(vertices.astype(np.float32)))
        prim.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
        prim.CreateFaceVertexIndicesAttr(Vt.IntArray(faces.ravel().tolist()))
        prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        scale = None
    else:
        return  # height fields and other types: not exported
    xform = UsdGeom.Xformable(prim)
    if model.geom(g).name:
        prim.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(model.geom(g).name)
    _place(xform, model.geom_pos[g], model.geom_quat[g], Gf)
    if scale is not None:
        xform.AddScaleOp().Set(Gf.Vec3f(*scale))
    rgba = [float(c) for c in model.geom_rgba[g]]
    UsdGeom.Gprim(prim).CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*rgba[:3])]))
    colliding = bool(model.geom_contype[g] or model.geom_conaffinity[g])
    if colliding:
        UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
        if kind == mujoco.mjtGeom.mjGEOM_MESH:
            api = UsdPhysics.MeshCollisionAPI.Apply(prim.GetPrim())
            api.CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
    else:
        UsdGeom.Imageable(prim).CreatePurposeAttr(UsdGeom.Tokens.render)
