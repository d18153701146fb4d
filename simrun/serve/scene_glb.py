"""The served world's scene as binary glTF (``GET /api/scene.glb``), built outside the simulation thread.

The simulation thread takes only :func:`pose_copy` (the compiled model and two array copies); :func:`glb_of`
builds the glTF from it in any thread, reading only the model's fixed arrays. The app keeps one build per
compiled model (:attr:`simrun.serve.loop.SimLoop.model`, a new object after an edit rebuilds the world).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import mujoco
import numpy as np

from simrun.record.replay_glb import recording_gltf
from simrun.record.replay_tracks import Tracks
from simrun.world.world import World


def world_glb(world: World) -> bytes:
    """The world's visual geoms as binary glTF at the current poses (Y-up root, one node per body)."""
    return glb_of(*pose_copy(world))


def pose_copy(world: World) -> tuple[mujoco.MjModel, np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """The compiled model and copies of every body's ``xpos`` (nbody, 3) m and ``xquat`` (nbody, 4), world frame.

    Cheap (two array copies): the simulation thread takes it; :func:`glb_of` builds from it in another thread.
    """
    data = world.data
    return world.model, np.array(data.xpos, dtype=np.float64), np.array(data.xquat, dtype=np.float64)


@dataclass(frozen=True)
class _Compiled:
    """What :func:`simrun.record.replay_glb.recording_gltf` reads of a world: its compiled model only."""

    model: mujoco.MjModel


def glb_of(model: mujoco.MjModel, xpos: np.ndarray[Any, Any], xquat: np.ndarray[Any, Any]) -> bytes:
    """Binary glTF of ``model``'s visual geoms with the bodies at ``xpos``/``xquat`` (from :func:`pose_copy`).

    Reads only the model's fixed arrays (geometry, meshes, materials), never an ``MjData``, so it may run in
    any thread while the world steps.
    """
    tracks = Tracks(np.array([0.0]), xpos[None], xquat[None], 0.02)
    return recording_gltf(cast(World, _Compiled(model)), tracks, {}, "live").glb()
