"""The physics plugin of ``meshtool validate`` (entry point ``meshtool.validate:physics``): found and loaded here.

Its signature and outcome are :mod:`meshtool.validate.plugin_types` (types only, which the plugin imports); this
module is the one that loads it, so the run-time edge to the plugin starts here (``tests/test_layering.py``).
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from meshtool.plugins import installed, load_plugin
from meshtool.validate.plugin_types import COMPUTED_WITH, PhysicsCheck

#: Entry-point group of ``meshtool validate``'s physics rules.
VALIDATE_GROUP = "meshtool.validate"


@cache
def physics_plugin() -> PhysicsCheck | None:
    """The installed ``meshtool.validate:physics`` plugin, or ``None``."""
    plugin: PhysicsCheck | None = load_plugin(VALIDATE_GROUP, "physics")
    return plugin


def environment() -> dict[str, Any]:
    """What validate's results depend on besides the files and options: the physics plugin and library versions.

    Part of the cache key: installing or removing the plugin, or upgrading MuJoCo or trimesh, re-checks
    every asset. Read from the installed distributions' metadata (nothing is imported).
    """
    point = installed(VALIDATE_GROUP, "physics")
    plugin = None
    if point is not None:
        dist = point.dist
        plugin = f"{point.value} ({dist.name} {dist.version})" if dist is not None else point.value
    versions: dict[str, str | None] = {}
    for name in COMPUTED_WITH:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = None
    return {"plugin": plugin, "versions": versions}
