"""simrun's world-to-USD export: read the stage back and compare it with the compiled model."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from simrun.cli.main import main
from simrun.errors import SimrunError
from simrun.export.usd import export_world_usd
from simrun.scene.scene_file import load_scene

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdPhysics  # noqa: E402

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def _export(scene: str, out: Path) -> tuple[mujoco.MjModel, Usd.Stage]:
    world = load_scene(SCENES / scene)
    world.compile()
    export_world_usd(world, out)
    return world.model, Usd.Stage.Open(str(out))


def test_every_body_and_geom_becomes_a_prim(tmp_path: Path) -> None:
    model, stage = _export("pioneer_room.toml", tmp_path / "room.usda")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    bodies = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    assert len(bodies) == model.nbody - 1
    gprims = [p for p in stage.Traverse() if p.IsA(UsdGeom.Gprim)]
    supported = sum(int(t) != int(mujoco.mjtGeom.mjGEOM_HFIELD) for t in model.geom_type)
    assert len(gprims) == supported
    colliders = [p for p in gprims if p.HasAPI(UsdPhysics.CollisionAPI)]
    assert len(colliders) == int(np.count_nonzero(model.geom_contype | model.geom_conaffinity))
    scene = UsdPhysics.Scene(stage.GetPrimAtPath("/PhysicsScene"))
    assert scene.GetGravityMagnitudeAttr().Get() == pytest.approx(float(np.linalg.norm(model.opt.gravity)))


def test_joints_and_rigid_bodies_match_the_model(tmp_path: Path) -> None:
    model, stage = _export("pioneer_room.toml", tmp_path / "room.usda")
    revolute = [p for p in stage.Traverse() if p.IsA(UsdPhysics.RevoluteJoint)]
    hinges = int(np.count_nonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE))
    assert hinges > 0 and len(revolute) == hinges
    names = {
        str(p.GetAttribute("simrun:name").Get()): p.GetPath()
        for p in stage.Traverse()
        if p.HasAPI(UsdPhysics.RigidBodyAPI)
    }
    for prim in revolute:
        joint = UsdPhysics.RevoluteJoint(prim)
        j = model.joint(str(prim.GetAttribute("simrun:name").Get())).id
        (child,) = joint.GetBody1Rel().GetTargets()
        assert child == names[model.body(int(model.jnt_bodyid[j])).name]
        parent = int(model.body_parentid[model.jnt_bodyid[j]])
        assert list(joint.GetBody0Rel().GetTargets()) == ([names[model.body(parent).name]] if parent else [])
        # the joint frame's X, seen from the child, is MuJoCo's joint axis
        rot = joint.GetLocalRot1Attr().Get()
        quat = np.array([rot.GetReal(), *rot.GetImaginary()], dtype=float)
        x_axis = np.zeros(3)
        mujoco.mju_rotVecQuat(x_axis, np.array([1.0, 0.0, 0.0]), quat)
        assert joint.GetAxisAttr().Get() == "X"
        np.testing.assert_allclose(x_axis, model.jnt_axis[j], atol=1e-6)
    rigid = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    masses = {str(p.GetAttribute("simrun:name").Get()): UsdPhysics.MassAPI(p).GetMassAttr().Get() for p in rigid}
    assert masses == pytest.approx({model.body(b).name: float(model.body_mass[b]) for b in range(1, model.nbody)})


def test_mesh_points_and_world_pose_round_trip(tmp_path: Path) -> None:
    model, stage = _export("head_on_table.toml", tmp_path / "head.usda")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert meshes
    cache = UsdGeom.XformCache()
    checked = 0
    for g in range(model.ngeom):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        mesh_id = int(model.geom_dataid[g])
        v0, nv = int(model.mesh_vertadr[mesh_id]), int(model.mesh_vertnum[mesh_id])
        local = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=float)
        expected = local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        matches = [p for p in meshes if len(UsdGeom.Mesh(p).GetPointsAttr().Get()) == nv]
        assert matches, f"no USD mesh with {nv} points"
        prim = matches[0]
        points = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=float)
        matrix = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=float)
        world = points @ matrix[:3, :3] + matrix[3, :3]  # USD uses row vectors
        np.testing.assert_allclose(world, expected, atol=1e-5)
        counts = UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get()
        assert len(counts) == int(model.mesh_facenum[mesh_id]) and set(counts) == {3}
        checked += 1
    assert checked >= 1


def test_export_is_deterministic_and_cli_writes_it(tmp_path: Path) -> None:
    first, second = tmp_path / "a.usda", tmp_path / "b.usda"
    export_world_usd(_loaded("basic.toml"), first)
    export_world_usd(_loaded("basic.toml"), second)
    assert first.read_bytes() == second.read_bytes()
    out = tmp_path / "cli.usda"
    result = CliRunner().invoke(main, ["export", str(SCENES / "basic.toml"), "--usd", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes() == first.read_bytes()


def test_bad_extension_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(SimrunError, match=r"must end in \.usda"):
        export_world_usd(_loaded("basic.toml"), tmp_path / "scene.obj")
    assert not (tmp_path / "scene.obj").exists()


def _loaded(scene: str):  # type: ignore[no-untyped-def]
    world = load_scene(SCENES / scene)
    world.compile()
    return world


def test_entity_names_and_body_poses_round_trip(tmp_path: Path) -> None:
    model, stage = _export("arm_on_base.toml", tmp_path / "arm.usda")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cache = UsdGeom.XformCache()
    named = {
        str(p.GetAttribute("simrun:name").Get()): p
        for p in stage.Traverse()
        if p.HasAttribute("simrun:name") and not p.IsA(UsdPhysics.Joint)
    }
    assert {model.body(b).name for b in range(1, model.nbody)} <= set(named)
    assert {model.geom(g).name for g in range(model.ngeom) if model.geom(g).name} <= set(named)
    for b in range(1, model.nbody):
        prim = named[model.body(b).name]
        assert prim.GetTypeName() == "Xform"
        matrix = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=float)
        np.testing.assert_allclose(matrix[3, :3], data.xpos[b], atol=1e-6)
        np.testing.assert_allclose(matrix[:3, :3].T, data.xmat[b].reshape(3, 3), atol=1e-6)
