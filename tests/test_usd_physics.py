"""USD exports read by USD's own tools: pxr validation (0 errors) and the UsdPhysics parser.

Every fixture scene and two URDF robots (the fixture arm and the quirks robot) are exported and parsed
back with ``UsdPhysics.LoadUsdPhysicsFromRange``: one rigid body per MuJoCo body with its mass, one
revolute/prismatic joint per hinge/slide between the right bodies, one articulation per articulated tree.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun import UrdfRobot, World
from simrun.export.usd import export_world_usd
from simrun.scene.scene_file import load_scene

pytest.importorskip("pxr")
from pxr import Usd, UsdPhysics, UsdValidation

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
SCENES = sorted(p for p in (FIXTURES / "scenes").glob("*.toml") if not p.name.endswith(".commands.toml"))


def _parse(path: Path) -> tuple[list[str], dict[str, list[object]]]:
    stage = Usd.Stage.Open(str(path))
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    found = UsdValidation.ValidationContext(validators).Validate(stage)
    errors = [e.GetMessage() for e in found if e.GetType() == UsdValidation.ValidationErrorType.Error]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        parsed = UsdPhysics.LoadUsdPhysicsFromRange(stage, ["/"])
    return errors, {str(kind).rsplit(".", 1)[-1]: list(zip(*value, strict=True)) for kind, value in parsed.items()}


def _check(world: World, out: Path) -> None:
    model, _ = world.compile()
    export_world_usd(world, out)
    errors, parsed = _parse(out)
    assert errors == []
    bodies = parsed.get("RigidBody", [])
    assert len(bodies) == model.nbody - 1
    by_path = {str(path): desc for path, desc in bodies}
    stage = Usd.Stage.Open(str(out))
    name_of = {
        str(p.GetPath()): str(p.GetAttribute("simrun:name").Get())
        for p in stage.Traverse()
        if p.HasAttribute("simrun:name")
    }
    for path in by_path:
        mass = UsdPhysics.MassAPI(stage.GetPrimAtPath(path)).GetMassAttr().Get()
        assert mass == pytest.approx(float(model.body_mass[model.body(name_of[path]).id]), abs=1e-6)
    kinds = {int(mujoco.mjtJoint.mjJNT_HINGE): "RevoluteJoint", int(mujoco.mjtJoint.mjJNT_SLIDE): "PrismaticJoint"}
    for kind, label in kinds.items():
        joints = parsed.get(label, [])
        assert len(joints) == int(np.count_nonzero(model.jnt_type == kind))
        for path, desc in joints:
            j = model.joint(name_of[str(path)]).id
            body = int(model.jnt_bodyid[j])
            parent = int(model.body_parentid[body])
            assert name_of[str(desc.body1)] == model.body(body).name
            assert (name_of[str(desc.body0)] if str(desc.body0) else "") == (model.body(parent).name if parent else "")
            if model.jnt_limited[j]:
                low, high = model.jnt_range[j]
                scale = 180 / np.pi if kind == int(mujoco.mjtJoint.mjJNT_HINGE) else 1.0
                assert (desc.limit.lower, desc.limit.upper) == pytest.approx((low * scale, high * scale), rel=1e-6)
    articulated = {int(model.body_rootid[model.jnt_bodyid[j]]) for j in range(model.njnt) if model.jnt_type[j] in kinds}
    assert len(parsed.get("Articulation", [])) == len(articulated)


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_fixture_scenes_parse_as_physics(scene: Path, tmp_path: Path) -> None:
    _check(load_scene(scene), tmp_path / f"{scene.stem}.usda")


@pytest.mark.parametrize("urdf", ["tiny_arm_description/urdf/tiny_arm.urdf", "quirks/quirks_robot/urdf/quirks.urdf"])
def test_urdf_robots_parse_as_physics(urdf: str, tmp_path: Path) -> None:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(UrdfRobot(name="robot", urdf=urdf))
    _check(world, tmp_path / "robot.usda")


def test_prim_names_are_valid_and_unique(tmp_path: Path) -> None:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(UrdfRobot(name="2arm", urdf="tiny_arm_description/urdf/tiny_arm.urdf"))
    world.insert(UrdfRobot(name="2arm-b", urdf="tiny_arm_description/urdf/tiny_arm.urdf"))
    out = tmp_path / "two.usda"
    export_world_usd(world, out)
    stage = Usd.Stage.Open(str(out))
    paths = [str(p.GetPath()) for p in stage.Traverse()]
    assert len(paths) == len(set(paths)) and all(not part[:1].isdigit() for p in paths for part in p.split("/"))
