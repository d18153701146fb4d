"""The one registry of scene types: every entity, service and sensor a scene file may name.

:class:`~simrun.world.world.World` (``service``, ``add_sensor``), :mod:`simrun.scene.scene_file` (``[[entities]]``,
``[[services]]``, ``[[sensors]]``), :mod:`simrun.run.commands` and ``docs/scene-format.md``
(tests/test_simrun_registry.py keeps the document in step) read this registry and nothing else; whether an entity
is a robot is the robot contract's answer (:func:`simrun.robots.contract.is_robot`), not a registry flag.
Classes are named by ``module:Class`` and imported on first use, so the registry imports no other simrun module
and the modules it names may import :mod:`simrun.world.world` freely: there is no cycle.

Its three parts:

- :mod:`simrun.world.registry.tables`: the types (:class:`~simrun.world.registry.tables.SceneType`,
  :data:`~simrun.world.registry.tables.REGISTRY`, ``names``, ``scene_type``, ``load``) and :class:`Controller`,
  the protocol of services and sensors (the world's stepping loop, checkpoints and
  ``save_scene(state="current")`` rely on it);
- :mod:`simrun.world.registry.key_schema`: every key of every type, with its type, unit, default and one-line
  description, read from the class (``schema``), never kept by hand; ``keys_markdown`` writes
  docs/scene-format.md's key tables (tests/test_registry_schema.py checks them against the schema);
- :mod:`simrun.world.registry.conversion`: ``arguments``, the one route from a table to the constructor's
  arguments, for entities, services and sensors alike, whether the table comes from a scene file (errors at its
  file and line) or from Python (``World.add_sensor``, a service binding): unknown keys are named with the known
  ones and the closest, values are checked against their key's type.

The names below stay importable from here for the modules that import them from ``simrun.world.registry``
(``simrun/world/world.py``, ``simrun/serve/catalogue.py``); new code imports from the part that holds the name.
"""

from __future__ import annotations

from simrun.world.registry.conversion import arguments, python_fail, service_arguments
from simrun.world.registry.tables import REGISTRY, Controller, names, scene_type

__all__ = ["REGISTRY", "Controller", "arguments", "names", "python_fail", "scene_type", "service_arguments"]
