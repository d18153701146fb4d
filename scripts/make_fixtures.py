"""Regenerate the test fixtures in fixtures/ (deterministic; the committed files are its output).

Usage: python scripts/make_fixtures.py
"""

from __future__ import annotations

import io
import math
import shutil
from pathlib import Path

import make_validate_fixtures  # the same folder: scripts/
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent / "fixtures"


def gradient(size: int = 16) -> Image.Image:
    y, x = np.mgrid[0:size, 0:size]
    rgb = np.stack([x * 255 // (size - 1), y * 255 // (size - 1), np.full_like(x, 96)], axis=2).astype(np.uint8)
    return Image.fromarray(rgb, "RGB")


def write(path: Path, text: str | bytes, newline: str = "\n", encoding: str = "utf-8") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, str):
        text = text.replace("\n", newline).encode(encoding)
    path.write_bytes(text)


def image(path: Path, img: Image.Image, fmt: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    img.save(buf, format=fmt)
    path.write_bytes(buf.getvalue())


def head() -> None:
    """3ds Max export: spaces in names, absolute Windows texture path, BMP, centimetres, Y-up, CRLF."""
    rings, segments = 6, 8
    rx, ry, rz = 8.0, 12.0, 10.0
    v, vt, faces = [], [], []
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2 * math.pi * j / segments
            v.append(
                (
                    rx * math.sin(theta) * math.cos(phi),
                    ry + ry * math.cos(theta),
                    rz * math.sin(theta) * math.sin(phi),
                )
            )
            vt.append((j / segments, 1 - i / rings))
    row = segments + 1
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = i * row + j + 1, i * row + j + 2, (i + 1) * row + j + 2, (i + 1) * row + j + 1
            if i == 0:
                faces.append((a, c, d))
            elif i == rings - 1:
                faces.append((a, b, d))
            else:
                faces.append((a, b, c, d))
    lines = [
        "# 3ds Max Wavefront OBJ Exporter v0.97b - (c)2007 guruware",
        "# File Created: 21.11.2026 10:00:00",
        "",
        "mtllib Head 1.mtl",
        "",
        "#",
        "# object Head 1",
        "#",
        "",
    ]
    lines += [f"v  {x:.4f} {y:.4f} {z:.4f}" for x, y, z in v]
    lines += [f"# {len(v)} vertices", ""]
    lines += [f"vt {u:.4f} {w:.4f} 0.0000" for u, w in vt]
    lines += [f"# {len(vt)} texture coords", "", "g Head 1", "usemtl Head_Material", "s 1"]
    lines += ["f " + " ".join(f"{k}/{k}" for k in f) + " " for f in faces]
    lines += [f"# {len(faces)} polygons", ""]
    write(ROOT / "head" / "Head 1.obj", "\n".join(lines), newline="\r\n")
    mtl = """# 3ds Max Wavefront OBJ Exporter v0.97b - (c)2007 guruware
# File Created: 21.11.2026 10:00:00

newmtl Head_Material
	Ns 10.0000
	Ni 1.5000
	d 1.0000
	Tr 0.0000
	Tf 1.0000 1.0000 1.0000
	illum 2
	Ka 0.5882 0.5882 0.5882
	Kd 0.5882 0.5882 0.5882
	Ks 0.0000 0.0000 0.0000
	Ke 0.0000 0.0000 0.0000
	map_Ka C:\\Users\\sama-sama\\Desktop\\Head 1\\Head 1.bmp
	map_Kd C:\\Users\\sama-sama\\Desktop\\Head 1\\Head 1.bmp
"""
    write(ROOT / "head" / "Head 1.mtl", mtl, newline="\r\n")
    image(ROOT / "head" / "Head 1.bmp", gradient(), "BMP")


CUBE_V = """v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.5 0.5 0.5
v -0.5 0.5 0.5
vt 0 0
vt 1 0
vt 1 1
vt 0 1
"""


def simple_cases() -> None:
    # wrong case everywhere: MTL name, texture folder and file
    write(
        ROOT / "case_mismatch" / "model.obj",
        "mtllib MODEL.MTL\n"
        + CUBE_V
        + """usemtl Wood
f 1/1 4/4 3/3 2/2
f 5/1 6/2 7/3 8/4
f 1/1 2/2 6/3 5/4
f 2/1 3/2 7/3 6/4
f 3/1 4/2 8/3 7/4
f 4/1 1/2 5/3 8/4
""",
    )
    write(ROOT / "case_mismatch" / "model.mtl", "newmtl Wood\nKd 0.6 0.4 0.2\nmap_Kd Textures\\Wood.PNG\n")
    image(ROOT / "case_mismatch" / "textures" / "wood.png", gradient(8), "PNG")

    # three materials, JPG and TGA textures, interleaved usemtl, two objects
    write(
        ROOT / "multi_material" / "crate.obj",
        "# Blender 4.2 OBJ\nmtllib crate.mtl\no Body\n"
        + CUBE_V
        + """usemtl painted
f 1/1 4/4 3/3 2/2
usemtl wood
f 5/1 6/2 7/3 8/4
usemtl painted
f 1/1 2/2 6/3 5/4
o Lid
usemtl checker
f 2/1 3/2 7/3 6/4
usemtl wood
f 3/1 4/2 8/3 7/4
usemtl checker
f 4/1 1/2 5/3 8/4
""",
    )
    write(
        ROOT / "multi_material" / "crate.mtl",
        """newmtl painted
Kd 0.8 0.1 0.1
Ks 0.5 0.5 0.5
Ns 96.0

newmtl wood
Kd 1 1 1
map_Kd -s 2 2 1 wood grain.jpg

newmtl checker
Kd 1.0 1.0 1.0
map_Kd "checker.tga" -clamp on

newmtl unused
Kd 0 1 0
""",
    )
    img = gradient(16)
    image(ROOT / "multi_material" / "wood grain.jpg", img, "JPEG")
    check = np.kron((np.indices((4, 4)).sum(0) % 2), np.ones((4, 4))).astype(np.uint8) * 255
    image(ROOT / "multi_material" / "checker.tga", Image.fromarray(np.stack([check] * 3, 2), "RGB"), "TGA")

    # CRLF, negative indices, a concave hexagon (L shape), a concave quad (dart) and a 10-point star
    star = []
    for k in range(10):
        r = 1.0 if k % 2 == 0 else 0.4
        a = math.pi / 2 + k * math.pi / 5
        star.append(f"v {3 + r * math.cos(a):.6f} {r * math.sin(a):.6f} 0")
    text = "\n".join(
        [
            "# L-shaped hexagon, area 3",
            "v 0 0 0",
            "v 2 0 0",
            "v 2 1 0",
            "v 1 1 0",
            "v 1 2 0",
            "v 0 2 0",
            "f -6 -5 -4 -3 -2 -1",
            "# dart (concave quad, reflex corner at its 4th vertex), area 0.5",
            "v 1 -4 0",
            "v 0 -3 0",
            "v -1 -4 0",
            "v 0 -3.5 0",
            "f -4 -3 -2 -1",
            "# ten-point star",
            *star,
            "f " + " ".join(str(k) for k in range(-10, 0)),
            "",
        ]
    )
    write(ROOT / "crlf_ngon" / "shapes.obj", text, newline="\r\n")

    write(
        ROOT / "missing_texture" / "panel.obj",
        "mtllib panel.mtl\n" + CUBE_V + "usemtl metal\nf 1/1 2/2 3/3 4/4\n",
    )
    write(ROOT / "missing_texture" / "panel.mtl", "newmtl metal\nKd 0.7 0.7 0.75\nmap_Kd brushed.png\n")

    write(
        ROOT / "missing_mtl" / "box.obj",
        "mtllib gone.mtl\n" + CUBE_V + "usemtl steel\nf 1 2 3 4\nf 5 6 7 8\n",
    )

    write(
        ROOT / "traversal" / "evil.obj",
        "mtllib ../../../../../../etc/passwd\nmtllib evil.mtl\n" + CUBE_V + "usemtl skin\nf 1/1 2/2 3/3\n",
    )
    write(
        ROOT / "traversal" / "evil.mtl",
        "newmtl skin\nKd 0.9 0.8 0.7\nmap_Kd /etc/hostname\nmap_Ks ../../secret.png\n",
    )

    write(ROOT / "bad_index" / "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n")
    write(ROOT / "nan" / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 1 1 1\nf 1 2 3\n")
    write(ROOT / "empty" / "empty.obj", b"")
    write(ROOT / "empty" / "comments.obj", "# only a comment\n\n   \n")
    garbage = bytes((i * 97 + 13) % 256 for i in range(512))
    write(ROOT / "garbage" / "garbage.obj", b"\x89PNG\r\n\x1a\n" + garbage)
    write(
        ROOT / "utf16" / "part.obj",
        "# UTF-16 export\ng Größe\n" + CUBE_V + "f 1 2 3\nf 1 3 4\n",
        encoding="utf-16",
    )
    write(
        ROOT / "latin1" / "piece.obj",
        "mtllib piece.mtl\n" + CUBE_V + "usemtl Métal\nf 1/1 2/2 3/3\n",
        encoding="latin-1",
    )
    write(ROOT / "latin1" / "piece.mtl", "newmtl Métal\nKd 0.5 0.5 0.5\nmap_Kd béton.png\n", encoding="latin-1")
    image(ROOT / "latin1" / "béton.png", gradient(4), "PNG")

    write(
        ROOT / "features" / "features.obj",
        """# every statement the reader knows
mtllib lib a.mtl lib b.mtl
o Thing
v 0 0 0 1 0 0
v 1 0 0 0 1 0
v 1 1 0 0 0 1
v 0 1 0 1.0 1 1
v 0 0 1 1.0
vt 0 0 0
vt 1 0
vt 1 1
vn 0 0 1
s off
g front back
usemtl first
f 1/1/1 2/2/1 \\
3/3/1
f 1//1 3//1 4//1
l 1 2 3
p 4
s 1
usemtl second
f 1 2 5
f 1 5 4 # inline comment
""",
    )
    write(ROOT / "features" / "lib a.mtl", "newmtl first\nKd 1 0 0\n")
    write(ROOT / "features" / "lib b.mtl", "newmtl second\nKd 0 0 1\n")
    write(ROOT / "points" / "cloud.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n")


def bowl() -> None:
    """A hemispherical bowl (metres, Z-up, opening up): concave, so one convex hull fills its cavity."""
    import manifold3d

    outer = manifold3d.Manifold.sphere(0.1, 24)
    inner = manifold3d.Manifold.sphere(0.09, 24)
    cut = manifold3d.Manifold.cube([0.3, 0.3, 0.15]).translate([-0.15, -0.15, 0.0])
    mesh = ((outer - inner) - cut).to_mesh()
    v = np.asarray(mesh.vert_properties)[:, :3].astype(np.float64)
    f = np.asarray(mesh.tri_verts)
    lines = ["# bowl: outer radius 0.1 m, wall 0.01 m, metres, Z-up"]
    lines += [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
    write(ROOT / "bowl" / "bowl.obj", "\n".join(lines) + "\n")


def scenes() -> None:
    """The seed's basic environment and a head on a table (uses the packed seed head)."""
    from meshtool.pipeline import ConvertOptions, convert
    from meshtool.repair.normalise import NormaliseOptions

    folder = ROOT / "scenes"
    folder.mkdir(parents=True, exist_ok=True)
    h, w = 64, 128
    y, x = np.mgrid[0:h, 0:w]
    land = ((np.sin(x / 9.0) + np.cos(y / 7.0)) > 0.6).astype(np.uint8)
    rgb = np.stack([40 + 60 * land, 90 + 90 * land, 200 - 150 * land], axis=2).astype(np.uint8)
    image(folder / "globe.png", Image.fromarray(rgb, "RGB"), "PNG")
    convert(ROOT / "head" / "Head 1.obj", folder / "head.mbin", ConvertOptions(NormaliseOptions(units="cm")))
    write(
        folder / "basic.toml",
        """# The seed's basic environment: sky, ground, a 0.2 m box (100 kg), a globe (10 kg).
[world]
timestep = 0.002

[[entities]]
type = "Sky"
name = "sky"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Light"
name = "sun"
pose = { position = [0.0, 0.0, 4.0] }
direction = [0.3, 0.2, -1.0]

[[entities]]
type = "Box"
name = "box"
free = true
mass = 100.0
dimensions = [0.2, 0.2, 0.2]
color = [0.8, 0.3, 0.2, 1.0]
pose = { position = [0.0, 0.0, 0.1] }

[[entities]]
type = "Sphere"
name = "globe"
free = true
mass = 10.0
radius = 0.15
texture = "globe.png"
pose = { position = [0.6, 0.0, 0.5] }

[[entities]]
type = "Camera"
name = "view"
main = true
eye = [2.0, -2.0, 1.2]
target = [0.0, 0.0, 0.2]
""",
    )
    write(
        folder / "head_on_table.toml",
        """# The packed seed head (collision: its convex hull) dropped onto a table.
[world]
timestep = 0.002

[assets]
head = "head.mbin"

[[entities]]
type = "Sky"
name = "sky"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Box"
name = "table"
dimensions = [1.0, 0.6, 0.05]
color = [0.55, 0.4, 0.25, 1.0]
pose = { position = [0.0, 0.0, 0.725] }

[[entities]]
type = "MeshEntity"
name = "head"
asset = "head"
free = true
mass = 2.0
pose = { position = [0.0, 0.0, 0.9] }
""",
    )


BOEBOT_SCENE = """# The seed's Boe-Bot scene: sky, ground, a Boe-Bot at (1, 1) with a drive service, a 0.2 m box.
[world]
timestep = 0.002

[[entities]]
type = "Sky"
name = "sky"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "BoeBot"
name = "boebot"
pose = { position = [1.0, 1.0, 0.001] }

[[entities]]
type = "Box"
name = "box"
mass = 5.0
free = true
dimensions = [0.2, 0.2, 0.2]
pose = { position = [1.6, 1.0, 0.1] }

[[services]]
type = "DriveService"
entity = "boebot"
"""


def square_commands() -> str:
    """Timed DriveService calls that take the Boe-Bot of boebot.toml around the box and back (at full power).

    The Boe-Bot's servos give 0.131 m/s, so a leg of 0.8 m takes 7.2 s; each call starts 0.2-0.3 s after the
    previous one ends (times measured in simulation), the last ends at 39.7 s.
    """
    lines = ["# Drive the Boe-Bot of boebot.toml around the box and back to its start: a right turn, legs of 0.3,\n"]
    lines.append("# 0.8, 0.6, 0.8 and 0.3 m with left turns between them, 0.2 m or more from the box.\n")
    sequence: list[tuple[float, str, list[float]]] = [(0.2, "rotate_degrees", [-90.0, 1.0])]
    starts = [2.6, 6.2, 8.5, 16.0, 18.3, 24.2, 26.5, 34.0, 36.3]
    calls = [("drive_distance", [0.3, 1.0])]
    for leg in (0.8, 0.6, 0.8, 0.3):
        calls += [("rotate_degrees", [90.0, 1.0]), ("drive_distance", [leg, 1.0])]
    sequence += [(t, call, args) for t, (call, args) in zip(starts, calls, strict=True)]
    for t, call, args in sequence:
        lines.append(f'[[commands]]\nt = {t:.1f}\nentity = "boebot"\ncall = "{call}"\nargs = {args}\n\n')
    return "".join(lines).rstrip() + "\n"


def robot_scenes() -> None:
    """Scenes with robots (the drive stack)."""
    write(ROOT / "scenes" / "boebot.toml", BOEBOT_SCENE)
    write(ROOT / "scenes" / "square.commands.toml", square_commands())
    walls = ""
    for name, pos, dims in (
        ("north", (0, 2, 0.25), (4, 0.1, 0.5)),
        ("south", (0, -2, 0.25), (4, 0.1, 0.5)),
        ("east", (2, 0, 0.25), (0.1, 4, 0.5)),
        ("west", (-2, 0, 0.25), (0.1, 4, 0.5)),
    ):
        walls += (
            f'\n[[entities]]\ntype = "Box"\nname = "wall_{name}"\ndimensions = [{dims[0]:.1f}, {dims[1]:.1f}, '
            f"{dims[2]:.1f}]\npose = {{ position = [{pos[0]:.1f}, {pos[1]:.1f}, {pos[2]:.2f}] }}\n"
        )
    write(
        ROOT / "scenes" / "pioneer_room.toml",
        f"""# A Pioneer 3-DX with a 360-ray laser in a 4 x 4 m walled room.
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"
{walls}
[[entities]]
type = "Pioneer3DX"
name = "p3dx"
pose = {{ position = [0.5, 0.0, 0.001] }}

[[services]]
type = "DriveService"
entity = "p3dx"

[[sensors]]
type = "LaserRangeFinder"
name = "laser"
entity = "p3dx"
fov_deg = 360.0
rays = 360
rate = 10.0
""",
    )
    write(
        ROOT / "scenes" / "arm_on_base.toml",
        """# A Lynx L6-style arm mounted on a Pioneer 3-DX (the seed's Corobot + Lynx arm case).
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Pioneer3DX"
name = "base"
pose = { position = [0.0, 0.0, 0.001] }

[[entities]]
type = "LynxL6"
name = "arm"
parent = "base"
pose = { position = [0.1, 0.0, 0.237] }

[[services]]
type = "DriveService"
entity = "base"

[[services]]
type = "ArmService"
entity = "base/arm"
""",
    )


URDF_ARM = """<?xml version="1.0"?>
<!-- A three-link arm in the ROS layout: an OBJ base in millimetres with a JPG texture, an STL link in
     millimetres, primitives, a fixed tool link, and package:// mesh paths. -->
<robot name="tiny_arm">
  <link name="base_link">
    <inertial>
      <origin xyz="0 0 0.025" rpy="0 0 0"/>
      <mass value="2.0"/>
      <inertia ixx="0.002083" ixy="0" ixz="0" iyy="0.002083" iyz="0" izz="0.003333"/>
    </inertial>
    <visual>
      <origin xyz="0 0 0" rpy="0 0 0"/>
      <geometry><mesh filename="package://tiny_arm_description/meshes/base.obj" scale="0.001 0.001 0.001"/></geometry>
    </visual>
    <collision>
      <geometry><mesh filename="package://tiny_arm_description/meshes/base.obj" scale="0.001 0.001 0.001"/></geometry>
    </collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/>
    <child link="upper"/>
    <origin xyz="0 0 0.05" rpy="0 0 0.3"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2.0" upper="2.0" effort="10" velocity="2"/>
    <dynamics damping="0.1" friction="0.01"/>
  </joint>
  <link name="upper">
    <inertial>
      <origin xyz="0 0 0.1" rpy="0 0 0"/>
      <mass value="0.5"/>
      <inertia ixx="0.00172" ixy="0" ixz="0" iyy="0.00172" iyz="0" izz="0.0001"/>
    </inertial>
    <visual>
      <geometry>
        <mesh filename="package://tiny_arm_description/meshes/upper arm.stl" scale="0.001 0.001 0.001"/>
      </geometry>
      <material name="grey"><color rgba="0.5 0.5 0.55 1"/></material>
    </visual>
    <collision>
      <geometry><mesh filename="../meshes/upper arm.stl" scale="0.001 0.001 0.001"/></geometry>
    </collision>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="upper"/>
    <child link="fore"/>
    <origin xyz="0 0 0.2" rpy="0.2 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="5" velocity="2"/>
  </joint>
  <link name="fore">
    <inertial>
      <origin xyz="0.075 0 0" rpy="0 0 0"/>
      <mass value="0.3"/>
      <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0006" iyz="0" izz="0.0006"/>
    </inertial>
    <visual>
      <origin xyz="0.075 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.015" length="0.15"/></geometry>
    </visual>
    <collision>
      <origin xyz="0.075 0 0" rpy="0 0 0"/>
      <geometry><box size="0.15 0.03 0.03"/></geometry>
    </collision>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="fore"/>
    <child link="tool"/>
    <origin xyz="0.15 0 0" rpy="0 0 0"/>
    <axis xyz="1 0 0"/>
    <limit lower="0" upper="0.05" effort="20" velocity="0.5"/>
  </joint>
  <link name="tool">
    <inertial>
      <mass value="0.05"/>
      <inertia ixx="0.00001" ixy="0" ixz="0" iyy="0.00001" iyz="0" izz="0.00001"/>
    </inertial>
    <collision><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <joint name="tip_fixed" type="fixed">
    <parent link="tool"/>
    <child link="tip"/>
    <origin xyz="0.02 0 0" rpy="0 0 0"/>
  </joint>
  <link name="tip"/>
</robot>
"""


def _binary_stl(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    tris = vertices[faces]
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    record = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    data = np.zeros(len(faces), dtype=record)
    data["n"], data["v"] = normals, tris
    return b"tiny_arm upper link, millimetres".ljust(80, b" ") + np.uint32(len(faces)).tobytes() + data.tobytes()


def urdf_robot() -> None:
    pkg = ROOT / "urdf" / "tiny_arm_description"
    write(pkg / "urdf" / "tiny_arm.urdf", URDF_ARM)
    # base: a 100 x 100 x 50 mm box (Z-up, as URDF meshes are), textured with a JPG.
    corners = [(x, y, z) for z in (0, 50) for y in (-50, 50) for x in (-50, 50)]
    lines = ["# tiny arm base, millimetres, Z-up", "mtllib base.mtl"]
    lines += [f"v {x} {y} {z}" for x, y, z in corners]
    lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1", "usemtl painted"]
    quads = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]
    lines += [f"f {a}/1 {b}/2 {c}/3 {d}/4" for a, b, c, d in quads]
    write(pkg / "meshes" / "base.obj", "\n".join(lines) + "\n")
    write(pkg / "meshes" / "base.mtl", "newmtl painted\nKd 1 1 1\nmap_Kd ../textures/base.jpg\n")
    image(pkg / "textures" / "base.jpg", gradient(16), "JPEG")
    # upper arm: a 24-sided cylinder, radius 20 mm, 200 mm tall, standing on z = 0.
    n = 24
    angles = np.arange(n) * 2 * math.pi / n
    ring = np.stack([20 * np.cos(angles), 20 * np.sin(angles)], axis=1)
    vertices = np.concatenate([np.c_[ring, np.zeros(n)], np.c_[ring, np.full(n, 200.0)], [[0, 0, 0], [0, 0, 200]]])
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i), (2 * n, j, i), (2 * n + 1, n + i, n + j)]
    write(pkg / "meshes" / "upper arm.stl", _binary_stl(vertices.astype(np.float64), np.asarray(faces)))
    write(
        pkg / "urdf" / "missing_mesh.urdf",
        URDF_ARM.replace('meshes/upper arm.stl" scale', 'meshes/lower arm.stl" scale', 1),
    )
    write(pkg / "urdf" / "escape.urdf", URDF_ARM.replace("../meshes/upper arm.stl", "../../secret.stl", 1))
    write(
        ROOT / "scenes" / "urdf_arm.toml",
        """# The fixture URDF arm on a table, imported through meshtool (package:// meshes in mm, JPG texture).

[world]
timestep = 0.002

[[entities]]
type = "Sky"
name = "sky"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Box"
name = "table"
dimensions = [0.6, 0.6, 0.4]
pose = { position = [0.0, 0.0, 0.2] }

[[entities]]
type = "UrdfRobot"
name = "arm"
urdf = "../urdf/tiny_arm_description/urdf/tiny_arm.urdf"
actuators = true
pose = { position = [0.0, 0.0, 0.4] }
""",
    )
    write(ROOT / "urdf" / "secret.stl", _binary_stl(vertices.astype(np.float64), np.asarray(faces)))


def main() -> None:
    for child in ROOT.iterdir():
        if child.is_dir() and child.name != "golden":  # goldens are written once, never regenerated here
            shutil.rmtree(child)
    head()
    simple_cases()
    bowl()
    scenes()
    robot_scenes()
    urdf_robot()
    make_validate_fixtures.main()


if __name__ == "__main__":
    main()
