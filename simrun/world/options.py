"""Which physics options a world runs with when its robots bring their own ``<option>`` (issue 37).

A world has one option set (MuJoCo has one per model). The rule:

1. What the scene's ``[world]`` table or Python's :class:`~simrun.world.world.WorldOptions` sets explicitly
   (``timestep``, ``integrator``; ``gravity`` always) governs.
2. Every other MuJoCo option (:data:`MODEL_OPTIONS`: timestep and integrator where not explicit, solver,
   iterations, tolerances, cone, impratio, fluid density and viscosity, wind, margins and overrides...) is the
   robot's own where its ``<option>`` differs from MuJoCo's default (a model that does not say takes MuJoCo's
   default, so only what a model sets counts), else simrun's (the world's defaults).
3. Two robots that set one option to different values: the first entity (scene order) wins. That conflict,
   and a robot's own value overridden by an explicit world option, are reported as a warning naming both
   values (:func:`choose`; ``simrun check`` prints them, :func:`simrun.world.checks.scene_warnings` returns
   them).

Gravity and the disable/enable flags are the world's; a model's ``gravity="0 0 0"`` or disabled gravity or
contacts are kept for its own bodies instead (``simrun.robots.mjcf_robot``: gravity compensation, no contact).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import mujoco
import numpy as np

#: The ``MjSpec.option`` fields a robot's own ``<option>`` may give the world.
MODEL_OPTIONS = (
    "timestep",
    "integrator",
    "solver",
    "iterations",
    "tolerance",
    "ls_iterations",
    "ls_tolerance",
    "noslip_iterations",
    "noslip_tolerance",
    "ccd_iterations",
    "ccd_tolerance",
    "sdf_iterations",
    "sdf_initpoints",
    "cone",
    "jacobian",
    "impratio",
    "density",
    "viscosity",
    "wind",
    "magnetic",
    "o_margin",
    "o_solref",
    "o_solimp",
    "o_friction",
)
#: Options the world's own settings (:class:`~simrun.world.world.WorldOptions`) may fix explicitly.
WORLD_OPTIONS = ("timestep", "integrator")


def _plain(value: Any) -> Any:
    """An option value as a comparable, JSON-ready Python value (arrays as tuples of floats)."""
    if isinstance(value, np.ndarray) or hasattr(value, "__len__"):
        return tuple(float(v) for v in value)
    if isinstance(value, float):
        return value
    return int(value)


_DEFAULTS = {name: _plain(getattr(mujoco.MjSpec().option, name)) for name in MODEL_OPTIONS}


def own_options(spec: mujoco.MjSpec) -> dict[str, Any]:
    """The options of a model's spec that differ from MuJoCo's defaults (what its ``<option>`` sets), by name."""
    found = {name: _plain(getattr(spec.option, name)) for name in MODEL_OPTIONS}
    return {name: value for name, value in found.items() if value != _DEFAULTS[name]}


def text(name: str, value: Any) -> str:
    """``name = value`` as a warning writes it (enums by MuJoCo's name: ``integrator = RK4``)."""
    enums = {"integrator": mujoco.mjtIntegrator, "solver": mujoco.mjtSolver, "cone": mujoco.mjtCone}
    if name in enums:
        value = enums[name](value).name.split("_", 1)[-1]
    elif isinstance(value, tuple):
        value = " ".join(f"{v:g}" for v in value)
    elif isinstance(value, float):
        value = f"{value:g}"
    return f"{name} = {value}"


def choose(
    world: dict[str, Any], explicit: Iterable[str], robots: Iterable[tuple[str, dict[str, Any]]]
) -> tuple[dict[str, Any], list[str]]:
    """The options the robots give the world, and the warnings of what was overridden.

    Args:
        world: The world's own values of :data:`WORLD_OPTIONS` (as ``MjSpec.option`` holds them).
        explicit: Which of them the scene or Python set explicitly.
        robots: (entity full name, :func:`own_options`) per robot, in entity order.

    Returns:
        Option name to value for the world's spec (only those a robot sets), and one warning line per
        override, in entity order then :data:`MODEL_OPTIONS` order.
    """
    fixed = set(explicit)
    chosen: dict[str, tuple[Any, str]] = {}
    notes: list[str] = []
    for entity, options in robots:
        for name in MODEL_OPTIONS:
            if name not in options:
                continue
            value = options[name]
            if name in fixed:
                if _plain(world[name]) != value:
                    notes.append(
                        f"option {name}: the world's {text(name, world[name])} (set by the scene) overrides "
                        f"{entity!r}'s own {text(name, value)}"
                    )
            elif name in chosen:
                first, owner = chosen[name]
                if first != value:
                    notes.append(
                        f"option {name}: {entity!r}'s own {text(name, value)} differs from {owner!r}'s "
                        f"{text(name, first)}, which the world uses"
                    )
            else:
                chosen[name] = (value, entity)
    return {name: value for name, (value, _) in chosen.items()}, notes


def apply(option: Any, values: dict[str, Any]) -> None:
    """Set the chosen values on an ``MjSpec.option``."""
    for name, value in values.items():
        setattr(option, name, list(value) if isinstance(value, tuple) else value)
