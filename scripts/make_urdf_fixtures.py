# ruff: noqa: E501
"""Write fixtures/urdf/quirks/: a small robot with every URDF quirk the importer handles (see fixtures/README.md).

Run from the repository root: python scripts/make_urdf_fixtures.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "urdf" / "quirks"

URDF = """<?xml version="1.0" encoding="utf-8"?>
<!-- written by scripts/make_urdf_fixtures.py: one robot, every quirk -->
<!-- =================================================================== -->
<robot name="quirks">
  <material name="blue"><color rgba="0.1 0.2 0.9 1"/></material>
  <link name="world">
    <visual><geometry><box size="0.4 0.4 0.02"/></geometry></visual>
    <collision><geometry><box size="0.4 0.4 0.02"/></geometry></collision>
  </link>
  <joint name="anchor" type="fixed">
    <parent link="world"/><child link="base"/>
    <origin xyz="0 0 0.01"/>
  </joint>
  <link name="base">
    <!-- an exporter's zero inertia: fixed as balanceinertia does, with a warning -->
    <inertial><mass value="1.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <visual><geometry><mesh filename="package:///meshes/painted.dae"/></geometry></visual>
    <collision><geometry><mesh filename="package:///meshes/painted.dae"/></geometry></collision>
  </link>
  <joint name="turn" type="revolute">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.05" rpy="0 0 0.3"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="5" velocity="1"/>
  </joint>
  <link name="arm">
    <!-- a rotated inertial frame with products of inertia -->
    <inertial>
      <origin xyz="0.1 0.01 0.02" rpy="0.3 -0.2 0.5"/>
      <mass value="0.4"/>
      <inertia ixx="0.002" ixy="0.0003" ixz="-0.0001" iyy="0.003" iyz="0.0002" izz="0.004"/>
    </inertial>
    <visual><geometry><mesh filename="package://quirks_robot/meshes/fin.stl"/></geometry>
      <material name="blue"/></visual>
    <collision><geometry><mesh filename="package://quirks_robot/meshes/fin.stl"/></geometry></collision>
    <visual><origin xyz="0.15 0 0"/><geometry><mesh filename="package://quirks_robot/meshes/knob.obj"/></geometry></visual>
  </link>
  <joint name="sensor_mount" type="fixed">
    <parent link="arm"/><child link="sensor"/>
    <origin xyz="0.2 0 0"/>
  </joint>
  <!-- a massless link with a collision geom: stays massless -->
  <link name="sensor">
    <collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision>
  </link>
  <joint name="left_slide" type="prismatic">
    <parent link="arm"/><child link="left"/>
    <origin xyz="0.2 0.03 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="0" upper="0.02" effort="10" velocity="0.1"/>
  </joint>
  <link name="left">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <visual><geometry><mesh filename="package://quirks_robot/meshes/fin.stl" scale="0.5 0.5 0.5"/></geometry></visual>
  </link>
  <joint name="right_slide" type="prismatic">
    <parent link="arm"/><child link="right"/>
    <origin xyz="0.2 -0.03 0"/>
    <axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.02" effort="10" velocity="0.1"/>
    <mimic joint="left_slide" multiplier="1" offset="0"/>
  </joint>
  <link name="right">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <!-- the left finger's mesh, mirrored -->
    <visual><geometry><mesh filename="package://quirks_robot/meshes/fin.stl" scale="0.5 -0.5 0.5"/></geometry></visual>
    <collision><geometry><mesh filename="package://quirks_robot/meshes/fin.stl" scale="0.5 -0.5 0.5"/></geometry></collision>
  </link>
</robot>
"""

DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_images><image id="decal"><init_from>textures/missing_decal.png</init_from></image></library_images>
  <library_effects>
    <effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
      <diffuse><color>0.8 0.1 0.1 1</color></diffuse>
    </phong></technique></profile_COMMON></effect>
    <effect id="decal-fx"><profile_COMMON>
      <newparam sid="surf"><surface type="2D"><init_from>decal</init_from></surface></newparam>
      <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
      <technique sid="common"><phong><diffuse><texture texture="samp" texcoord="UV"/></diffuse></phong></technique>
    </profile_COMMON></effect>
  </library_effects>
  <library_materials>
    <material id="red"><instance_effect url="#red-fx"/></material>
    <material id="decal-mat"><instance_effect url="#decal-fx"/></material>
  </library_materials>
  <library_geometries>{geometries}</library_geometries>
  <library_visual_scenes><visual_scene id="scene">
    <node id="body"><instance_geometry url="#body-geom"><bind_material><technique_common>
      <instance_material symbol="m" target="#red"/></technique_common></bind_material></instance_geometry></node>
    <node id="lid"><translate>0 0 0.03</translate><instance_geometry url="#lid-geom"><bind_material><technique_common>
      <instance_material symbol="m" target="#decal-mat"/></technique_common></bind_material></instance_geometry></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""


def _geometry(name: str, mesh: trimesh.Trimesh) -> str:
    positions = " ".join(f"{v:.6g}" for v in mesh.vertices.ravel())
    uv = " ".join("0 0 1 0 1 1" for _ in range(len(mesh.faces)))
    indices = " ".join(f"{v} {3 * f + k}" for f, tri in enumerate(mesh.faces) for k, v in enumerate(tri))
    n = len(mesh.vertices)
    t = 3 * len(mesh.faces)
    return f"""
    <geometry id="{name}"><mesh>
      <source id="{name}-p"><float_array id="{name}-pa" count="{3 * n}">{positions}</float_array>
        <technique_common><accessor source="#{name}-pa" count="{n}" stride="3">
          <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
        </accessor></technique_common></source>
      <source id="{name}-t"><float_array id="{name}-ta" count="{2 * t}">{uv}</float_array>
        <technique_common><accessor source="#{name}-ta" count="{t}" stride="2">
          <param name="S" type="float"/><param name="T" type="float"/></accessor></technique_common></source>
      <vertices id="{name}-v"><input semantic="POSITION" source="#{name}-p"/></vertices>
      <triangles material="m" count="{len(mesh.faces)}">
        <input semantic="VERTEX" source="#{name}-v" offset="0"/>
        <input semantic="TEXCOORD" source="#{name}-t" offset="1" set="0"/>
        <p>{indices}</p></triangles>
    </mesh></geometry>"""


def main() -> None:
    (ROOT / "quirks_robot" / "urdf").mkdir(parents=True, exist_ok=True)
    (ROOT / "quirks_robot" / "meshes").mkdir(parents=True, exist_ok=True)
    (ROOT / "quirks_robot" / "package.xml").write_text("<package><name>quirks_robot</name></package>\n")
    (ROOT / "quirks_robot" / "urdf" / "quirks.urdf").write_text(URDF)
    body = trimesh.creation.box(extents=(0.1, 0.1, 0.04))
    lid = trimesh.creation.box(extents=(0.06, 0.06, 0.02))
    geometries = _geometry("body-geom", body) + _geometry("lid-geom", lid)
    (ROOT / "quirks_robot" / "meshes" / "painted.dae").write_text(DAE.format(geometries=geometries))
    # an asymmetric fin (a wedge leaning to +y), so the mirror image is a different shape
    fin = trimesh.Trimesh(
        vertices=np.array(
            [[0, 0, 0], [0.1, 0, 0], [0, 0.03, 0], [0, 0.005, 0.02], [0.1, 0.004, 0.01], [0, 0.03, 0.01]]
        ),
        faces=np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]]),
    )
    assert fin.is_watertight and fin.volume > 0
    (ROOT / "quirks_robot" / "meshes" / "fin.stl").write_bytes(trimesh.exchange.stl.export_stl(fin))
    (ROOT / "quirks_robot" / "meshes" / "knob.mtl").write_text("newmtl brass\nKd 0.7 0.55 0.2\n")
    knob = trimesh.creation.icosphere(subdivisions=1, radius=0.02)
    lines = ["mtllib knob.mtl", "usemtl brass"]
    lines += [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in knob.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in knob.faces]
    (ROOT / "quirks_robot" / "meshes" / "knob.obj").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
