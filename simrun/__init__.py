# ruff: noqa: E402  (MUJOCO_GL must be decided before the imports below import mujoco)
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

from simrun.headless import import_mujoco as _import_mujoco

_import_mujoco()  # headless OpenGL by default: MUJOCO_GL is decided before anything imports mujoco

from simrun.entity import Entity, Material
from simrun.environment import Camera, Ground, HeightField, Light, Sky
from simrun.errors import CompileError, EntityError, SceneError, SimrunError
from simrun.mesh_entity import MeshEntity
from simrun.pose import Pose
from simrun.scene import load_scene, save_scene, scene_text
from simrun.shapes import Box, Capsule, Cylinder, Sphere
from simrun.urdf_robot import UrdfRobot
from simrun.world import World, WorldOptions

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
