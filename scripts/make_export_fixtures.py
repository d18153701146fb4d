"""Write fixtures/mjcf/exports/: an MJCF model whose exports used to lose what it says (issue 37 item 5).

``settings.xml`` has ``<compiler boundmass="0.05" boundinertia="0.001">`` (its light tip is raised to the
bounds), a world geom (a 4 x 4 x 0.1 m slab of density 1000: 1.6 t that belongs to no body in MuJoCo), a mesh
in MuJoCo's legacy binary format (``tet.msh``, a tetrahedron with normals and texture coordinates), a
one-joint ``<equality joint>`` (the hinge held at its reference angle) and a geom whose world rotation is the
identity reached through its body's turn and its own opposite one (``1 1 1 3`` then ``1 -1 -1 -3``), which
``mju_mat2Quat`` returns as ``w = 1.0000000000000002``. ``settings.toml`` puts it in a world.

Usage: python scripts/make_export_fixtures.py
"""

from __future__ import annotations

import shutil
import struct
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf" / "exports"

MODEL = """<!-- Made for simrun's export tests (scripts/make_export_fixtures.py): compiler bounds, a world geom, a .msh
     mesh, a one-joint equality and a geom whose world rotation is a composed identity. -->
<mujoco model="export_settings">
  <compiler angle="radian" boundmass="0.05" boundinertia="0.001"/>
  <asset>
    <mesh name="tet" file="tet.msh"/>
  </asset>
  <worldbody>
    <geom name="slab" type="box" size="2 2 0.05" pos="0 0 -0.05" density="1000"/>
    <body name="base" pos="0 0 0.05">
      <geom name="base" type="box" size="0.05 0.05 0.02" mass="0.4"/>
      <body name="tip" pos="0 0 0.1">
        <joint name="swing" axis="0 1 0" damping="0.1"/>
        <geom name="tip" type="sphere" size="0.01" mass="0.001"/>
        <geom name="tet" type="mesh" mesh="tet" mass="0.001"/>
      </body>
      <body name="turned" pos="0.1 0 0" quat="1 1 1 3">
        <geom name="straight" type="box" size="0.01 0.02 0.03" quat="1 -1 -1 -3" mass="0.05"/>
      </body>
    </body>
  </worldbody>
  <equality>
    <joint name="hold" joint1="swing"/>
  </equality>
</mujoco>
"""

SCENE = """# The export fixture model in a world (scripts/make_export_fixtures.py): MJCF, USD and GLB exports keep it.
[world]
timestep = 0.002

[[entities]]
type = "MjcfRobot"
name = "robot"
file = "settings.xml"
"""


def tetrahedron_msh() -> bytes:
    """A tetrahedron in MuJoCo's legacy ``.msh`` (little-endian).

    int32 counts (4 vertices, 4 normals, 4 texture coordinates, 4 faces), then float32 positions, normals and
    texture coordinates and int32 faces.
    """
    vertices = [(0.0, 0.0, 0.0), (0.04, 0.0, 0.0), (0.0, 0.03, 0.0), (0.0, 0.0, 0.02)]
    normals = [(-0.57735, -0.57735, -0.57735), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    uvs = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.5, 0.5)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = struct.pack("<4i", len(vertices), len(normals), len(uvs), len(faces))
    data += b"".join(struct.pack("<3f", *v) for v in vertices)
    data += b"".join(struct.pack("<3f", *n) for n in normals)
    data += b"".join(struct.pack("<2f", *t) for t in uvs)
    return data + b"".join(struct.pack("<3i", *f) for f in faces)


def main() -> None:
    if ROOT.exists():
        shutil.rmtree(ROOT)
    ROOT.mkdir(parents=True)
    (ROOT / "settings.xml").write_text(MODEL, encoding="utf-8")
    (ROOT / "tet.msh").write_bytes(tetrahedron_msh())
    (ROOT / "settings.toml").write_text(SCENE, encoding="utf-8")


if __name__ == "__main__":
    main()
