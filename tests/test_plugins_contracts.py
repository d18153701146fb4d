"""How meshtool finds its plugins (``meshtool/plugins.py``), checked against the installed metadata and MuJoCo.

Ground truth: the entry points the installed distribution declares (``importlib.metadata``, read from
``pyproject.toml`` when it was installed), the functions they name, and MuJoCo compiling and loading what
the builder plugin returns. The "no plugin installed" paths are covered by ``tests/test_followups_check.py``.
"""

from __future__ import annotations

from importlib.metadata import distribution

import mujoco
import numpy as np
import pytest

import meshtool.plugins as plugins
import simrun.asset_check
import simrun.export.mjcf_builder
from meshtool.mjcf.model_desc import BodyDesc, GeomDesc, MeshDesc, ModelDesc, ModelError

DECLARED = {(p.group, p.name): p.value for p in distribution("meshtool-simrun").entry_points}


def test_installed_reads_the_declared_entry_points_without_loading_them() -> None:
    for group, name in (("meshtool.mjcf", "builder"), ("meshtool.mjcf", "check"), ("meshtool.validate", "physics")):
        point = plugins.installed(group, name)
        assert point is not None and (point.group, point.name, point.value) == (group, name, DECLARED[group, name])
    assert plugins.installed("meshtool.mjcf", "nothing") is None
    assert plugins.installed("no.such.group", "builder") is None
    assert plugins.MJCF_GROUP == "meshtool.mjcf"


def test_load_plugin_gives_what_the_entry_point_names() -> None:
    assert plugins.load_plugin("meshtool.mjcf", "builder") is simrun.export.mjcf_builder.build_files
    assert plugins.load_plugin("meshtool.mjcf", "check") is simrun.export.mjcf_builder.check_model
    assert plugins.load_plugin("meshtool.validate", "physics") is simrun.asset_check.check_pack
    assert plugins.load_plugin("meshtool.validate", "nothing") is None
    assert plugins.mjcf_builder() is simrun.export.mjcf_builder.build_files
    assert plugins.mjcf_checker() is simrun.export.mjcf_builder.check_model


def _box_model(half: float) -> ModelDesc:
    box = GeomDesc(role="collision", type="box", size=(half, half, half))
    return ModelDesc(name="crate", bodies=[BodyDesc(name="crate", pos=(0.0, 0.0, 1.0), free=True, geoms=[box])])


def test_check_model_compiles_with_the_plugin_and_raises_what_mujoco_refuses() -> None:
    assert plugins.check_model(_box_model(0.1)) is True
    flat = MeshDesc(name="flat", vertices=np.eye(3), faces=np.array([[0, 1, 2]]))
    refused = ModelDesc(
        name="flat", meshes=[flat], bodies=[BodyDesc(name="b", geoms=[GeomDesc("visual", "mesh", mesh="flat")])]
    )
    with pytest.raises(ModelError, match="at least 4 vertices"):
        plugins.check_model(refused)


def test_mjcf_files_are_a_folder_mujoco_loads() -> None:
    files = plugins.mjcf_files(_box_model(0.25))
    assert "crate.xml" in files
    model = mujoco.MjModel.from_xml_string(files["crate.xml"].decode("utf-8"), dict(files))
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "crate")
    assert body > 0 and model.body_pos[body].tolist() == [0.0, 0.0, 1.0]
    np.testing.assert_allclose(model.geom_size[model.body_geomadr[body]], [0.25, 0.25, 0.25])
