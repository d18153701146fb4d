"""Worlds of many entities built in batches (simrun/world/batch.py): the same model and spec as one by one."""

from __future__ import annotations

import shutil
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np
import pytest

from simrun import MeshEntity, Pose, World
from simrun.entities.environment import Camera, Ground, Light, Sky
from simrun.entities.shapes import Box, Capsule, Cylinder, Sphere
from simrun.scene.scene_file import load_scene
from simrun.world import batch
from simrun.world.entity import BuildContext, Material

SCENES = Path(__file__).parent.parent / "fixtures" / "scenes"


def model_bytes(spec: mujoco.MjSpec) -> bytes:
    model = spec.compile()
    buffer = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def assert_same_build(world: World) -> None:
    """The batched and the one-by-one builds compile to the same MJB bytes and write the same XML."""
    direct, batched = world.build_spec(batched=False), world.build_spec(batched=True)
    assert model_bytes(batched) == model_bytes(direct)
    assert batched.to_xml() == direct.to_xml()


def crowd(tmp_path: Path) -> World:
    """Over three batches of shapes and meshes: children, free and kinematic bodies, negative zeros,
    textures and materials, with unbatched entities (ground, sky, lights, cameras) between them."""
    shutil.copy(SCENES / "head.mbin", tmp_path / "head.mbin")
    shutil.copy(SCENES / "globe.png", tmp_path / "globe.png")
    world = World(base_dir=tmp_path)
    world.insert(Ground(name="floor"))
    world.insert(Sky(name="sky"))
    shapes = (Box, Sphere, Capsule, Cylinder)
    for k in range(3 * batch.BATCH + 17):
        pose = Pose((0.25 * (k % 20), 0.25 * (k // 20), (-0.0, 0.0, 0.5)[k % 3]), (1.0, 0.0, (0.0, -0.0)[k % 2], 0.0))
        if k % 7 == 0:
            world.insert(MeshEntity(name=f"m{k}", asset="head.mbin", pose=pose, free=k % 2 == 0, mass=0.5))
        elif k % 11 == 0:
            world.insert(Box(name=f"t{k}", pose=pose, texture="globe.png", material=Material(restitution=0.3)))
        elif k % 13 == 0:
            world.insert(Sphere(name=f"k{k}", pose=pose, kinematic=True))
        else:
            world.insert(shapes[k % 4](name=f"s{k}", pose=pose, free=k % 5 == 0))
        if k % 9 == 0:  # a child, batched with its parent or not
            world.insert(Box(name="c", parent=world.full_name(list(world)[-1][1]), pose=Pose((0.0, 0.1, 0.0))))
        if k % 97 == 0:
            world.insert(Light(name=f"l{k}", pose=Pose((0.0, 0.0, 3.0))))
        if k % 101 == 0:
            world.insert(Camera(name=f"cam{k}", pose=Pose((1.0, 0.0, 1.0))))
    return world


def test_a_batched_build_is_the_one_by_one_build(tmp_path):
    world = crowd(tmp_path)
    assert len(world) > batch.BATCH
    assert_same_build(world)


def test_a_large_world_is_batched_without_warnings_or_log_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo's default warning handler writes MUJOCO_LOG.TXT here
    world = crowd(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        spec = world.build_spec()
        model, _ = world.compile()
        assert model_bytes(spec) == model_bytes(world.build_spec(batched=False))
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert model.nbody == len(spec.bodies)


def test_shapes_alone_are_counted_without_the_spec_list(tmp_path):
    world = World()
    for k in range(batch.BATCH + 3):
        world.insert(Box(name=f"b{k}", pose=Pose((0.2 * k, 0.0, 0.1))))
        world.insert(Sphere(name="s", parent=f"b{k}"))
    spec = world.build_spec()
    assert world.compile()[0].nbody == len(spec.bodies) == 2 * (batch.BATCH + 3) + 1


FIXTURE_SCENES = sorted(p.name for p in SCENES.glob("*.toml") if not p.name.endswith(".commands.toml"))


@pytest.mark.parametrize("scene", FIXTURE_SCENES)
def test_every_fixture_scene_builds_the_same_batched(scene):
    assert_same_build(load_scene(SCENES / scene))


@dataclass(kw_only=True)
class _Marked(Box):
    """A Box whose build adds a site to the world body as well (not batchable)."""

    TYPE: ClassVar[str] = "Marked"

    def build(self, body: Any, ctx: BuildContext) -> None:
        super().build(body, ctx)
        ctx.spec.worldbody.add_site(name=ctx.name("mark"))


def test_only_entities_whose_build_says_so_are_batched(tmp_path):
    assert batch.batchable(Box) and batch.batchable(MeshEntity) and batch.batchable(Cylinder)
    assert not batch.batchable(_Marked) and not batch.batchable(Sky) and not batch.batchable(Ground)
    world = World()
    for k in range(batch.BATCH + 5):
        cls = _Marked if k % 50 == 0 else Box
        world.insert(cls(name=f"b{k}", pose=Pose((0.2 * k, 0.0, 0.1))))
    assert_same_build(world)


def test_children_inserted_long_after_their_parents(tmp_path):
    world = World()
    for k in range(3 * batch.BATCH):
        world.insert(Box(name=f"b{k}", pose=Pose((0.2 * k, 0.0, 0.1)), free=k % 2 == 1))
    for k in range(0, 3 * batch.BATCH, 37):  # parents in sealed child specs, merged or attached
        world.insert(Sphere(name="late", parent=f"b{k}", pose=Pose((0.0, 0.0, 0.2))))
        world.insert(Camera(name="eye", parent=f"b{k}"))
    world.insert(Box(name="last"))
    assert_same_build(world)
