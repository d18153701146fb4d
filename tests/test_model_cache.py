"""Compiled-model cache (simrun/world/model_cache.py): a hit is the same model as compiling, any change is a miss."""

from __future__ import annotations

import contextlib
import os
import shutil
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import xxhash

from meshtool.files import cachefile
from meshtool.packfile import load
from simrun import Box, HeightField, MeshEntity, Pose, World
from simrun.errors import SimrunError
from simrun.world.model_cache import KIND as MODEL_KIND
from simrun.world.model_cache import RACY_NS, ModelCache, model_bytes

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


def _state(world: World) -> bytes:
    """Every number of MuJoCo's full physics state (time, qpos, qvel, act, warm start...)."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(world.model, spec))
    mujoco.mj_getState(world.model, world.data, state, spec)
    return state.tobytes()


def _falling(folder: Path, cache: ModelCache | None) -> World:
    """Textured meshes falling onto a box: contacts, free joints, a texture, two mesh files."""
    world = World(base_dir=folder)
    world.model_cache = cache
    world.insert(Box(name="floor", dimensions=(2.0, 2.0, 0.1), pose=Pose((0.0, 0.0, -0.05))))
    for k in range(3):
        world.insert(MeshEntity(name=f"m{k}", asset=f"a{k}.mbin", free=True, pose=Pose((0.1 * k, 0.0, 0.3 + 0.2 * k))))
    return world


def test_a_cached_world_behaves_identically(folder: Path, tmp_path: Path) -> None:
    """Cold, first load (a miss that stores) and second load (a hit): the same MJB bytes, the same files read,
    the same warnings, and the same simulation bit for bit at every one of 300 steps."""
    cache = ModelCache(tmp_path / "cache")
    worlds = [_falling(folder, None), _falling(folder, cache), _falling(folder, cache)]
    assert [model_bytes(w.model) for w in worlds[1:]] == [model_bytes(worlds[0].model)] * 2
    assert (cache.hits, cache.misses) == (1, 1)
    assert (
        worlds[2].files_read() == worlds[0].files_read() == sorted((folder / f"a{k}.mbin").resolve() for k in range(3))
    )
    assert worlds[2].scene_warnings() == worlds[0].scene_warnings()
    for _ in range(300):
        states = {_state(w) for w in worlds}
        assert len(states) == 1
        for w in worlds:
            w.step(1)
    assert worlds[0].data.ncon > 0  # the meshes landed: contacts were part of what was compared
    assert {tuple(w.warnings().items()) for w in worlds} == {tuple(worlds[0].warnings().items())}


def test_a_hit_writes_nothing(folder: Path, tmp_path: Path) -> None:
    cache = ModelCache(tmp_path / "cache")
    _falling(folder, cache).compile()
    (entry,) = cache.folder.iterdir()
    before = entry.stat(), entry.read_bytes()
    os.utime(entry, ns=(1, 1))  # a rewrite would set the times anew
    _falling(folder, cache).compile()
    assert cache.hits == 1 and list(cache.folder.iterdir()) == [entry]
    assert entry.stat().st_mtime_ns == 1 and entry.read_bytes() == before[1]


@pytest.mark.parametrize("hash_inputs", [False, True])
def test_other_bytes_behind_the_same_size_and_time_are_a_miss(hash_inputs: bool, folder: Path, tmp_path: Path) -> None:
    """A file rewritten with other bytes of the same size and given back its old times (as `cp -p` or `touch -r`
    would): its status-change time moved, so it is hashed again and the world recompiles with the new mesh."""
    cache = ModelCache(tmp_path / "cache", hash_inputs=hash_inputs)
    target = folder / "a1.mbin"
    time.sleep(RACY_NS / 1e9 + 0.1)  # files older than the racy window: their fingerprints are trusted
    _falling(folder, cache).compile()
    _falling(folder, cache).compile()
    assert (cache.hits, cache.misses) == (1, 1)
    shutil.copy(GOLDEN / "features-1.1.mbin", folder / "other.mbin")
    stamp = os.stat(target)
    other = (folder / "other.mbin").read_bytes()
    data = other[: stamp.st_size] if len(other) >= stamp.st_size else other + bytes(stamp.st_size - len(other))
    target.write_bytes(data)  # another mesh cut or padded to the old size
    os.utime(target, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))
    assert os.stat(target).st_size == stamp.st_size and os.stat(target).st_mtime_ns == stamp.st_mtime_ns
    with contextlib.suppress(SimrunError):  # the other bytes may not even load: what matters is they are read
        _falling(folder, cache).compile()
    assert (cache.hits, cache.misses) == (1, 2) and cache.problems == []


def test_an_entry_whose_model_mujoco_refuses_is_a_miss(
    folder: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """A well-formed entry (digests right) whose MJB MuJoCo refuses: a miss with one problem, nothing printed."""
    truth = model_bytes(_falling(folder, None).model)
    cache = ModelCache(tmp_path / "cache")
    _falling(folder, cache).compile()
    (entry,) = cache.folder.iterdir()
    key = entry.stem
    payload = bytearray(entry.read_bytes()[cachefile.HEADER_BYTES :])
    mjb = len(payload) - len(truth)
    payload[mjb + 4 : mjb + 64] = b"\xff" * 60  # the MJB's ID stays, its sizes become nonsense
    payload[:16] = xxhash.xxh3_128_digest(bytes(payload[16:]))
    cachefile.write_entry(entry, MODEL_KIND, key, bytes(payload))
    capfd.readouterr()
    world = _falling(folder, cache)
    assert model_bytes(world.model) == truth and cache.hits == 0
    assert len(cache.problems) == 1 and "not a compiled model" in cache.problems[0]
    printed = capfd.readouterr()
    assert printed.out == printed.err == ""
