"""UrdfRobot: a URDF robot in a world, its meshes through meshtool's normalise -> hulls -> pack path.

The robot is imported with :func:`meshtool.urdf.import_robot.import_urdf` (package:// paths, mm meshes, JPG textures
and all) into a model description, built into a child spec by :func:`simrun.export.mjcf_builder.spec_from_model`
(meshes from arrays, PNG textures in the world's virtual file system under names unique to the entity)
and attached under the entity's body with the ``NAME/`` prefix: ``arm/shoulder`` is the joint
``shoulder`` of the entity ``arm``. The root link sits at the entity's pose; ``free=True`` makes it a
mobile robot. A URDF ``world`` link becomes a body ``NAME/world_link`` fixed to the entity's body.

The services of MJCF robots work here too: a :class:`~simrun.services.joint_service.JointService` over the motors
(``actuators = true``), ``wheels`` for a :class:`~simrun.services.drive_service.DriveService`, sensors on a link
(``body = "NAME/link"``).
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
from meshtool.hulls.compute import HullOptions
from meshtool.mjcf.model_desc import BodyDesc
from meshtool.urdf.import_robot import UrdfOptions, import_urdf
from simrun.errors import EntityError
from simrun.export.mjcf_builder import compile_spec, spec_from_model
from simrun.robots.contract import Robot
from simrun.robots.mjcf_robot import WheelGeometry, wheel_geometry
from simrun.robots.wheels import WheelFields, Wheels
from simrun.world.entity import BuildContext, Entity


@dataclass(kw_only=True)
class UrdfRobot(WheelFields, Entity, Robot):
    """A robot from a URDF file.

    Attributes:
        urdf: Path of the ``.urdf`` (relative to the world folder).
        package_dirs: ``package://NAME`` to folder (relative to the world folder); others are searched
            for upwards from the URDF.
        hulls: Collision hulls of mesh colliders: ``convex`` (one per mesh) or ``decompose`` (CoACD).
        actuators: Add a motor per moving joint, named like the joint, limited to its URDF effort.
        wheels: Left and right wheel joints for a :class:`~simrun.services.drive_service.DriveService`: they get
            simrun's DC motors ``NAME/left_motor`` and ``NAME/right_motor`` (as an ``MjcfRobot``'s wheels;
            :class:`~simrun.robots.wheels.WheelFields`: ``wheel_radius``, ``track``, ``stall_torque``,
            ``no_load_speed`` too).
    """

    TYPE: ClassVar[str] = "UrdfRobot"

    urdf: str
    package_dirs: dict[str, str] = field(default_factory=dict)
    hulls: str = "convex"
    actuators: bool = False

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Import the URDF and attach its bodies, joints, geoms and assets under ``body``."""
        tag = "".join(c if c.isalnum() else "_" for c in ctx.full_name)
        child, files, result = self._child(ctx.base_dir, f"urdf_{tag}_")
        frame = body.add_frame()
        for root in child.worldbody.bodies:
            frame.attach_body(root, f"{ctx.full_name}/", "")
        ctx.assets.vfs.update(files)
        ctx.assets.sources.update(Path(os.path.realpath(p)) for p in result.sources)

    def _child(self, base_dir: Path, prefix: str) -> tuple[Any, dict[str, bytes], Any]:
        """The robot as a compiled child spec (wheel motors added), its in-memory files and the import result."""
        if self.hulls not in ("convex", "decompose"):
            raise EntityError(f"UrdfRobot {self.name!r}: hulls must be 'convex' or 'decompose'")
        packages = tuple((name, base_dir / folder) for name, folder in sorted(self.package_dirs.items()))
        options = UrdfOptions(packages, HullOptions(mode=self.hulls), self.actuators)
        try:
            with _xml_parser_quiet():
                result = import_urdf(base_dir / self.urdf, options)
            model = result.model
            if model.world_geoms:  # a URDF 'world' link: a body fixed to the entity's body, named 'world_link'
                world = BodyDesc("world_link", geoms=model.world_geoms, children=model.bodies)
                model = dataclasses.replace(model, world_geoms=[], bodies=[world])
            child, files = spec_from_model(model, texture_prefix=prefix)
            if self.wheels:
                self.add_wheel_motors(child, f"UrdfRobot {self.name!r}", self.urdf)
            compile_spec(child, model)
        except MeshtoolError as exc:
            raise EntityError(f"UrdfRobot {self.name!r}: {exc.one_line()}") from None
        return child, files, result

    def driven_wheels(self, full_name: str, model: Any, base: str) -> Wheels | None:
        """The named wheels in the world's model (:meth:`~simrun.robots.wheels.WheelFields.named_wheels`)."""
        return self.named_wheels(full_name, model, base)

    def wheel_geometry(self, base_dir: Path) -> WheelGeometry:
        """Wheel joints, radius and track, measured from the robot compiled alone where not given."""
        child, files, _ = self._child(Path(base_dir), "wheels_")
        child.assets = dict(files)
        return wheel_geometry(self, child.compile())


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
