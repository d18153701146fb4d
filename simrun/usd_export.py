"""USD export of a whole world from its compiled MuJoCo model, with UsdPhysics schemas physics tools read.

Layout: ``/World/TREE/BODY`` for every body (one ``Xform`` per kinematic tree hanging from the world, its
bodies flat under it at their world poses at ``qpos0``, full names in a ``simrun:name`` attribute; prim
names sanitised to ``[A-Za-z0-9_]``, never starting with a digit, clashes numbered). Each body is a
``RigidBodyAPI`` with ``MassAPI`` (MuJoCo's mass, centre of mass, principal moments and axes; massless
bodies author the mass only); mocap bodies are kinematic. Hinge and slide joints become
``RevoluteJoint``/``PrismaticJoint`` (ball joints ``SphericalJoint``) in ``TREE/joints`` from the parent
body (none: the world) to the child, frames rotated so X is MuJoCo's axis, limits in degrees/metres;
bodies without joints are held by a ``FixedJoint``; free bodies have none. A tree with a moving joint gets
``ArticulationRootAPI``. Geoms become ``Cube``/``Sphere``/``Capsule``/``Cylinder``/``Mesh`` prims
(planes a thin ``Cube``, ellipsoids meshes) under the body's ``collisions`` scope (``CollisionAPI``; meshes
with a ``convexHull`` approximation; collision-only group-3 geoms such as hulls with purpose ``guide``)
or its ``visuals`` scope (purpose ``render``). Z-up, metres, a physics scene with the world's gravity.
"""

from __future__ import annotations

import math
import re
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import trimesh

from meshtool.formats import check_suffix
from simrun.compiled_mesh import compiled_mesh
from simrun.errors import SimrunError
from simrun.outfile import stamp_usd, write_bytes
from simrun.world import World

_UNSAFE = re.compile(r"[^A-Za-z0-9_]")


def _ident(name: str, fallback: str) -> str:
    """A valid prim name: ``[A-Za-z0-9_]``, not starting with a digit."""
    text = _UNSAFE.sub("_", name) or fallback
    return text if not text[0].isdigit() else f"_{text}"


def export_world_usd(
    world: World, out: Path, decorate: Callable[[Any, dict[int, str]], None] | None = None
) -> list[str]:
    """Write the world (at its initial state) as ``.usda``/``.usdc``.

    Actuators on hinge and slide joints become ``UsdPhysics.DriveAPI`` on their joint (:func:`_drive`),
    contact exclusions ``FilteredPairsAPI`` on the first body of each pair; what has no UsdPhysics
    counterpart (equality constraints such as a gripper's mirrored finger, actuators on other
    transmissions) is listed, one line each, in the returned findings and in the root layer's
    ``customLayerData["simrun:unmapped"]``.

    Args:
        world: The world (compiled if needed).
        out: The output file.
        decorate: Called as ``decorate(stage, body_paths)`` (body id to prim path) before the stage is saved:
            how :mod:`simrun.replay_usd` adds time samples to the same stage.

    Raises:
        SimrunError: An unsupported extension or a failed write.

    Returns:
        The unmapped elements, one line each (empty when everything has a UsdPhysics counterpart).
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

    wrong = check_suffix(out, "usd")
    if wrong is not None:
        raise SimrunError(f"{out}: {wrong}")
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
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # body poses at qpos0, the frame the joints are defined in
        names = _Names()
        joint_paths: dict[int, str] = {}
        paths: dict[int, str] = {0: "/World"}
        trees: dict[int, str] = {}
        for b in range(1, model.nbody):
            root_body = int(model.body_rootid[b])
            if root_body not in trees:
                trees[root_body] = names.claim("/World", model.body(root_body).name or f"body{root_body}")
                tree = UsdGeom.Xform.Define(stage, trees[root_body])
                if _articulated(model, root_body):
                    UsdPhysics.ArticulationRootAPI.Apply(tree.GetPrim())
            name = model.body(b).name or f"body{b}"
            paths[b] = names.claim(trees[root_body], name)
            xform = UsdGeom.Xform.Define(stage, paths[b])
            # Bodies are flat under their tree, at their world pose; the full name travels as an attribute.
            xform.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(name)
            _place(xform, data.xpos[b], data.xquat[b], Gf)
            _rigid_body(xform.GetPrim(), model, b, UsdPhysics, Gf)
            joints = [j for j in _joints(model, b) if int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_FREE)]
            free = len(joints) != len(_joints(model, b))
            parent = int(model.body_parentid[b])
            if not joints and not free and model.body_mocapid[b] < 0:
                # welded to its parent (or to the world): a fixed joint keeps it there
                path = names.claim(f"{trees[root_body]}/joints", f"{name}_fixed")
                fixed = UsdPhysics.FixedJoint.Define(stage, path)
                _fixed_frames(fixed, model, b, paths[parent] if parent else None, paths[b], data, Gf)
            for j in joints:
                joint_paths[j] = _joint(
                    stage, model, j, (paths[parent] if parent else None, paths[b]), data, names, trees[root_body]
                )
        for g in range(model.ngeom):
            body = int(model.geom_bodyid[g])
            _geom(stage, model, g, paths[body], names, UsdGeom, UsdPhysics, Gf, Vt, Sdf)
        unmapped = _drives(stage, model, joint_paths) + _filtered_pairs(stage, model, paths)
        unmapped += [_equality_gap(model, e) for e in range(model.neq)]
        if unmapped:
            layer = stage.GetRootLayer()
            layer.customLayerData = {**layer.customLayerData, "simrun:unmapped": Vt.StringArray(unmapped)}
        if decorate is not None:
            decorate(stage, paths)
        stamp_usd(stage.GetRootLayer())  # how a later export knows this file is simrun's to replace
        stage.GetRootLayer().Save()
        try:
            data = scratch.read_bytes()
        except OSError as exc:
            raise SimrunError(f"{out}: usd-core did not write the stage ({exc.strerror})") from None
    write_bytes(out, data)
    return unmapped


def _drives(stage: Any, model: mujoco.MjModel, joints: dict[int, str]) -> list[str]:
    """``DriveAPI`` (type ``force``) on the joint of each actuator; returns the actuators left unmapped.

    MuJoCo's affine actuator ``force = gain * ctrl + bias0 + bias1 * q + bias2 * qdot`` is a UsdPhysics drive
    ``force = stiffness * (target - q) + damping * (targetVelocity - qdot)`` when ``gain`` is fixed:
    ``stiffness = -bias1``, ``damping = -bias2``; a position servo (``bias1 = -gain``) targets the control as
    ``targetPosition``, a velocity servo or DC motor (``bias1 = 0``) as ``targetVelocity = ctrl * gain /
    damping`` (at control 0 both targets are 0). Angular drives take degrees: stiffness and damping per
    degree (times pi / 180). ``maxForce`` is the actuator's force limit (N m or N).
    """
    from pxr import Sdf, UsdPhysics

    gaps = []
    for a in range(model.nu):
        name = model.actuator(a).name or f"actuator{a}"
        j = int(model.actuator_trnid[a][0])
        gain, bias = model.actuator_gainprm[a], model.actuator_biasprm[a]
        affine = int(model.actuator_biastype[a]) in (int(mujoco.mjtBias.mjBIAS_AFFINE), int(mujoco.mjtBias.mjBIAS_NONE))
        if (
            int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT)
            or j not in joints
            or int(model.actuator_gaintype[a]) != int(mujoco.mjtGain.mjGAIN_FIXED)
            or not affine
            or bias[0] != 0.0
            or bias[1] not in (0.0, -gain[0])
        ):
            gaps.append(f"actuator {name}: not a fixed-gain servo on a hinge or slide joint; no UsdPhysics drive")
            continue
        angular = int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE)
        per = math.pi / 180 if angular else 1.0
        prim = stage.GetPrimAtPath(joints[j])
        drive = UsdPhysics.DriveAPI.Apply(prim, "angular" if angular else "linear")
        drive.CreateTypeAttr("force")
        drive.CreateStiffnessAttr(float(-bias[1]) * per)
        drive.CreateDampingAttr(float(-bias[2]) * per)
        if model.actuator_forcelimited[a]:
            drive.CreateMaxForceAttr(float(np.max(np.abs(model.actuator_forcerange[a]))))
        if bias[1] != 0.0:
            drive.CreateTargetPositionAttr(0.0)
        else:
            drive.CreateTargetVelocityAttr(0.0)
        prim.CreateAttribute("simrun:actuator", Sdf.ValueTypeNames.String).Set(name)
    return gaps


def _filtered_pairs(stage: Any, model: mujoco.MjModel, paths: dict[int, str]) -> list[str]:
    """``FilteredPairsAPI``: each contact exclusion (``<exclude>``) as a filtered pair of its two bodies."""
    from pxr import UsdPhysics

    gaps = []
    for k in range(model.nexclude):
        signature = int(model.exclude_signature[k])
        first, second = signature >> 16, signature & 0xFFFF
        if first not in paths or second not in paths:
            gaps.append(f"contact exclusion {k}: bodies {first} and {second} have no prims")
            continue
        api = UsdPhysics.FilteredPairsAPI.Apply(stage.GetPrimAtPath(paths[first]))
        api.CreateFilteredPairsRel().AddTarget(paths[second])
    return gaps


def _equality_gap(model: mujoco.MjModel, e: int) -> str:
    """The finding for equality constraint ``e``: UsdPhysics has no equality constraints (joint couplings)."""
    kind = mujoco.mjtEq(int(model.eq_type[e])).name.removeprefix("mjEQ_").lower()
    name = model.eq(e).name or f"equality{e}"
    if kind == "joint":
        first = model.joint(int(model.eq_obj1id[e])).name
        second = model.joint(int(model.eq_obj2id[e])).name
        ratio = float(model.eq_data[e][1])
        return f"equality {name}: joint coupling {first} = {ratio:g} * {second}; no UsdPhysics counterpart"
    return f"equality {name} ({kind}): no UsdPhysics counterpart"


def _joints(model: mujoco.MjModel, body: int) -> range:
    first = int(model.body_jntadr[body])
    return range(first, first + int(model.body_jntnum[body])) if first >= 0 else range(0)


def _place(xform: Any, pos: Any, quat: Any, Gf: Any) -> None:
    """Translate (double3) and orient (quatd) ops.

    The orientation is double precision: a float quaternion near the identity turns into a rotation off by
    up to 1e-5 rad when USD composes the transform.
    """
    from pxr import UsdGeom

    xform.AddTranslateOp().Set(Gf.Vec3d(*(float(v) for v in pos)))
    w, x, y, z = (float(v) for v in quat)
    xform.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(w, x, y, z))


class _Names:
    """Unique, valid prim paths: names sanitised (``[A-Za-z0-9_]``, no leading digit), clashes numbered."""

    def __init__(self) -> None:
        self.taken: set[str] = set()

    def claim(self, parent: str, name: str) -> str:
        base = _ident(name, "prim")
        path, n = f"{parent}/{base}", 1
        while path in self.taken:
            n += 1
            path = f"{parent}/{base}_{n}"
        self.taken.add(path)
        return path


def _articulated(model: mujoco.MjModel, root: int) -> bool:
    """Whether the tree under ``root`` has a hinge, slide or ball joint (an articulation)."""
    moving = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_BALL))
    return any(
        int(model.body_rootid[model.jnt_bodyid[j]]) == root and int(model.jnt_type[j]) in moving
        for j in range(model.njnt)
    )


def _rigid_body(prim: Any, model: mujoco.MjModel, b: int, UsdPhysics: Any, Gf: Any) -> None:
    """RigidBodyAPI and MassAPI with MuJoCo's mass, centre of mass, principal moments and axes."""
    rigid = UsdPhysics.RigidBodyAPI.Apply(prim)
    if model.body_mocapid[b] >= 0:
        rigid.CreateKinematicEnabledAttr(True)
    mass = UsdPhysics.MassAPI.Apply(prim)
    mass.CreateMassAttr(float(model.body_mass[b]))
    mass.CreateCenterOfMassAttr(Gf.Vec3f(*(float(v) for v in model.body_ipos[b])))
    if np.all(np.asarray(model.body_inertia[b]) > 0):  # massless bodies: neither inertia nor axes (USD's rule)
        mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*(float(v) for v in model.body_inertia[b])))
        w, x, y, z = (float(v) for v in model.body_iquat[b])
        mass.CreatePrincipalAxesAttr(Gf.Quatf(w, x, y, z))


def _fixed_frames(
    joint: Any, model: mujoco.MjModel, b: int, parent: str | None, child: str, data: mujoco.MjData, Gf: Any
) -> None:
    """A fixed joint at the child's origin: its pose in the parent's frame (the world's when ``parent`` is None)."""
    if parent is not None:
        joint.CreateBody0Rel().SetTargets([parent])
        pos, quat = model.body_pos[b], model.body_quat[b]
    else:
        pos, quat = data.xpos[b], data.xquat[b]
    joint.CreateBody1Rel().SetTargets([child])
    joint.CreateLocalPos0Attr(Gf.Vec3f(*(float(v) for v in pos)))
    joint.CreateLocalRot0Attr(Gf.Quatf(*(float(v) for v in quat)))
    joint.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    joint.CreateLocalRot1Attr(Gf.Quatf(1.0, 0.0, 0.0, 0.0))


def _joint(
    stage: Any,
    model: mujoco.MjModel,
    j: int,
    bodies: tuple[str | None, str],
    data: mujoco.MjData,
    names: _Names,
    tree: str,
) -> str:
    """A revolute, prismatic or spherical joint from the parent body (the world when None) to the child."""
    from pxr import Gf, Sdf, UsdPhysics

    parent, child = bodies
    kind = int(model.jnt_type[j])  # plain ints: `in` on numpy ints vs. the enum tuple is unreliable
    path = names.claim(f"{tree}/joints", model.joint(j).name or f"joint{j}")
    body = int(model.jnt_bodyid[j])
    if kind == int(mujoco.mjtJoint.mjJNT_HINGE):
        joint = UsdPhysics.RevoluteJoint.Define(stage, path)
    elif kind == int(mujoco.mjtJoint.mjJNT_SLIDE):
        joint = UsdPhysics.PrismaticJoint.Define(stage, path)
    else:
        joint = UsdPhysics.SphericalJoint.Define(stage, path)
    axis = np.asarray(model.jnt_axis[j], dtype=float)
    # USD joints turn about X of their joint frames; rotate those frames so X is MuJoCo's axis.
    joint.CreateAxisAttr("X")
    to_axis = _x_to(axis / np.linalg.norm(axis))
    if parent is not None:
        joint.CreateBody0Rel().SetTargets([parent])
        frame_pos, frame_quat = np.asarray(model.body_pos[body], float), np.asarray(model.body_quat[body], float)
    else:
        frame_pos, frame_quat = np.asarray(data.xpos[body], float), np.asarray(data.xquat[body], float)
    joint.CreateBody1Rel().SetTargets([child])
    anchor = np.asarray(model.jnt_pos[j], dtype=float)  # in the child body's frame
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, frame_quat)
    in_parent = frame_pos + rotation.reshape(3, 3) @ anchor
    in_parent_rot = np.zeros(4)
    mujoco.mju_mulQuat(in_parent_rot, frame_quat, to_axis)
    joint.CreateLocalPos0Attr(Gf.Vec3f(*(float(v) for v in in_parent)))
    joint.CreateLocalPos1Attr(Gf.Vec3f(*(float(v) for v in anchor)))
    joint.CreateLocalRot0Attr(Gf.Quatf(*(float(v) for v in in_parent_rot)))
    joint.CreateLocalRot1Attr(Gf.Quatf(*(float(v) for v in to_axis)))
    joint.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(model.joint(j).name)
    if model.jnt_limited[j] and kind != int(mujoco.mjtJoint.mjJNT_BALL):
        low, high = (float(v) for v in model.jnt_range[j])
        if kind == int(mujoco.mjtJoint.mjJNT_HINGE):
            low, high = math.degrees(low), math.degrees(high)
        joint.CreateLowerLimitAttr(low)
        joint.CreateUpperLimitAttr(high)
    return path


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
    names: _Names,
    UsdGeom: Any,
    UsdPhysics: Any,
    Gf: Any,
    Vt: Any,
    Sdf: Any,
) -> None:
    """The geom as a gprim under the body's ``collisions`` scope (colliding) or ``visuals`` scope (not)."""
    colliding = bool(model.geom_contype[g] or model.geom_conaffinity[g])
    scope = f"{body_path}/{'collisions' if colliding else 'visuals'}"
    if not stage.GetPrimAtPath(scope):
        UsdGeom.Scope.Define(stage, scope)
    path = names.claim(scope, model.geom(g).name.rsplit("/", 1)[-1] or f"geom{g}")
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
    elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:  # a mesh: USD physics has no scaled-sphere collider
        sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        vertices = np.asarray(sphere.vertices, dtype=float) * size
        prim = UsdGeom.Mesh.Define(stage, path)
        prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(vertices.astype(np.float32)))
        prim.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(sphere.faces)))
        prim.CreateFaceVertexIndicesAttr(Vt.IntArray(np.asarray(sphere.faces).ravel().tolist()))
        prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
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
    if colliding:
        if int(model.geom_group[g]) >= 3:  # collision-only geometry (hulls): not rendered, like MuJoCo's viewer
            UsdGeom.Imageable(prim).CreatePurposeAttr(UsdGeom.Tokens.guide)
        UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
        if kind in (int(mujoco.mjtGeom.mjGEOM_MESH), int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)):
            api = UsdPhysics.MeshCollisionAPI.Apply(prim.GetPrim())
            api.CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
    else:
        UsdGeom.Imageable(prim).CreatePurposeAttr(UsdGeom.Tokens.render)
