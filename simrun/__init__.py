# ruff: noqa: E402  (the MUJOCO_GL hook is armed before the imports below)
"""simrun: MuJoCo worlds of named entities built on ``mujoco.MjSpec``, with meshtool's ``.mbin`` assets.

Build a world in code::

    from simrun import World, Ground, Sky, Light, Box, Sphere, Pose

    world = World()
    world.insert(Sky(name="sky"))
    world.insert(Ground(name="ground"))
    world.insert(Light(name="sun", pose=Pose((0, 0, 3))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=100.0, pose=Pose((0, 0, 0.1)), free=True))
    world.step(500)

or load one from a TOML scene file with :func:`load_scene`.
"""

__version__ = "0.1.0"

from simrun.run.headless import arm as _arm_gl_choice

# Headless OpenGL by default: MUJOCO_GL is decided the moment anything first imports mujoco (a
# sys.meta_path hook, simrun/run/headless.py), so ``import simrun`` and ``simrun --help`` never load MuJoCo.
_arm_gl_choice()

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from simrun.entities.environment import Camera, Ground, HeightField, Light, Sky
    from simrun.entities.mesh_entity import MeshEntity
    from simrun.entities.shapes import Box, Capsule, Cylinder, Sphere
    from simrun.errors import CompileError, EntityError, SceneError, SimrunError
    from simrun.robots.urdf_robot import UrdfRobot
    from simrun.scene.scene_file import load_scene, save_scene, scene_text
    from simrun.world.entity import Entity, Material
    from simrun.world.pose import Pose
    from simrun.world.world import World, WorldOptions

#: Public name -> the module that defines it, imported on first use (PEP 562): a tool that needs one part
#: of simrun (meshtool's MuJoCo load check imports ``simrun.export.mjcf_builder``) does not import all of it.
_LAZY = {
    "Entity": "simrun.world.entity",
    "Material": "simrun.world.entity",
    "Camera": "simrun.entities.environment",
    "Ground": "simrun.entities.environment",
    "HeightField": "simrun.entities.environment",
    "Light": "simrun.entities.environment",
    "Sky": "simrun.entities.environment",
    "CompileError": "simrun.errors",
    "EntityError": "simrun.errors",
    "SceneError": "simrun.errors",
    "SimrunError": "simrun.errors",
    "MeshEntity": "simrun.entities.mesh_entity",
    "Pose": "simrun.world.pose",
    "load_scene": "simrun.scene.scene_file",
    "save_scene": "simrun.scene.scene_file",
    "scene_text": "simrun.scene.scene_file",
    "Box": "simrun.entities.shapes",
    "Capsule": "simrun.entities.shapes",
    "Cylinder": "simrun.entities.shapes",
    "Sphere": "simrun.entities.shapes",
    "UrdfRobot": "simrun.robots.urdf_robot",
    "World": "simrun.world.world",
    "WorldOptions": "simrun.world.world",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'simrun' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "Box",
    "Camera",
    "Capsule",
    "CompileError",
    "Cylinder",
    "Entity",
    "EntityError",
    "Ground",
    "HeightField",
    "Light",
    "Material",
    "MeshEntity",
    "Pose",
    "SceneError",
    "SimrunError",
    "Sky",
    "Sphere",
    "UrdfRobot",
    "World",
    "WorldOptions",
    "__version__",
    "load_scene",
    "save_scene",
    "scene_text",
]
