"""The normaliser's output is what MuJoCo needs: it compiles, with its PNG texture, at the right size."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from meshtool import NormaliseOptions, normalise_to


def model_xml(folder: Path, obj: str, texture: str) -> str:
    return f"""<mujoco><compiler meshdir="{folder}" texturedir="{folder}"/>
<asset><mesh name="m" file="{obj}"/><texture name="t" type="2d" file="{texture}"/>
<material name="mat" texture="t"/></asset>
<worldbody><geom type="mesh" mesh="m" material="mat" contype="0" conaffinity="0" group="2"/></worldbody>
</mujoco>"""


def test_normalised_head_compiles_in_mujoco(fixtures, tmp_path):
    folder, asset = normalise_to(fixtures / "head" / "Head 1.obj", tmp_path, NormaliseOptions(units="cm"))
    model = mujoco.MjModel.from_xml_string(model_xml(folder, "head_1.obj", "head_1.png"))
    assert (model.nmesh, model.ntex, model.nmat) == (1, 1, 1)
    assert model.mesh_vertnum[0] == asset.stats["vertices"] == 61
    assert model.mesh_facenum[0] == asset.stats["triangles"] == 80
    assert model.mesh_texcoordnum[0] == 61
    assert (model.tex_width[0], model.tex_height[0]) == (16, 16)
    extent = model.mesh_vert.max(axis=0) - model.mesh_vert.min(axis=0)
    np.testing.assert_allclose(extent, [0.16, 0.2, 0.24], rtol=1e-6)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 10)
    assert data.time > 0


def test_the_raw_export_does_not(fixtures):
    """The reason the normaliser exists: MuJoCo refuses the source's BMP texture."""
    with pytest.raises(ValueError, match="unsupported content type"):
        mujoco.MjModel.from_xml_string(model_xml(fixtures / "head", "Head 1.obj", "Head 1.bmp"))


SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


@pytest.mark.parametrize(
    "scene", sorted(p for p in SCENES.glob("*.toml") if not p.name.endswith(".commands.toml")), ids=lambda p: p.stem
)
def test_exported_scene_folder_loads_alone_after_being_moved(scene, tmp_path):
    from click.testing import CliRunner

    from simrun.cli.main import main as simrun_main
    from simrun.scene.scene_file import load_scene

    result = CliRunner().invoke(simrun_main, ["export", str(scene), "--mjcf", str(tmp_path / "out" / "scene.xml")])
    assert result.exit_code == 0, result.output
    moved = tmp_path / "elsewhere" / "copy"
    (tmp_path / "out").rename(moved.parent.mkdir(parents=True) or moved)
    model = mujoco.MjModel.from_xml_path(str(moved / "scene.xml"))
    reference, _ = load_scene(scene).compile()
    for count in ("nbody", "njnt", "ngeom", "nmesh", "ntex", "nmat", "nu", "nmeshvert"):
        assert getattr(model, count) == getattr(reference, count), count
    np.testing.assert_array_equal(model.body_mass, reference.body_mass)
    np.testing.assert_array_equal(model.body_pos, reference.body_pos)
    assert all(p.suffix in (".xml", ".obj", ".png") for p in moved.iterdir())


def test_meshtool_mjcf_without_a_builder_is_one_error_line(fixtures, tmp_path, monkeypatch):
    from click.testing import CliRunner

    import meshtool.plugins
    from meshtool.cli.main import main as meshtool_main

    monkeypatch.setattr(meshtool.plugins, "mjcf_builder", lambda: None)
    result = CliRunner().invoke(meshtool_main, ["mjcf", str(SCENES / "head.mbin"), "-o", str(tmp_path / "m")])
    assert result.exit_code == 1 and result.output.count("\n") == 1
    assert "pip install meshtool-simrun" in result.output and not (tmp_path / "m").exists()


def test_meshtool_mjcf_folder_loads_alone_with_its_texture_upright(tmp_path):
    from click.testing import CliRunner

    from meshtool.cli.main import main as meshtool_main

    result = CliRunner().invoke(meshtool_main, ["mjcf", str(SCENES / "head.mbin"), "-o", str(tmp_path / "m")])
    assert result.exit_code == 0, result.output
    moved = tmp_path / "moved"
    (tmp_path / "m" / "head").rename(moved)
    model = mujoco.MjModel.from_xml_path(str(moved / "head.xml"))
    assert (model.nmesh, model.ntex) == (2, 1) and model.body_mass[1] > 0
    from meshtool.packfile import load

    with load(SCENES / "head.mbin") as packed:
        uvs = np.asarray(packed.uvs, dtype=float)
    texcoords = model.mesh_texcoord[model.mesh_texcoordadr[0] : model.mesh_texcoordadr[0] + model.mesh_texcoordnum[0]]
    np.testing.assert_allclose(np.sort(texcoords[:, 1]), np.sort(1.0 - uvs[: len(texcoords), 1]), atol=1e-6)
