"""Compiled-model cache (simrun/world/model_cache.py): a hit is the same model as compiling, any change is a miss."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import pytest

from meshtool.packfile import load
from simrun import Box, HeightField, MeshEntity, Pose, World
from simrun.world.model_cache import ModelCache, model_bytes

GOLDEN = Path(__file__).resolve().parent.parent / "fixtures" / "golden"


def _world(folder: Path, cache: ModelCache | None, count: int = 3, x: float = 0.0) -> World:
    world = World(base_dir=folder)
    world.model_cache = cache
    for k in range(count):
        world.insert(MeshEntity(name=f"m{k}", asset=f"a{k}.mbin", pose=Pose((x + 0.3 * k, 0.0, 0.2))))
    world.insert(Box(name="box", dimensions=(0.1, 0.1, 0.1), pose=Pose((0.0, 1.0, 0.1))))
    return world


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    for k in range(3):
        shutil.copy(GOLDEN / "head-1.1.mbin", tmp_path / f"a{k}.mbin")
    return tmp_path


def test_a_hit_is_the_compiled_model_byte_for_byte(folder: Path, tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    fresh = model_bytes(_world(folder, None).model)
    first = _world(folder, cache)
    assert model_bytes(first.model) == fresh and (cache.hits, cache.misses) == (0, 1)
    second = _world(folder, cache)
    assert model_bytes(second.model) == fresh and cache.hits == 1
    # the simulation from the cached model is the simulation from the compiled one
    for world in (first, second):
        world.step(50)
    assert first.data.qpos.tolist() == second.data.qpos.tolist()
    assert second.spec.compile() is not None  # the spec is still there when asked for


def test_changed_file_entity_or_option_is_a_miss(folder: Path, tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    _world(folder, cache).compile()
    moved = _world(folder, cache, x=0.5)
    moved.compile()
    assert cache.hits == 0 and moved.model.body("m0").pos[0] == pytest.approx(0.5)
    # same bytes written again (new mtime): still a hit, the key is the content
    shutil.copy(GOLDEN / "head-1.1.mbin", folder / "a1.mbin")
    _world(folder, cache).compile()
    assert cache.hits == 1
    # another mesh in the same file name: a miss, and the new geometry is what compiles
    shutil.copy(GOLDEN / "features-1.1.mbin", folder / "a1.mbin")
    changed = _world(folder, cache)
    assert model_bytes(changed.model) == model_bytes(_world(folder, None).model)
    assert cache.hits == 1
    with load(folder / "a1.mbin") as packed:  # the features mesh: one visual mesh per submesh
        names = [changed.model.mesh(k).name for k in range(changed.model.nmesh)]
        assert sum(n.startswith("a1/visual") for n in names) == len(packed.submeshes) == 2
        assert sum(n.startswith("a0/visual") for n in names) == 1


def test_damaged_entry_is_a_miss(folder: Path, tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    expected = model_bytes(_world(folder, cache).model)
    for mjb in (tmp_path / "cache").glob("*.mjb"):
        mjb.write_bytes(mjb.read_bytes()[:100])
    world = _world(folder, cache)
    assert model_bytes(world.model) == expected and cache.hits == 0


def test_worlds_with_other_entities_are_not_cached(tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    world = World(base_dir=tmp_path)
    world.model_cache = cache
    world.insert(HeightField(name="hf", heights=[[0.0, 0.1], [0.2, 0.3]], size=(1.0, 1.0, 0.5, 0.1)))
    assert cache.key(world) is None
    world.compile()
    assert not (tmp_path / "cache").exists()


def test_identical_textures_are_decoded_once(folder: Path) -> None:
    """Three copies of one textured asset give one texture; MuJoCo decodes each distinct image once."""
    world = _world(folder, None)
    assert world.model.ntex == 1
    assert {world.model.mat_texid[k][mujoco.mjtTextureRole.mjTEXROLE_RGB] for k in range(world.model.nmat)} == {0}
