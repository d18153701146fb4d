"""Rules that need a simulator come from plugins, so that meshtool itself never imports one.

A plugin is a callable registered under the entry-point group ``meshtool.validate`` with the name
``physics``; this distribution registers :func:`simrun.asset_check.check_pack` (MuJoCo). It receives one
packed asset (``.mbin`` bytes) and returns a :class:`PhysicsOutcome`. When no plugin is installed the
physics rules are reported as not run.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from importlib.metadata import PackageNotFoundError, entry_points, version
from typing import Any, Protocol

from meshtool.findings import Finding
from meshtool.model import load_plugin

GROUP = "meshtool.validate"
#: Libraries whose versions change what rules compute (hulls, volumes, decoding, simulation).
COMPUTED_WITH = ("numpy", "scipy", "trimesh", "Pillow", "mujoco")


@dataclass(slots=True)
class PhysicsOutcome:
    """What a physics plugin found for one asset.

    Attributes:
        findings: Findings of the P rules (built with :func:`meshtool.validate.rules.hit`).
        thumbnail: PNG bytes (visual and collision views side by side), when asked for and possible.
        notes: Why something was not done (no GL context for the thumbnail, ...), one line each.
        stats: Numbers worth reporting (mass in kg, settle time in s, ...).
    """

    findings: list[Finding] = field(default_factory=list)
    thumbnail: bytes | None = None
    notes: list[str] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)


class PhysicsCheck(Protocol):
    """The signature of a physics plugin."""

    def __call__(self, mbin: bytes, name: str, limits: dict[str, float], thumbnail: bool) -> PhysicsOutcome:
        """Check one packed asset.

        Args:
            mbin: The ``.mbin`` bytes (metres, Z-up; collision hulls included when the asset has them).
            name: The asset's display name (for messages).
            limits: :meth:`meshtool.validate.config.Limits.as_dict`.
            thumbnail: Whether to render a thumbnail.
        """
        ...


@cache
def physics_plugin() -> PhysicsCheck | None:
    """The installed ``physics`` plugin, or ``None``."""
    plugin: PhysicsCheck | None = load_plugin(GROUP, "physics")
    return plugin


def environment() -> dict[str, Any]:
    """What the results depend on besides the files and options: the physics plugin and library versions.

    Part of the cache key: installing or removing the plugin, or upgrading MuJoCo or trimesh, re-checks
    every asset. Read from the installed distributions' metadata (nothing is imported).
    """
    plugin = None
    for point in entry_points(group=GROUP, name="physics"):
        dist = point.dist
        plugin = f"{point.value} ({dist.name} {dist.version})" if dist is not None else point.value
        break
    versions: dict[str, str | None] = {}
    for name in COMPUTED_WITH:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = None
    return {"plugin": plugin, "versions": versions}
