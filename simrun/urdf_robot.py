"""UrdfRobot: a URDF robot in a world, its meshes through meshtool's normalise -> hulls -> pack path.

The robot is imported with :func:`meshtool.urdf.import_urdf` (package:// paths, mm meshes, JPG textures
and all) into a model description, built into a child spec by :func:`simrun.mjcf_builder.spec_from_model`
(meshes from arrays, PNG textures in the world's virtual file system under names unique to the entity)
and attached under the entity's body with the ``NAME/`` prefix: ``arm/shoulder`` is the joint
``shoulder`` of the entity ``arm``. The root link sits at the entity's pose; ``free=True`` makes it a
mobile robot. A URDF ``world`` link becomes a body ``NAME/world_link`` fixed to the entity's body.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from meshtool.errors import MeshtoolError
from meshtool.hulls import HullOptions
from meshtool.model import BodyDesc
from meshtool.urdf import UrdfOptions, import_urdf
from simrun.entity import BuildContext, Entity
from simrun.errors import EntityError
from simrun.mjcf_builder import compile_spec, spec_from_model


@dataclass(kw_only=True)
class UrdfRobot(Entity):
    """A robot from a URDF file.

    Attributes:
        urdf: Path of the ``.urdf`` (relative to the world folder).
        package_dirs: ``package://NAME`` to folder (relative to the world folder); others are searched
            for upwards from the URDF.
        hulls: Collision hulls of mesh colliders: ``convex`` (one per mesh) or ``decompose`` (CoACD).
        actuators: Add a motor per moving joint, named like the joint, limited to its URDF effort.
    """

    TYPE: ClassVar[str] = "UrdfRobot"

    urdf: str
    package_dirs: dict[str, str] = field(default_factory=dict)
    hulls: str = "convex"
    actuators: bool = False

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Import the URDF and attach its bodies, joints, geoms and assets under ``body``."""
        if self.hulls not in ("convex", "decompose"):
            raise EntityError(f"UrdfRobot {self.name!r}: hulls must be 'convex' or 'decompose'")
        packages = tuple((name, ctx.base_dir / folder) for name, folder in sorted(self.package_dirs.items()))
        options = UrdfOptions(packages, HullOptions(mode=self.hulls), self.actuators)
        try:
            with _xml_parser_quiet():
                result = import_urdf(ctx.base_dir / self.urdf, options)
            model = result.model
            if model.world_geoms:  # a URDF 'world' link: a body fixed to the entity's body, named 'world_link'
                world = BodyDesc("world_link", geoms=model.world_geoms, children=model.bodies)
                model = dataclasses.replace(model, world_geoms=[], bodies=[world])
            tag = "".join(c if c.isalnum() else "_" for c in ctx.full_name)
            child, files = spec_from_model(model, texture_prefix=f"urdf_{tag}_")
            compile_spec(child, model)
        except MeshtoolError as exc:
            raise EntityError(f"UrdfRobot {self.name!r}: {exc.one_line()}") from None
        frame = body.add_frame()
        for root in child.worldbody.bodies:
            frame.attach_body(root, f"{ctx.full_name}/", "")
        ctx.assets.vfs.update(files)
        ctx.assets.sources.update(Path(os.path.realpath(p)) for p in result.sources)


@contextlib.contextmanager
def _xml_parser_quiet() -> Iterator[None]:
    """Silence yourdfpy's log records while a URDF is imported.

    For a file lxml refuses (an undefined entity, an XXE attempt) yourdfpy logs ``Entity 'x' not defined``
    and ``Using different parsing approach.`` as errors before meshtool raises its own one-line error; a
    library must not print, so the records are dropped here (the error that follows says what is wrong).
    """
    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        logger.setLevel(level)
