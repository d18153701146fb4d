"""URDF import: the fixture arm (package:// meshes in mm, an OBJ with a JPG texture, an STL, primitives)."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
import yourdfpy
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.packfile import load
from meshtool.packfile.read import parse
from meshtool.urdf.import_robot import UrdfError, UrdfOptions, import_urdf
from meshtool.urdf.write import write_import

PKG = Path(__file__).resolve().parent.parent / "fixtures" / "urdf" / "tiny_arm_description"
ARM = PKG / "urdf" / "tiny_arm.urdf"
CONFIG = {"shoulder": 0.7, "elbow": -0.4, "slide": 0.03}


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, mujoco.MjModel]:
    out = tmp_path_factory.mktemp("arm")
    result = import_urdf(ARM, UrdfOptions(actuators=True))
    write_import(result, out)
    return out, mujoco.MjModel.from_xml_path(str(out / "tiny_arm.xml"))


def test_structure_matches_the_urdf(imported: tuple[Path, mujoco.MjModel]) -> None:
    out, model = imported
    assert [model.body(b).name for b in range(1, model.nbody)] == ["base_link", "upper", "fore", "tool", "tip"]
    assert [model.joint(j).name for j in range(model.njnt)] == ["shoulder", "elbow", "slide"]
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
    assert model.jnt_type.tolist() == [hinge, hinge, slide]
    np.testing.assert_array_equal(model.jnt_range, [[-2.0, 2.0], [-1.5, 1.5], [0.0, 0.05]])
    assert model.jnt_limited.tolist() == [1, 1, 1]
    assert model.dof_damping[0] == 0.1 and model.dof_frictionloss[0] == 0.01
    np.testing.assert_array_equal(model.body_mass[1:5], [2.0, 0.5, 0.3, 0.05])
    np.testing.assert_allclose(model.body_ipos[1], [0, 0, 0.025])
    assert model.nu == 3
    np.testing.assert_array_equal(model.actuator_ctrlrange, [[-10, 10], [-5, 5], [-20, 20]])
    # the JPG texture arrives as a PNG, 16 x 16, on the base's material
    assert model.ntex == 1 and (model.tex_width[0], model.tex_height[0]) == (16, 16)
    assert sorted(p.name for p in out.glob("*.png")) == ["base_base.png"]
    # one visual and one collision geom per mesh, primitives as they are
    groups = model.geom_group.tolist()
    assert groups.count(2) == 3 and groups.count(3) == 4
    assert sorted(p.name for p in (out / "meshes").iterdir()) == ["base.mbin", "upper_arm.mbin"]


def test_meshes_keep_the_link_frame_in_metres(imported: tuple[Path, mujoco.MjModel]) -> None:
    out, _ = imported
    with load(out / "meshes" / "base.mbin") as base:
        positions = np.asarray(base.positions, dtype=float)
        np.testing.assert_allclose(positions.min(axis=0), [-0.05, -0.05, 0.0], atol=1e-9)
        np.testing.assert_allclose(positions.max(axis=0), [0.05, 0.05, 0.05], atol=1e-9)
        assert len(base.hulls) == 1 and len(base.textures) == 1
    with load(out / "meshes" / "upper_arm.mbin") as upper:
        positions = np.asarray(upper.positions, dtype=float)
        assert positions[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        assert positions[:, 2].max() == pytest.approx(0.2, abs=1e-7)
        assert np.hypot(positions[:, 0], positions[:, 1]).max() == pytest.approx(0.02, abs=1e-7)
        assert len(upper.indices) == 4 * 24


def test_forward_kinematics_match_yourdfpy(imported: tuple[Path, mujoco.MjModel]) -> None:
    _, model = imported
    data = mujoco.MjData(model)
    for name, value in CONFIG.items():
        data.qpos[model.joint(name).qposadr[0]] = value
    mujoco.mj_kinematics(model, data)
    robot = yourdfpy.URDF.load(str(ARM), load_meshes=False, build_scene_graph=True)
    robot.update_cfg(CONFIG)
    for link in ["base_link", "upper", "fore", "tool", "tip"]:
        expected = robot.get_transform(frame_to=link, frame_from="base_link")
        body = model.body(link).id
        np.testing.assert_allclose(data.xpos[body], expected[:3, 3], atol=1e-6)
        np.testing.assert_allclose(data.xmat[body].reshape(3, 3), expected[:3, :3], atol=1e-6)


def test_the_model_steps_cleanly(imported: tuple[Path, mujoco.MjModel]) -> None:
    _, model = imported
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=500)
    assert np.all(np.isfinite(data.qpos)) and not any(w.number for w in data.warning)
    assert model.jnt_range[2, 0] - 1e-3 <= data.qpos[2] <= model.jnt_range[2, 1] + 1e-3


def test_import_is_deterministic() -> None:
    a, b = import_urdf(ARM), import_urdf(ARM)
    assert a.mjcf() == b.mjcf() and a.mbins == b.mbins


def test_missing_mesh_names_the_urdf_line(tmp_path: Path) -> None:
    with pytest.raises(UrdfError) as info:
        import_urdf(PKG / "urdf" / "missing_mesh.urdf")
    assert info.value.line == 35 and "lower arm.stl" in info.value.message
    result = CliRunner().invoke(main, ["urdf", str(PKG / "urdf" / "missing_mesh.urdf"), "-o", str(tmp_path / "o")])
    assert result.exit_code == 1 and not (tmp_path / "o").exists()
    assert result.output.count("\n") == 1 and "missing_mesh.urdf:35: mesh" in result.output


def test_relative_mesh_outside_the_package_is_refused() -> None:
    with pytest.raises(UrdfError, match="outside the robot's folder") as info:
        import_urdf(PKG / "urdf" / "escape.urdf")
    assert info.value.line == 40
    allowed = import_urdf(PKG / "urdf" / "escape.urdf", UrdfOptions(allow_outside=True))
    assert "meshes/secret.mbin" in allowed.mbins


def test_package_dir_option_finds_a_package_elsewhere(tmp_path: Path) -> None:
    shutil.copytree(PKG / "meshes", tmp_path / "vendor" / "renamed" / "meshes")
    shutil.copytree(PKG / "textures", tmp_path / "vendor" / "renamed" / "textures")
    shutil.copytree(PKG / "meshes", tmp_path / "robot" / "meshes")  # for the relative collision path
    robot = tmp_path / "robot" / "urdf" / "arm.urdf"
    robot.parent.mkdir(parents=True)
    shutil.copy(ARM, robot)
    with pytest.raises(UrdfError, match="--package-dir tiny_arm_description=FOLDER"):
        import_urdf(robot)
    result = CliRunner().invoke(
        main,
        [
            "urdf",
            str(robot),
            "-o",
            str(tmp_path / "out"),
            "--package-dir",
            f"tiny_arm_description={tmp_path / 'vendor' / 'renamed'}",
        ],
    )
    assert result.exit_code == 0, result.output
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "tiny_arm.xml"))
    assert (model.nbody, model.njnt, model.ntex) == (6, 3, 1)


def test_collada_meshes_go_through_trimesh(tmp_path: Path) -> None:
    package = tmp_path / "dae_robot"
    (package / "meshes").mkdir(parents=True)
    box = trimesh.creation.box(extents=(40.0, 60.0, 80.0))  # millimetres
    (package / "meshes" / "block.dae").write_bytes(trimesh.exchange.dae.export_collada(box))  # type: ignore[no-untyped-call]
    (package / "urdf").mkdir()
    (package / "urdf" / "r.urdf").write_text(
        '<robot name="r"><link name="base"><visual><geometry>'
        '<mesh filename="package://dae_robot/meshes/block.dae" scale="0.001 0.001 0.001"/>'
        "</geometry></visual></link></robot>"
    )
    result = import_urdf(package / "urdf" / "r.urdf")
    packed = parse(result.mbins["meshes/block.mbin"], "block.mbin")
    positions = np.asarray(packed.positions, dtype=float)
    np.testing.assert_allclose(positions.max(axis=0) - positions.min(axis=0), [0.04, 0.06, 0.08], atol=1e-9)
    assert len(packed.indices) == 12
