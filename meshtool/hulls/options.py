"""The collision-hull options (the ``--hulls`` family): modes, presets and :class:`HullOptions`.

Light on purpose (no numpy): the command line builds its options and its ``--help`` from this module
without importing the hull code (:mod:`meshtool.hulls.compute`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from meshtool.errors import OptionsError

MODES = ("none", "convex", "decompose", "objects")
#: Largest coordinate magnitude hulled, metres. The normaliser refuses more than 1e6 m; far beyond that
#: qhull's arithmetic overflows (at 1e308 it fails with an internal error).
MAX_HULL_COORDINATE = 1e9
#: Preset budgets: (max hulls, max vertices per hull).
PRESETS: dict[str, tuple[int, int]] = {"mujoco": (32, 64), "mjx": (8, 32), "physx-gpu": (16, 64)}


@dataclass(frozen=True, slots=True)
class HullOptions:
    """How collision geometry is made (the ``--hulls`` family of options).

    Attributes:
        mode: ``none``, ``convex`` (one hull), ``decompose`` (CoACD per part) or ``objects`` (a hull per part).
        max_hulls: Most hulls per part in ``decompose`` mode.
        max_hull_vertices: Most vertices per hull; larger hulls are re-hulled from the points qhull adds first.
        min_thickness: Smallest hull thickness, metres; thinner hulls are thickened (capped at 5 % of the
            part's largest extent so tiny parts stay tiny).
        merge_parts: Decompose the whole mesh at once instead of part by part.
        threshold: CoACD concavity threshold (0.01..1; smaller gives more, tighter hulls).
        seed: CoACD random seed (fixed for determinism).
        timeout_s: Limit for one CoACD run, seconds.
        time_budget_s: Limit for all CoACD runs of one asset, seconds; parts left when it is spent get
            their convex hull (a ``decompose-budget`` warning).
        cache_dir: Decomposition cache folder; ``None`` disables the cache.
    """

    mode: str = "convex"
    max_hulls: int = 32
    max_hull_vertices: int = 64
    min_thickness: float = 0.001
    merge_parts: bool = False
    threshold: float = 0.05
    seed: int = 0
    timeout_s: float = 300.0
    cache_dir: Path | None = None
    time_budget_s: float = 180.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise OptionsError(f"unknown hull mode {self.mode!r}", hint=f"use one of {', '.join(MODES)}")
        if self.max_hulls < 1 or self.max_hull_vertices < 4:
            raise OptionsError("--max-hulls must be >= 1 and --max-hull-vertices >= 4")
        if not (self.min_thickness > 0 and 0 < self.threshold <= 1 and self.timeout_s > 0 and self.time_budget_s > 0):
            raise OptionsError("min thickness, threshold (0..1], timeout and time budget must be positive")

    @classmethod
    def preset(cls, name: str, **overrides: object) -> HullOptions:
        """Options with a preset's budgets (``mujoco``, ``mjx``, ``physx-gpu``), then ``overrides``."""
        if name not in PRESETS:
            raise OptionsError(f"unknown preset {name!r}", hint=f"use one of {', '.join(PRESETS)}")
        hulls, vertices = PRESETS[name]
        return replace(cls(max_hulls=hulls, max_hull_vertices=vertices), **overrides)  # type: ignore[arg-type]

    def fingerprint(self) -> dict[str, object]:
        """The options that change results (the cache folder does not)."""
        return {
            "mode": self.mode,
            "max_hulls": self.max_hulls,
            "max_hull_vertices": self.max_hull_vertices,
            "min_thickness": self.min_thickness,
            "merge_parts": self.merge_parts,
            "threshold": self.threshold,
            "seed": self.seed,
        }
