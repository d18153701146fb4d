"""Write fixtures/vendor/: a vendor's MJCF robot two and three folders above its OBJ meshes (issue 38).

The layout robot vendors ship (``robots/NAME/robot.xml`` over ``meshes/PART/part.obj`` and
``meshes/convex/PART/part.obj``, the model naming them through ``<compiler meshdir="../../meshes"/>``). Each
OBJ carries the header Blender's OBJ exporter writes (whose default is Y-up) while the MJCF uses the file's
coordinates as MuJoCo does, Z-up: without the consumer, meshtool would turn every part 90 degrees about X.
The parts are small asymmetric wedges (every axis and sign can be told apart), each a different size.
``base.obj`` names an MTL that is not there (MuJoCo never reads it); ``finger.obj`` has its MTL.

Usage: python scripts/make_vendor_fixtures.py
"""

from __future__ import annotations

import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "vendor"

#: A wedge's corners (unit box scaled per part) and its eight triangles, outward.
CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (1, 0, 1), (1, 1, 1)]
TRIANGLES = [(0, 2, 1), (0, 3, 2), (0, 1, 4), (3, 5, 2), (1, 2, 5), (1, 5, 4), (0, 4, 5), (0, 5, 3)]
#: part -> (size x, y, z in metres, offset, missing MTL)
PARTS = {
    "base": ((0.3, 0.2, 0.1), (0.0, 0.0, 0.0), True),
    "finger": ((0.04, 0.12, 0.02), (0.05, 0.0, 0.1), False),
}


def wedge(size: tuple[float, float, float], offset: tuple[float, float, float], mtl: str | None, name: str) -> str:
    lines = ["# Blender v3.6.5 OBJ File: 'gripper.blend'", "# www.blender.org"]
    if mtl:
        lines.append(f"mtllib {mtl}")
    lines.append(f"o {name.capitalize()}")
    for corner in CORNERS:
        lines.append("v " + " ".join(f"{c * s + o:.6f}" for c, s, o in zip(corner, size, offset, strict=True)))
    if mtl:
        lines += ["usemtl Aluminium", "s off"]
    lines += ["f " + " ".join(str(i + 1) for i in tri) for tri in TRIANGLES]
    return "\n".join(lines) + "\n"


def write(rel: str, text: str) -> None:
    path = ROOT / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text.encode("utf-8"))


def main() -> None:
    shutil.rmtree(ROOT, ignore_errors=True)
    for part, (size, offset, missing) in PARTS.items():
        write(f"meshes/{part}/{part}.obj", wedge(size, offset, f"{part}.mtl", part))
        if not missing:
            write(
                f"meshes/{part}/{part}.mtl", "# Blender MTL File: 'gripper.blend'\nnewmtl Aluminium\nKd 0.8 0.8 0.85\n"
            )
        hull = (size[0] * 1.1, size[1] * 1.1, size[2] * 1.1)  # the collision copy: a slightly larger wedge
        write(f"meshes/convex/{part}/{part}.obj", wedge(hull, offset, None, part))
    write(
        "robots/gripper/robot.xml",
        """<mujoco model="gripper">
  <compiler angle="radian" meshdir="../../meshes"/>
  <default>
    <default class="visual"><geom type="mesh" contype="0" conaffinity="0" group="2"/></default>
    <default class="collision"><geom type="mesh" group="3"/></default>
  </default>
  <asset>
    <mesh name="base" file="base/base.obj"/>
    <mesh name="finger" file="finger/finger.obj"/>
    <mesh name="base_convex" file="convex/base/base.obj"/>
    <mesh name="finger_convex" file="convex/finger/finger.obj"/>
  </asset>
  <worldbody>
    <body name="base">
      <geom class="visual" mesh="base"/>
      <geom class="collision" mesh="base_convex"/>
      <body name="finger">
        <joint name="slide" type="slide" axis="0 1 0" range="0 0.05"/>
        <geom class="visual" mesh="finger"/>
        <geom class="collision" mesh="finger_convex"/>
      </body>
    </body>
  </worldbody>
</mujoco>
""",
    )


if __name__ == "__main__":
    main()
