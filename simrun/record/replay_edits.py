"""Replay exports of a recording with edits (``simrun serve --edit``): the edited world, bodies for their lifetimes.

A recording whose world was edited holds an edit record (:class:`simrun.world.edit_apply.EditRecord`) at each
edit's simulated time, and the frames after it are states of the edited model. :func:`edited_tracks` replays it
kinematically: the recorded scene is compiled, each edit that changes the model (``insert``, ``load_entities``,
``change``, ``remove``, ``set_gravity``) is applied at its place in the file through
:func:`~simrun.world.edit_apply.apply_edit` (the library's one dispatcher), and each frame's state is set into
the model of its time and forwarded (``mj_setState``, ``mj_forward``). Edits that change only the state
(``teleport``, ``apply_force``) or services and sensors are not applied: the frames after them hold their
effect (a teleported body just follows its recorded poses).

The exported world is the *union*: the recorded scene with every insert, load and change applied and no
removal, so it has every body that existed at some frame, named as in the session. Its tracks hold each
body's world pose per frame by name (metres, ``xquat`` w x y z, Z up); a body that does not exist at a frame
(inserted later, removed earlier) is ``alive`` False there and keeps the pose of its nearest frame alive.
:func:`edited_gltf` is the animated glTF of :mod:`simrun.record.replay_glb` plus, for each body with a
lifetime, a ``scale`` channel with ``STEP`` interpolation: 0 outside its lifetime, 1 inside (its node's
static scale is 0 when it does not exist at the first frame); the HTML player embeds that glTF, the USD export
gives such a body ``visibility`` time samples (:func:`simrun.record.replay_usd.export_recording_usd`), and the
MCAP export replays through :func:`edited_states` with its channels following the world
(:meth:`simrun.record.foxglove_channels.FoxgloveChannels.refresh`).

Limits: a body's look is the union world's (the last change applied; a colour changed mid-session shows its
final colour throughout); a name removed and inserted again is one body (the later insert's table is not
applied to the union when the name is taken).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import SimrunError
from simrun.record.replay_glb import recording_gltf
from simrun.record.replay_tracks import I64, Tracks
from simrun.record.simlog import Simlog, check_model
from simrun.record.simlog_format import CHECKPOINT, COMMAND, FRAME, SimlogError
from simrun.record.simlog_read import set_frame
from simrun.scene.scene_file import load_scene
from simrun.world.world import World

#: Edits that change the model (applied in the replay); the others change only state, services or sensors.
MODEL_EDITS = ("insert", "load_entities", "change", "remove", "set_gravity")
#: Of those, the edits applied to the union world (every body that ever existed).
UNION_EDITS = ("insert", "load_entities", "change", "set_gravity")

B8 = npt.NDArray[np.bool_]


def _is_edit(record: Any) -> bool:
    from simrun.run.commands import Command

    return bool(record.kind == COMMAND and record.command is not None and not isinstance(record.command, Command))


def has_edits(log: Simlog) -> bool:
    """Whether the recording holds an edit record (counted when it was opened: :attr:`Simlog.edits`)."""
    return bool(getattr(log, "edits", 0))


@dataclass(frozen=True)
class EditedReplay:
    """The union world, its tracks, and which body exists at which frame.

    Attributes:
        world: The recorded scene with every insert, load and change applied (compiled).
        tracks: Every union body's pose per frame (bodies of the union model, by index).
        alive: (n frames, nbody) whether each body existed at each frame (the world body always).
    """

    world: World
    tracks: Tracks
    alive: B8


def _apply(world: World, edit: Any, log: Simlog) -> None:
    from simrun.world.edit_apply import apply_edit

    try:
        apply_edit(world, edit.kind, edit.args)
    except SimrunError as exc:
        raise SimlogError(
            f"{log.path}: the edit {edit.kind} at t = {edit.t:g} s does not apply to the recorded scene ({exc})"
        ) from None


def edited_tracks(scene: Path, log: Simlog) -> EditedReplay:
    """Replay ``log`` (recorded in ``scene``, with edits) kinematically; see the module.

    Raises:
        SimlogError: A malformed record, an edit that does not apply, or a frame beyond
            :data:`~simrun.record.simlog_read.MAX_REPLAY_COORDINATE_M`.
        SimrunError: The recording holds no frame.
    """
    union = load_scene(scene)
    union.compile()
    check_model(log, union)
    for record in log.events():
        if _is_edit(record) and record.command.kind in UNION_EDITS:
            try:
                _apply(union, record.command, log)
            except SimlogError:
                if record.command.kind not in ("insert", "load_entities"):  # a name taken again: one body
                    raise
    names = [union.model.body(b).name for b in range(union.model.nbody)]
    world = load_scene(scene)
    world.compile()
    times: list[float] = []
    positions: list[npt.NDArray[np.float64]] = []
    quats: list[npt.NDArray[np.float64]] = []
    alive: list[B8] = []
    model: Any = None
    index = np.zeros(0, dtype=np.int64)
    for t in edited_states(world, log):
        if world.model is not model:  # union body -> this model's body id (-1: not there)
            model = world.model
            index = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) if n else 0 for n in names])
        data = world.data
        here = index >= 0
        safe = np.where(here, index, 0)
        times.append(t)
        positions.append(np.where(here[:, None], data.xpos[safe], 0.0))
        quats.append(np.where(here[:, None], data.xquat[safe], np.array([1.0, 0.0, 0.0, 0.0])))
        alive.append(here)
    if not times:
        raise SimrunError(f"{log.path}: the recording holds no frame")
    p, q, a = np.array(positions), np.array(quats), np.array(alive)
    _fill(p, q, a)
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    flips = np.cumsum(np.sum(q[1:] * q[:-1], axis=2) < 0, axis=0) % 2  # as read_tracks: frames agree in sign
    q[1:] *= np.where(flips[..., None] == 1, -1.0, 1.0)
    return EditedReplay(union, Tracks(np.array(times), p, q, log.frame_period), a)


def edited_states(world: World, log: Simlog) -> Iterator[float]:
    """Set ``world`` (compiled from the recorded scene) to each recorded frame in turn, edits applied; yields times.

    As :func:`simrun.record.simlog_read.replay_states` (each frame and checkpoint state through ``mj_setState``
    and ``mj_forward``), with each model edit (:data:`MODEL_EDITS`) applied to ``world`` where the recording
    holds it, so ``world.model`` and ``world.data`` are those of the frame's time.

    Raises:
        SimlogError: A malformed record, an edit that does not apply, or a frame beyond
            :data:`~simrun.record.simlog_read.MAX_REPLAY_COORDINATE_M`.
    """
    check_model(log, world)
    for record in log.events():
        if _is_edit(record):
            if record.command.kind in MODEL_EDITS:
                _apply(world, record.command, log)
            continue
        if record.kind not in (FRAME, CHECKPOINT):
            continue
        set_frame(world, log, record)
        yield record.time


def _fill(positions: Any, quats: Any, alive: B8) -> None:
    """Give each body, at frames where it does not exist, the pose of its nearest earlier (else later) live frame."""
    n = len(alive)
    for b in np.flatnonzero(~alive.all(axis=0)):
        live = np.flatnonzero(alive[:, b])
        if not len(live):
            continue  # never there: hidden throughout, at the origin
        nearest = np.maximum.accumulate(np.where(alive[:, b], np.arange(n), -1))
        nearest = np.where(nearest < 0, live[0], nearest)
        positions[:, b] = positions[nearest, b]
        quats[:, b] = quats[nearest, b]


def edited_gltf(replay: EditedReplay, keys: dict[int, I64], name: str = "recording") -> Any:
    """The animated glTF (a :class:`meshtool.export.gltf_write.GltfBuilder`) of an edited recording.

    :func:`simrun.record.replay_glb.recording_gltf` of the union world, plus a ``STEP`` ``scale`` channel per
    body with a lifetime (0 outside it, 1 inside), keyed at the frames where it appears or goes.
    """
    gltf = recording_gltf(replay.world, replay.tracks, keys, name)
    model = replay.world.model
    nodes = {
        item.get("extras", {}).get("simrun_body"): k
        for k, item in enumerate(gltf.json["nodes"])
        if "simrun_body" in item.get("extras", {})
    }
    times = replay.tracks.times.astype(np.float32)
    channels: list[tuple[int, int, int]] = []
    for b in range(1, model.nbody):
        life = replay.alive[:, b]
        node = nodes.get(model.body(b).name or f"body{b}")
        if life.all() or node is None:
            continue
        item = gltf.json["nodes"][node]
        if not life[0]:
            item["scale"] = [0.0, 0.0, 0.0]
        changes = np.concatenate([[0], np.flatnonzero(life[1:] != life[:-1]) + 1])
        changes = changes[np.concatenate([[True], np.diff(times[changes]) > 0])]  # float32 keys strictly increasing
        scale = np.repeat(life[changes].astype(np.float32)[:, None], 3, axis=1)
        channels.append(
            (node, gltf.accessor(times[changes], bounds=True, target=None), gltf.accessor(scale, target=None))
        )
    if channels:
        animations = gltf.json.setdefault("animations", [])
        if not animations:
            animations.append({"name": name, "channels": [], "samplers": []})
        animation = animations[0]
        for node, key_times, values in channels:
            animation["samplers"].append({"input": key_times, "output": values, "interpolation": "STEP"})
            animation["channels"].append(
                {"sampler": len(animation["samplers"]) - 1, "target": {"node": node, "path": "scale"}}
            )
    return gltf


def edited_replay(scene: Path, log: Simlog) -> EditedReplay | None:
    """:func:`edited_tracks` of a recording with edits, or ``None`` for one without (the plain replay)."""
    if not has_edits(log):
        return None
    return edited_tracks(scene, log)
