"""UrdfRobot: a URDF robot in a world, its meshes through meshtool's normalise -> hulls -> pack path.

The robot is imported with :func:`meshtool.urdf.import_urdf` (package:// paths, mm meshes, JPG textures
and all), its MJCF parsed into a child spec from memory and attached under the entity's body with the
``NAME/`` prefix: ``arm/shoulder`` is the joint ``shoulder`` of the entity ``arm``. The root link sits at
the entity's pose; ``free=True`` makes it a mobile robot.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, ClassVar

import mujoco

from meshtool.errors import MeshtoolError
from meshtool.hulls import HullOptions
from meshtool.urdf import UrdfOptions, import_urdf
from simrun.entity import BuildContext, Entity
from simrun.errors import EntityError

_FILE_ATTR = re.compile(r'file="([^"]+)"')


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
            result = import_urdf(ctx.base_dir / self.urdf, options)
        except MeshtoolError as exc:
            raise EntityError(f"UrdfRobot {self.name!r}: {exc.one_line()}") from None
        xml_name = f"{result.name}.xml"
        tag = "".join(c if c.isalnum() else "_" for c in ctx.full_name)
        renamed = {name: f"urdf_{tag}_{name}" for name in result.mjcf if name != xml_name}
        xml = _FILE_ATTR.sub(lambda m: f'file="{renamed.get(m.group(1), m.group(1))}"', result.mjcf[xml_name].decode())
        files = {renamed[name]: data for name, data in result.mjcf.items() if name in renamed}
        try:
            child = mujoco.MjSpec.from_string(xml, assets=files)
        except ValueError as exc:
            raise EntityError(f"UrdfRobot {self.name!r}: MuJoCo rejects the imported robot: {exc}") from None
        root = child.worldbody.first_body()
        frame = body.add_frame()
        frame.attach_body(root, f"{ctx.full_name}/", "")
        ctx.assets.vfs.update(files)
