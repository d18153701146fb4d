"""URDF quirks of real robot repositories, one small robot with all of them (fixtures/urdf/quirks/).

Ground truth is the URDF's own numbers and yourdfpy's kinematics; the MJCF is the one written to disk and
loaded by MuJoCo from that folder.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
import yourdfpy
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.packfile.read import parse
from meshtool.urdf.import_robot import UrdfImport, import_urdf
from meshtool.urdf.write import write_import

URDF = Path(__file__).resolve().parent.parent / "fixtures" / "urdf" / "quirks" / "quirks_robot" / "urdf" / "quirks.urdf"


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> tuple[UrdfImport, mujoco.MjModel]:
    out = tmp_path_factory.mktemp("quirks")
    result = import_urdf(URDF)
    write_import(result, out)
    return result, mujoco.MjModel.from_xml_path(str(out / "quirks.xml"))


def test_declaration_and_comments_before_the_root_and_the_world_link(imported) -> None:  # type: ignore[no-untyped-def]
    assert URDF.read_text().startswith('<?xml version="1.0" encoding="utf-8"?>\n<!--')
    _, model = imported
    assert [model.body(b).name for b in range(1, model.nbody)] == ["base", "arm", "sensor", "left", "right"]
    assert model.body_parentid[model.body("base").id] == 0 and model.body("base").jntnum[0] == 0
    world_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == 0]
    assert len(world_geoms) == 2  # the world link's box, visual and collision, on MuJoCo's world body
    np.testing.assert_allclose(model.geom_size[world_geoms[0]], [0.2, 0.2, 0.01])


def test_zero_inertia_is_balanced_with_a_warning_naming_the_link(imported) -> None:  # type: ignore[no-untyped-def]
    result, model = imported
    (finding,) = [f for f in result.findings if f.code == "urdf-inertia-fixed"]
    assert "'base'" in finding.message and finding.line == 14
    assert model.body_mass[model.body("base").id] == 1.5
    assert np.all(model.body_inertia[model.body("base").id] > 0)


def test_rotated_inertial_frame_gives_the_urdf_tensor(imported) -> None:  # type: ignore[no-untyped-def]
    _, model = imported
    b = model.body("arm").id
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.body_iquat[b])
    r = rotation.reshape(3, 3)
    tensor = r @ np.diag(model.body_inertia[b]) @ r.T
    origin = yourdfpy.URDF.load(str(URDF), load_meshes=False, build_scene_graph=False).link_map["arm"].inertial
    source = np.array([[0.002, 0.0003, -0.0001], [0.0003, 0.003, 0.0002], [-0.0001, 0.0002, 0.004]])
    expected = origin.origin[:3, :3] @ source @ origin.origin[:3, :3].T
    np.testing.assert_allclose(tensor, expected, atol=1e-15)
    np.testing.assert_allclose(model.body_ipos[b], [0.1, 0.01, 0.02], atol=1e-15)


def test_massless_link_stays_massless_and_total_mass_is_the_urdfs(imported) -> None:  # type: ignore[no-untyped-def]
    _, model = imported
    assert model.body_mass[model.body("sensor").id] == 0.0
    assert model.body_mass.sum() == pytest.approx(1.5 + 0.4 + 0.05 + 0.05, abs=1e-12)


def test_mirrored_mesh_is_reflected_with_outward_faces(imported) -> None:  # type: ignore[no-untyped-def]
    result, _ = imported
    assert sorted(result.mbins) == [f"meshes/{n}.mbin" for n in ("fin", "fin_", "fin__", "knob", "painted")]
    left, right = (parse(result.mbins[f"meshes/{n}.mbin"], n) for n in ("fin_", "fin__"))
    a, b = np.asarray(left.positions, float), np.asarray(right.positions, float)
    np.testing.assert_allclose(np.sort(b[:, 1]), np.sort(-a[:, 1]), atol=1e-7)
    for packed in (left, right):
        mesh = trimesh.Trimesh(np.asarray(packed.positions, float), np.asarray(packed.indices), process=False)
        assert mesh.volume > 0  # counter-clockwise from outside: positive signed volume
        # STL keeps no normals (consumers derive them from the winding); mirrored normals: tests/test_read_urdf.py
        assert packed.normals is None


def test_collada_and_obj_materials_are_kept_and_a_broken_texture_is_a_finding(imported) -> None:  # type: ignore[no-untyped-def]
    result, model = imported
    (missing,) = [f for f in result.findings if f.code == "texture-missing"]
    assert "missing_decal.png" in missing.message
    colours = np.asarray(model.mat_rgba[:, :3], float)
    for expected in ([0.8, 0.1, 0.1], [0.7, 0.55, 0.2]):  # COLLADA colours pass through trimesh's 8 bits
        assert np.abs(colours - expected).max(axis=1).min() <= 1 / 255
    painted = parse(result.mbins["meshes/painted.mbin"], "painted")
    assert len(painted.indices) == 24  # both boxes of the COLLADA file, the textured one included
    fin = next(
        g for g in range(model.ngeom) if model.geom_bodyid[g] == model.body("arm").id and model.geom_group[g] == 2
    )
    np.testing.assert_allclose(model.geom_rgba[fin], [0.1, 0.2, 0.9, 1.0], atol=1e-6)  # the URDF's named material


def test_mimic_is_a_joint_equality_and_forward_kinematics_match_yourdfpy(imported) -> None:  # type: ignore[no-untyped-def]
    _, model = imported
    assert model.neq == 1 and model.eq_type[0] == int(mujoco.mjtEq.mjEQ_JOINT)
    assert model.joint(int(model.eq_obj1id[0])).name == "right_slide"
    np.testing.assert_allclose(model.eq_data[0][:5], [0, 1, 0, 0, 0])
    robot = yourdfpy.URDF.load(str(URDF), load_meshes=False, build_scene_graph=True)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    for _ in range(10):
        cfg = {"turn": rng.uniform(-2, 2), "left_slide": rng.uniform(0, 0.02)}
        robot.update_cfg(cfg)
        data.qpos[:] = [cfg["turn"], cfg["left_slide"], cfg["left_slide"]]
        mujoco.mj_kinematics(model, data)
        for link in ["base", "arm", "sensor", "left", "right"]:
            expected = robot.get_transform(frame_to=link, frame_from="world")
            np.testing.assert_allclose(data.xpos[model.body(link).id], expected[:3, 3], atol=1e-9)
            np.testing.assert_allclose(data.xmat[model.body(link).id].reshape(3, 3), expected[:3, :3], atol=1e-9)


def test_mujoco_refusal_is_exit_1_naming_the_element(tmp_path: Path) -> None:
    robot = tmp_path / "r.urdf"
    robot.write_text(
        '<robot name="r"><link name="a"/><link name="b"/>\n'
        '<joint name="hinge" type="continuous"><parent link="a"/><child link="b"/></joint></robot>\n'
    )
    result = CliRunner().invoke(main, ["urdf", str(robot), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and not (tmp_path / "out").exists()
    assert result.output.count("\n") == 1 and "MuJoCo refuses the model" in result.output
    assert "'b'" in result.output and "r.urdf:1" in result.output
