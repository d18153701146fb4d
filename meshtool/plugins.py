"""How meshtool reaches its plugins (entry points a simulator package installs), and the MJCF plugins.

meshtool never imports MuJoCo (or simrun). What needs a simulator is found through entry points, looked up
here only (:func:`installed`, :func:`load_plugin`), each group loaded by one module:

- group ``meshtool.mjcf``: ``builder`` builds, writes and compiles an MJCF folder from a
  :class:`meshtool.mjcf.model_desc.ModelDesc` (``meshtool mjcf``, ``meshtool urdf``); ``check`` compiles one in memory
  (``obj2bin``'s check), loaded here. simrun registers :mod:`simrun.export.mjcf_builder`.
- group ``meshtool.validate``: ``physics`` runs the P rules of ``meshtool validate`` on one packed asset,
  loaded by :mod:`meshtool.validate.physics`. simrun registers :mod:`simrun.asset_check`.

The types both sides use (the model description, the outcome of a physics check) live in modules that load
nothing (:mod:`meshtool.mjcf.model_desc`, :mod:`meshtool.validate.plugin_types`), so a plugin that imports them never
imports its caller: ``tests/test_layering.py`` counts each entry point as an import of its target by the
module that loads it and finds no cycle.
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from meshtool.mjcf.model_desc import MjcfBuilder, ModelChecker, ModelDesc, ModelError

#: Entry-point group of the MJCF builder and the in-memory model check.
MJCF_GROUP = "meshtool.mjcf"


def installed(group: str, name: str) -> EntryPoint | None:
    """The first installed entry point ``name`` of ``group`` (read from metadata: nothing is imported)."""
    for point in entry_points(group=group, name=name):
        return point
    return None


def load_plugin(group: str, name: str) -> Any:
    """What the first installed entry point ``name`` of ``group`` names (loaded), or ``None``."""
    point = installed(group, name)
    return None if point is None else point.load()


@cache
def mjcf_builder() -> MjcfBuilder | None:
    """The installed MJCF builder plugin, or ``None``."""
    builder: MjcfBuilder | None = load_plugin(MJCF_GROUP, "builder")
    return builder


@cache
def mjcf_checker() -> ModelChecker | None:
    """The installed model check plugin (entry point ``meshtool.mjcf:check``), or ``None``."""
    checker: ModelChecker | None = load_plugin(MJCF_GROUP, "check")
    return checker


def check_model(model: ModelDesc) -> bool:
    """Whether MuJoCo could be asked: compile ``model`` with the installed plugin, writing nothing.

    Uses the ``check`` plugin (a compile in memory); an installation that registers only the ``builder``
    is asked through it (it also writes and reloads the folder in a scratch directory).

    Returns:
        ``True`` when MuJoCo compiled the model, ``False`` when no plugin is installed (nothing was checked).

    Raises:
        ModelError: MuJoCo refuses the model.
    """
    checker = mjcf_checker()
    if checker is not None:
        checker(model)
        return True
    builder = mjcf_builder()
    if builder is not None:
        builder(model)
        return True
    return False


def mjcf_files(model: ModelDesc) -> dict[str, bytes]:
    """Build, write and compile ``model`` with the installed builder; the files by name.

    Raises:
        ModelError: No builder is installed, or MuJoCo refuses the model.
    """
    builder = mjcf_builder()
    if builder is None:
        raise ModelError(
            "MJCF output needs a MuJoCo builder and none is installed (entry point 'meshtool.mjcf:builder')",
            hint="install simrun: pip install meshtool-simrun",
        )
    return builder(model)
