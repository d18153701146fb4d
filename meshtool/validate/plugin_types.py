"""Rules that need a simulator come from plugins, so that meshtool itself never imports one: their types.

A plugin is a callable registered under the entry-point group ``meshtool.validate`` with the name
``physics``; this distribution registers :func:`simrun.asset_check.check_pack` (MuJoCo). It receives one
packed asset (``.mbin`` bytes) and returns a :class:`PhysicsOutcome`. When no plugin is installed the
physics rules are reported as not run. The plugin is found and called through :mod:`meshtool.plugins`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from meshtool.findings import Finding

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
