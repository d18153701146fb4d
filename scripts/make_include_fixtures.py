"""Write fixtures/mjcf/included/: an MJCF arm spread over ``<include>`` files, and a ``simrun test`` scene of it.

``robot.xml`` (``<compiler meshdir="meshes" texturedir="textures"/>``) includes ``parts/assets.xml`` (relative to
the main file's folder), which includes ``defaults.xml`` (found beside ``parts/assets.xml`` only: MuJoCo's
second rule) and names a mesh ``meshes/paddle.obj`` and a material on the texture ``textures/grid.png``;
``robot.xml`` also includes ``parts/link.xml`` inside its base body: the hinged paddle that uses the mesh and
the material. ``swing.toml`` runs it for ``simrun test``: a position servo holds the hinge at 0.5 rad.

Usage: python scripts/make_include_fixtures.py
"""

from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf" / "included"

ROBOT = """<!-- An MJCF arm made for simrun's tests, spread over include files (scripts/make_include_fixtures.py). -->
<mujoco model="included_arm">
  <compiler angle="radian" meshdir="meshes" texturedir="textures" autolimits="true"/>
  <include file="parts/assets.xml"/>
  <worldbody>
    <body name="base">
      <geom name="base" type="box" size="0.05 0.05 0.02" pos="0 0 0.02" mass="0.4"/>
      <include file="parts/link.xml"/>
    </body>
  </worldbody>
  <actuator>
    <position name="swing" joint="swing" kp="20" kv="1" ctrlrange="-1.5 1.5"/>
  </actuator>
  <keyframe>
    <key name="home" qpos="0.5" ctrl="0.5"/>
  </keyframe>
</mujoco>
"""

ASSETS = """<mujoco>
  <include file="defaults.xml"/>
  <asset>
    <mesh name="paddle" file="paddle.obj"/>
    <texture name="grid" type="2d" file="grid.png"/>
    <material name="painted" texture="grid" rgba="1 1 1 1"/>
  </asset>
</mujoco>
"""

DEFAULTS = """<mujoco>
  <default>
    <joint damping="0.2" armature="0.005"/>
    <geom density="600" rgba="0.6 0.6 0.7 1"/>
  </default>
</mujoco>
"""

LINK = """<mujoco>
  <body name="paddle" pos="0 0 0.05">
    <joint name="swing" axis="0 1 0" range="-1.5 1.5"/>
    <geom name="paddle" type="mesh" mesh="paddle" material="painted" mass="0.1"/>
  </body>
</mujoco>
"""

SCENE = """# simrun test fixture (scripts/make_include_fixtures.py): the MJCF arm of robot.xml, whose parts come from
# <include> files, on the ground; its position servo holds the swing hinge at 0.5 rad (the home keyframe's
# control), and the expectation checks the joint there.
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "MjcfRobot"
name = "arm"
file = "robot.xml"
pose = { position = [0.0, 0.0, 0.001] }

[[services]]
type = "JointService"
entity = "arm"

[test]
duration = 1.0
commands = "swing.commands.toml"

[[expect]]
id = "swing-held"
message = "the hinge of the included link reaches its 0.5 rad target"
kind = "joint"
joint = "arm/swing"
min = 0.45
max = 0.55
at = "end"
"""

COMMANDS = """# Commands for swing.toml: the JointService moves the hinge to 0.5 rad at once.
[[commands]]
t = 0.0
service = "JointService"
entity = "arm"
call = "move_to"
args = [["swing"], [0.5], 0.3]
"""


def paddle_obj() -> str:
    """A 0.02 x 0.12 x 0.02 m bar (8 corners, 12 triangles, outward), texture coordinates on its corners."""
    corners = [(x, y, z) for x in (-0.01, 0.01) for y in (-0.01, 0.01) for z in (0.0, 0.12)]
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1)]
    faces += [(2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    lines = ["# paddle: made by scripts/make_include_fixtures.py"]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in corners]
    lines += [f"vt {(k & 1):g} {(k >> 1 & 1):g}" for k in range(8)]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in face) for face in faces]
    return "\n".join(lines) + "\n"


def grid_png(size: int = 8) -> bytes:
    """An 8 x 8 RGB checkerboard PNG (written by hand: no imaging library needed)."""
    rows = b"".join(
        b"\0" + b"".join(b"\xff\xff\xff" if (x + y) % 2 else b"\x20\x40\x80" for x in range(size)) for y in range(size)
    )

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b"")


def main() -> None:
    if ROOT.exists():
        shutil.rmtree(ROOT)
    for folder in ("parts", "meshes", "textures"):
        (ROOT / folder).mkdir(parents=True)
    (ROOT / "robot.xml").write_text(ROBOT, encoding="utf-8")
    (ROOT / "parts" / "assets.xml").write_text(ASSETS, encoding="utf-8")
    (ROOT / "parts" / "defaults.xml").write_text(DEFAULTS, encoding="utf-8")
    (ROOT / "parts" / "link.xml").write_text(LINK, encoding="utf-8")
    (ROOT / "meshes" / "paddle.obj").write_text(paddle_obj(), encoding="utf-8")
    (ROOT / "textures" / "grid.png").write_bytes(grid_png())
    (ROOT / "swing.toml").write_text(SCENE, encoding="utf-8")
    (ROOT / "swing.commands.toml").write_text(COMMANDS, encoding="utf-8")


if __name__ == "__main__":
    main()
