"""Entities: named pieces of a world that build MjSpec fragments and hold no simulation state.

The :class:`~simrun.world.world.World` creates one body per entity (named by its full name, ``parent/child``
for children) at the entity's pose and hands it to :meth:`Entity.build`, which adds geoms, sites, lights
or cameras named ``FULLNAME/...``. Runtime hooks receive ``model`` and ``data`` explicitly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.world.pose import Pose

if TYPE_CHECKING:
    from simrun.world.assets import AssetLibrary


@dataclass(frozen=True, slots=True)
class Material:
    """Contact material, MSRS style, mapped to MuJoCo (see docs/conventions.md).

    Attributes:
        restitution: Bounce, 0 (none) to 0.65: a ball dropped from h rises to about restitution^2 * h.
        dynamic_friction: Sliding friction coefficient (MuJoCo ``friction[0]``).
        static_friction: Recorded for completeness; MuJoCo has one sliding coefficient, the dynamic one.
    """

    restitution: float = 0.0
    dynamic_friction: float = 1.0
    static_friction: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.restitution <= MAX_RESTITUTION:
            raise EntityError(
                f"restitution must be in [0, {MAX_RESTITUTION}] (MuJoCo's soft contacts are unstable beyond), "
                f"got {self.restitution}"
            )
        if self.dynamic_friction < 0 or self.static_friction < 0:
            raise EntityError("friction coefficients must be >= 0")

    def apply(self, geom: Any) -> None:
        """Set a geom's ``friction`` and ``solref`` from this material."""
        geom.friction = [self.dynamic_friction, 0.005, 0.0001]
        geom.solref = list(restitution_solref(self.restitution))
        geom.priority = 1  # this geom's contact parameters win over a default partner's


#: Measured mapping from MuJoCo's contact damping ratio (solref[1], time constant 0.02 s) to the coefficient of
#: restitution of a ball dropped on a plane (timestep 0.002 s, implicitfast; 0.001 s differs by < 0.01).
#: Regenerate with ``python scripts/calibrate_restitution.py``; the table is in docs/conventions.md.
RESTITUTION_TABLE: tuple[tuple[float, float], ...] = (
    (0.15, 0.678),
    (0.2, 0.595),
    (0.25, 0.518),
    (0.3, 0.453),
    (0.4, 0.353),
    (0.5, 0.277),
    (0.6, 0.215),
    (0.7, 0.162),
    (0.8, 0.112),
    (0.9, 0.055),
    (1.0, 0.0),
)
MAX_RESTITUTION = 0.65
CONTACT_TIMECONST = 0.02


def restitution_solref(restitution: float) -> tuple[float, float]:
    """MuJoCo ``solref`` (time constant, damping ratio) giving a coefficient of restitution.

    Interpolates :data:`RESTITUTION_TABLE` (measured; MuJoCo's soft contacts do not follow the ideal
    spring-damper formula). 0 gives MuJoCo's default (0.02 s, critically damped).
    """
    zetas = [z for z, _ in RESTITUTION_TABLE][::-1]
    es = [e for _, e in RESTITUTION_TABLE][::-1]
    return (CONTACT_TIMECONST, float(np.interp(restitution, es, zetas)))


@dataclass(slots=True)
class BuildContext:
    """What an entity may use while building.

    Attributes:
        spec: The world's spec.
        full_name: The entity's full name (prefix for everything it adds).
        assets: Shared asset loading (``.mbin`` meshes, PNG textures), each added to the spec once.
        base_dir: Folder relative file names are resolved against.
        asset_paths: The world's named assets (name to ``.mbin`` path relative to ``base_dir``).
    """

    spec: mujoco.MjSpec
    full_name: str
    assets: AssetLibrary
    base_dir: Path
    asset_paths: dict[str, str] = field(default_factory=dict)

    def name(self, local: str) -> str:
        """``FULLNAME/local``."""
        return f"{self.full_name}/{local}"


@dataclass(kw_only=True)
class Entity:
    """Base of all entities.

    Attributes:
        name: Unique among its siblings; no ``/``.
        pose: Relative to the parent (or the world).
        parent: Full name of the parent entity, or ``None`` for the world.
        free: Give the body a free joint (it falls, collides, can be pushed); else it is welded in place.
        kinematic: Move it by :meth:`simrun.world.world.World.set_pose` (a MuJoCo mocap body); top level only.
    """

    TYPE: ClassVar[str] = "Entity"
    HAS_BODY: ClassVar[bool] = True
    #: Whether :meth:`build` adds nothing but elements of ``body`` (geoms, sites) and assets of ``ctx.assets``,
    #: so that a world of many entities may build it in a child spec (:mod:`simrun.world.batch`). Read from
    #: the class that defines the ``build`` an entity runs: a subclass overriding ``build`` is not batched
    #: unless it sets it too.
    BATCHABLE: ClassVar[bool] = False

    name: str
    pose: Pose = field(default_factory=Pose)
    parent: str | None = None
    free: bool = False
    kinematic: bool = False

    def body_pose(self) -> Pose:
        """Where the World places this entity's body (the pose, unless the entity derives it)."""
        return self.pose

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Add this entity's elements to ``body`` (or to ``ctx.spec`` for body-less entities)."""

    def before_step(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Runtime hook called before every physics step (no-op unless overridden)."""

    def parameters(self) -> dict[str, Any]:
        """The entity-specific fields (not name/pose/parent/free/kinematic), for scene files."""
        base = {f.name for f in fields(Entity)}
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name not in base}


def check_positive(entity: Entity, **values: float | None) -> None:
    """Raise :class:`EntityError` naming the entity when a given value is not a positive finite number."""
    for key, value in values.items():
        if value is not None and not (math.isfinite(value) and value > 0):
            raise EntityError(f"{entity.TYPE} {entity.name!r}: {key} must be a positive number, got {value}")
