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
