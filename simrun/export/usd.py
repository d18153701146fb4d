"""USD export of a whole world from its compiled MuJoCo model, with UsdPhysics schemas physics tools read.

Built with the project's one USD writer (:class:`meshtool.export.usd_write.UsdBuilder`: stage, prim names, meshes,
colliders, poses, stamp), as the asset and recording exports are; this module adds what it reads from
MuJoCo: bodies, joints, drives, geoms.

Layout: ``/World/TREE/BODY`` for every body (one ``Xform`` per kinematic tree hanging from the world, its
bodies flat under it at their world poses at ``qpos0``, full names in a ``simrun:name`` attribute; prim
names made valid and unique by the builder's one rule, :func:`meshtool.export.usd_write.prim_name`). Each body is a
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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import trimesh

from meshtool.errors import OutputError
from meshtool.export.usd_write import UsdBuilder
from simrun.errors import SimrunError
from simrun.export.compiled_mesh import compiled_mesh
from simrun.outfile import GENERATOR, write_bytes
from simrun.world.world import World


def export_world_usd(
    world: World, out: Path, decorate: Callable[[UsdBuilder, dict[int, str]], None] | None = None
) -> list[str]:
    """Write the world (at its initial state) as ``.usda``/``.usdc``.

    Actuators on hinge and slide joints become ``UsdPhysics.DriveAPI`` on their joint (:func:`_drives`),
    contact exclusions ``FilteredPairsAPI`` on the first body of each pair; what has no UsdPhysics
    counterpart (equality constraints such as a gripper's mirrored finger, actuators on other
    transmissions) is listed, one line each, in the returned findings and in the root layer's
    ``customLayerData["simrun:unmapped"]``.

    Args:
        world: The world (compiled if needed).
        out: The output file.
        decorate: Called as ``decorate(builder, body_paths)`` (body id to prim path) before the stage is
            saved: how :mod:`simrun.record.replay_usd` adds time samples to the same stage.

    Raises:
        SimrunError: An unsupported extension or a failed write.

    Returns:
        The unmapped elements, one line each (empty when everything has a UsdPhysics counterpart).
    """
    from pxr import Sdf, UsdPhysics, Vt

    try:
        usd = UsdBuilder(out, "World", GENERATOR)
    except OutputError as exc:
        raise SimrunError(f"{out}: {exc.message}") from None
    with usd:
        model = world.model
        stage = usd.stage
        usd.physics_scene(model.opt.gravity)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)  # body poses at qpos0, the frame the joints are defined in
        joint_paths: dict[int, str] = {}
        paths: dict[int, str] = {0: usd.root}
        trees: dict[int, str] = {}
        for b in range(1, model.nbody):
            root_body = int(model.body_rootid[b])
            if root_body not in trees:
                trees[root_body] = usd.child(usd.root, model.body(root_body).name or f"body{root_body}")
                tree = usd.xform(trees[root_body])
                if _articulated(model, root_body):
                    UsdPhysics.ArticulationRootAPI.Apply(tree.GetPrim())
            name = model.body(b).name or f"body{b}"
            paths[b] = usd.child(trees[root_body], name)
            xform = usd.xform(paths[b])
            # Bodies are flat under their tree, at their world pose; the full name travels as an attribute.
            xform.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(name)
            usd.place(xform, data.xpos[b], data.xquat[b])
            _rigid_body(xform.GetPrim(), model, b)
            joints = [j for j in _joints(model, b) if int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_FREE)]
            free = len(joints) != len(_joints(model, b))
            parent = int(model.body_parentid[b])
            if not joints and not free and model.body_mocapid[b] < 0:
                # welded to its parent (or to the world): a fixed joint keeps it there
                path = usd.child(usd.group(trees[root_body], "joints"), f"{name}_fixed")
                fixed = UsdPhysics.FixedJoint.Define(stage, path)
                _fixed_frames(fixed, model, b, paths[parent] if parent else None, paths[b], data)
            for j in joints:
                joint_paths[j] = _joint(
                    usd, model, j, (paths[parent] if parent else None, paths[b]), data, trees[root_body]
                )
        for g in range(model.ngeom):
            _geom(usd, model, g, paths[int(model.geom_bodyid[g])])
        unmapped = _drives(stage, model, joint_paths) + _filtered_pairs(stage, model, paths)
        unmapped += [_equality_gap(model, e) for e in range(model.neq)]
        if unmapped:
            layer = stage.GetRootLayer()
            layer.customLayerData = {**layer.customLayerData, "simrun:unmapped": Vt.StringArray(unmapped)}
        if decorate is not None:
            decorate(usd, paths)
        try:
            saved = usd.finish()
        except OutputError as exc:
            raise SimrunError(f"{out}: {exc.message}") from None
    write_bytes(out, saved, world=world)
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
        if int(model.eq_obj2id[e]) < 0:  # one joint: q1 - q1_0 = polycoef[0] (MuJoCo's rule), so held there
            j = int(model.eq_obj1id[e])
            held = float(model.qpos0[model.jnt_qposadr[j]]) + float(model.eq_data[e][0])
            return f"equality {name}: joint {first} held at {held:g}; no UsdPhysics counterpart"
        second = model.joint(int(model.eq_obj2id[e])).name
        ratio = float(model.eq_data[e][1])
        return f"equality {name}: joint coupling {first} = {ratio:g} * {second}; no UsdPhysics counterpart"
    return f"equality {name} ({kind}): no UsdPhysics counterpart"


def _joints(model: mujoco.MjModel, body: int) -> range:
    first = int(model.body_jntadr[body])
    return range(first, first + int(model.body_jntnum[body])) if first >= 0 else range(0)


def _articulated(model: mujoco.MjModel, root: int) -> bool:
    """Whether the tree under ``root`` has a hinge, slide or ball joint (an articulation)."""
    moving = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_BALL))
    return any(
        int(model.body_rootid[model.jnt_bodyid[j]]) == root and int(model.jnt_type[j]) in moving
        for j in range(model.njnt)
    )


def _rigid_body(prim: Any, model: mujoco.MjModel, b: int) -> None:
    """RigidBodyAPI and MassAPI with MuJoCo's mass, centre of mass, principal moments and axes."""
    from pxr import Gf, UsdPhysics

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
    joint: Any, model: mujoco.MjModel, b: int, parent: str | None, child: str, data: mujoco.MjData
) -> None:
    """A fixed joint at the child's origin: its pose in the parent's frame (the world's when ``parent`` is None)."""
    from pxr import Gf

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
    usd: UsdBuilder, model: mujoco.MjModel, j: int, bodies: tuple[str | None, str], data: mujoco.MjData, tree: str
) -> str:
    """A revolute, prismatic or spherical joint from the parent body (the world when None) to the child."""
    from pxr import Gf, Sdf, UsdPhysics

    parent, child = bodies
    kind = int(model.jnt_type[j])  # plain ints: `in` on numpy ints vs. the enum tuple is unreliable
    stage = usd.stage
    path = usd.child(usd.group(tree, "joints"), model.joint(j).name or f"joint{j}")
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


#: Geom types the export writes (height fields and others are left out).
_EXPORTED = {
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_BOX,
        mujoco.mjtGeom.mjGEOM_PLANE,
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_ELLIPSOID,
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        mujoco.mjtGeom.mjGEOM_MESH,
    )
}


def _geom(usd: UsdBuilder, model: mujoco.MjModel, g: int, body_path: str) -> None:
    """The geom as a gprim under the body's ``collisions`` scope (colliding) or ``visuals`` scope (not).

    Boxes are unit ``Cube`` prims scaled to their full size, planes thin cubes of their drawn size (50 m
    half-sizes when infinite), ellipsoids icosphere meshes (USD physics has no scaled-sphere collider),
    capsules and cylinders along Z; meshes are MuJoCo's compiled vertices (the mesh frame MuJoCo centred and
    aligned) under the geom's pose in its body.
    """
    from pxr import Gf, Sdf, UsdGeom

    kind, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=float)
    if kind not in _EXPORTED:
        return
    stage = usd.stage
    colliding = bool(model.geom_contype[g] or model.geom_conaffinity[g])
    scope = usd.group(body_path, "collisions" if colliding else "visuals")
    path = usd.child(scope, model.geom(g).name.rsplit("/", 1)[-1] or f"geom{g}")
    scale = None
    if kind in (int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_PLANE)):
        prim = UsdGeom.Cube.Define(stage, path)
        prim.CreateSizeAttr(1.0)
        if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
            scale = (2 * size).tolist()
        else:
            half_x = float(size[0]) if size[0] > 0 else 50.0
            half_y = float(size[1]) if size[1] > 0 else 50.0
            scale = [2 * half_x, 2 * half_y, 0.001]
    elif kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        prim = UsdGeom.Sphere.Define(stage, path)
        prim.CreateRadiusAttr(float(size[0]))
    elif kind == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        prim = usd.mesh(path, np.asarray(sphere.vertices, dtype=float) * size, np.asarray(sphere.faces))
    elif kind in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
        cls = UsdGeom.Capsule if kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE) else UsdGeom.Cylinder
        prim = cls.Define(stage, path)
        prim.CreateRadiusAttr(float(size[0]))
        prim.CreateHeightAttr(float(2 * size[1]))
        prim.CreateAxisAttr(UsdGeom.Tokens.z)
    else:
        prim = usd.mesh(path, *compiled_mesh(model, int(model.geom_dataid[g])))
    if model.geom(g).name:
        prim.GetPrim().CreateAttribute("simrun:name", Sdf.ValueTypeNames.String).Set(model.geom(g).name)
    usd.place(prim, model.geom_pos[g], model.geom_quat[g])
    if scale is not None:
        UsdGeom.Xformable(prim).AddScaleOp().Set(Gf.Vec3f(*scale))
    usd.display_colour(prim, model.geom_rgba[g])
    if colliding:
        if int(model.geom_group[g]) >= 3:  # collision-only geometry (hulls): not rendered, like MuJoCo's viewer
            usd.purpose(prim, guide=True)
        usd.collider(prim, convex_hull=kind in (int(mujoco.mjtGeom.mjGEOM_MESH), int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)))
    else:
        usd.purpose(prim, guide=False)
