"""The current state of a world as a scene's ``[state]`` table (``save_scene(..., state="current")``).

The table holds every component of MuJoCo's integration state by name (``time``, ``qpos``, ``qvel``,
``act``, ``warmstart``, ``ctrl``, ``mocap_pos``...; empty ones left out) and, as one JSON string, the
snapshots of the world's controllers (services by ``service:TYPE:ENTITY``, sensors by ``sensor:NAME``), so
a reloaded world continues the motion bit for bit: the same integration state restored with
``mj_setState`` and the same controller state, exactly as ``simrun resim`` restores a checkpoint.
"""

from __future__ import annotations

import json
import math
from typing import Any

import mujoco
import numpy as np

from meshtool.files.nesting import bounded
from simrun.errors import EntityError
from simrun.world.world import World

#: The integration state's components in MuJoCo's order, by their name in a ``[state]`` table.
COMPONENTS: tuple[tuple[str, int], ...] = tuple(
    (name.lower(), int(getattr(mujoco.mjtState, f"mjSTATE_{name}")))
    for name in (
        "TIME",
        "QPOS",
        "QVEL",
        "ACT",
        "HISTORY",
        "WARMSTART",
        "CTRL",
        "QFRC_APPLIED",
        "XFRC_APPLIED",
        "EQ_ACTIVE",
        "MOCAP_POS",
        "MOCAP_QUAT",
        "USERDATA",
        "PLUGIN",
        "PLASTIC",
    )
    if hasattr(mujoco.mjtState, f"mjSTATE_{name}")
    and int(getattr(mujoco.mjtState, f"mjSTATE_{name}")) & int(mujoco.mjtState.mjSTATE_INTEGRATION)
)
KEYS = (*(name for name, _ in COMPONENTS), "controllers")


def state_table(world: World) -> dict[str, Any]:
    """The world's current state as a ``[state]`` table (lists of floats, a JSON string of snapshots)."""
    model, data = world.model, world.data
    table: dict[str, Any] = {}
    for name, bit in COMPONENTS:
        size = mujoco.mj_stateSize(model, bit)
        if size == 0:
            continue
        values = np.empty(size)
        mujoco.mj_getState(model, data, values, bit)
        table[name] = float(values[0]) if name == "time" else [float(v) for v in values]
    snapshots = {key: controller.snapshot() for key, controller in controller_keys(world).items()}
    if snapshots:
        table["controllers"] = json.dumps(snapshots, sort_keys=True)
    return table


def controller_keys(world: World) -> dict[str, Any]:
    """The world's services (``service:TYPE:ENTITY``) and named sensors (``sensor:NAME``) by key."""
    keys: dict[str, Any] = {}
    for (kind, entity), service in world._bound.items():
        keys[f"service:{kind}:{entity}"] = service
    for name, sensor in world.sensors.items():
        keys[f"sensor:{name}"] = sensor
    return keys


def apply_state(world: World, table: dict[str, Any], fail: Any) -> None:
    """Set a freshly loaded world to a ``[state]`` table: binds its services, restores every controller.

    Args:
        world: The loaded world (compiled here).
        table: The ``[state]`` table.
        fail: ``fail(message, key)`` makes the error to raise for a bad key.
    """
    model, data = world.model, world.data
    for key in table:
        if key not in KEYS:
            raise fail(f"unknown key (known: {', '.join(KEYS)})", key)
    for name, bit in COMPONENTS:
        size = mujoco.mj_stateSize(model, bit)
        value = table.get(name, [] if name != "time" else 0.0)
        values = [value] if name == "time" else value
        if not isinstance(values, list) or len(values) != size:
            got = len(values) if isinstance(values, list) else type(value).__name__
            raise fail(f"expected {size} number(s) for this scene's model, got {got}", name)
        for v in values:
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise fail(f"expected finite numbers, got {v!r}", name)
        if size:
            mujoco.mj_setState(model, data, np.asarray(values, dtype=np.float64), bit)
    mujoco.mj_forward(model, data)
    for binding in world.services:
        world.service(binding["type"], binding["entity"])
    raw = table.get("controllers", "{}")
    try:
        snapshots = bounded(lambda: json.loads(raw, parse_constant=_no_nan)) if isinstance(raw, str) else None
    except ValueError as exc:  # NestingError included
        raise fail(f"not a JSON object of controller snapshots ({exc})", "controllers") from None
    if not isinstance(snapshots, dict):
        raise fail("expected a JSON object of controller snapshots (a string)", "controllers")
    controllers = controller_keys(world)
    if set(snapshots) != set(controllers):
        raise fail(
            f"holds {sorted(snapshots)}, the scene's services and sensors are {sorted(controllers)}", "controllers"
        )
    for key, snapshot in snapshots.items():
        try:
            controllers[key].restore(snapshot)
        except (EntityError, KeyError, TypeError, ValueError, IndexError) as exc:
            raise fail(f"{key}: snapshot does not fit ({type(exc).__name__}: {exc})", "controllers") from None
    world.reschedule()


def _no_nan(name: str) -> float:
    if name == "NaN":
        raise ValueError("NaN in a snapshot")
    return float(name.replace("Infinity", "inf"))
