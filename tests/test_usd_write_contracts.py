"""The USD writer (``meshtool/export/usd_write.py``) in-process, each method read back by usd-core (``pxr``).

Ground truth: the stage as ``pxr`` opens it from the bytes the builder returns (attribute values,
interpolations, connections, time samples, the transforms ``UsdGeom.XformCache`` composes), the
UsdPreviewSurface specification (openusd.org, "UsdPreviewSurface Specification": ``normal`` input, a
tangent-space normal map read with ``sourceColorSpace = raw`` and mapped by ``scale (2, 2, 2, 1)`` and
``bias (-1, -1, -1, 0)``; ``UsdPrimvarReader_float2`` with a string ``varname``) and the UsdPhysics schema
(gravity as direction and magnitude).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from meshtool.export.usd_write import UsdBuilder, prim_name
from meshtool.files.outdir import GENERATOR

pxr = pytest.importorskip("pxr")
from pxr import Sdf, Usd, UsdGeom, UsdPhysics, UsdShade  # noqa: E402

TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=float)
TETRA_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _open(tmp_path: Path, data: bytes, name: str = "s.usda") -> Any:
    path = tmp_path / "read" / name
    path.parent.mkdir(exist_ok=True)
    path.write_bytes(data)
    return Usd.Stage.Open(str(path))


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("   ", "fb"),
        ("9", "_9"),
        ("a  b", "a_b"),
        ("__a__", "a"),
        ("a.-b", "a_b"),
        ("_", "fb"),
        ("é9", "_9"),
        ("Xbox X", "Xbox_X"),
    ],
)
def test_prim_names_follow_usd_s_identifier_rule(name: str, expected: str) -> None:
    assert prim_name(name, "fb") == expected
    assert Sdf.Path.IsValidIdentifier(expected)


def test_the_stage_is_z_up_in_metres_with_its_root_as_default_prim_and_the_stamp(tmp_path: Path) -> None:
    with UsdBuilder(tmp_path / "A.USDA", "my robot", generator="simrun 9") as usd:
        assert usd.root == "/my_robot" and usd.out == tmp_path / "A.USDA"
        data = usd.finish()
    assert data.startswith(b"#usda 1.0")  # the suffix is read case-blind
    stage = _open(tmp_path, data)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert str(root.GetPath()) == "/my_robot" and root.IsA(UsdGeom.Xform)
    assert dict(stage.GetRootLayer().customLayerData) == {"generator": "simrun 9"}
    with UsdBuilder(tmp_path / "b.usdc", "r") as usd:
        crate = usd.finish()
    assert crate.startswith(b"PXR-USDC")
    crate_stage = _open(tmp_path, crate, "b.usdc")  # held: the layer lives as long as its stage
    assert crate_stage.GetRootLayer().customLayerData["generator"] == GENERATOR


def test_a_wrong_suffix_names_the_file_and_a_root_without_a_usable_name_is_root(tmp_path: Path) -> None:
    from meshtool.errors import OutputError

    out = tmp_path / "scene.glb"
    with pytest.raises(OutputError) as refused:
        UsdBuilder(out, "s")
    assert refused.value.path == str(out) and refused.value.one_line().startswith(f"{out}: USD output must end in")
    with UsdBuilder(tmp_path / "s.usda", " !! ") as usd:
        assert usd.root == "/root"
        stage = _open(tmp_path, usd.finish())
    assert str(stage.GetDefaultPrim().GetPath()) == "/root"


def test_leaving_the_builder_removes_its_scratch_folder(tmp_path: Path) -> None:
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        scratch = Path(usd._tmp.name)
        assert scratch.is_dir()
    assert not scratch.exists() and list(tmp_path.iterdir()) == []


def test_child_and_group_claim_unique_names_per_parent(tmp_path: Path) -> None:
    with UsdBuilder(tmp_path / "s.usda", "root") as usd:
        assert usd.child("", "root") == "/root_2"
        assert [usd.child(usd.root, "a b") for _ in range(3)] == ["/root/a_b", "/root/a_b_2", "/root/a_b_3"]
        assert usd.child(usd.root, "!!") == "/root/prim" and usd.child(usd.root, "", "thing") == "/root/thing"
        assert usd.child("/root/a_b", "a b") == "/root/a_b/a_b"
        geom = usd.group(usd.root, "Geom")
        assert geom == "/root/Geom" and usd.group(usd.root, "Geom") == geom
        assert usd.child(usd.root, "Geom") == "/root/Geom_2"
        assert usd.group("/root/Geom", "Geom") == "/root/Geom/Geom"
        stage = _open(tmp_path, usd.finish())
    assert stage.GetPrimAtPath("/root/Geom").IsA(UsdGeom.Scope)
    assert stage.GetPrimAtPath("/root/Geom/Geom").IsA(UsdGeom.Scope)


def test_a_mesh_holds_its_points_faces_normals_uvs_and_extent(tmp_path: Path) -> None:
    normals = TETRA / np.maximum(np.linalg.norm(TETRA, axis=1, keepdims=True), 1.0)
    uvs = TETRA[:, :2] / 2.0
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        full = usd.mesh("/s/full", TETRA.ravel(), TETRA_FACES.ravel(), normals, uvs)
        assert isinstance(full, UsdGeom.Mesh)
        usd.mesh("/s/bare", TETRA + 1.0, TETRA_FACES)
        usd.mesh("/s/empty", np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
        stage = _open(tmp_path, usd.finish())
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/s/full"))
    np.testing.assert_array_equal(np.array(mesh.GetPointsAttr().Get()), TETRA)
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3, 3, 3, 3]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == TETRA_FACES.ravel().tolist()
    assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    np.testing.assert_allclose(np.array(mesh.GetNormalsAttr().Get()), normals, rtol=1e-6)
    assert mesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray and st.GetInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(np.array(st.Get()), uvs)
    assert [tuple(v) for v in mesh.GetExtentAttr().Get()] == [(0, 0, 0), (1, 2, 3)]
    bare = UsdGeom.Mesh(stage.GetPrimAtPath("/s/bare"))
    assert [tuple(v) for v in bare.GetExtentAttr().Get()] == [(1, 1, 1), (2, 3, 4)]
    assert not bare.GetNormalsAttr().HasAuthoredValue() and not UsdGeom.PrimvarsAPI(bare).HasPrimvar("st")
    empty = UsdGeom.Mesh(stage.GetPrimAtPath("/s/empty"))
    assert not empty.GetExtentAttr().HasAuthoredValue() and list(empty.GetFaceVertexCountsAttr().Get()) == []


def test_a_mesh_of_five_vertices_keeps_one_normal_and_one_uv_per_vertex(tmp_path: Path) -> None:
    pyramid = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    normals = (pyramid - [0.5, 0.5, 0.4]) / np.linalg.norm(pyramid - [0.5, 0.5, 0.4], axis=1, keepdims=True)
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        usd.mesh("/s/pyramid", pyramid, faces, normals, pyramid[:, :2])
        stage = _open(tmp_path, usd.finish())
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/s/pyramid"))
    assert len(mesh.GetPointsAttr().Get()) == 5 and list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * 6
    np.testing.assert_allclose(np.array(mesh.GetNormalsAttr().Get()), normals, rtol=1e-6)
    np.testing.assert_allclose(np.array(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st").Get()), pyramid[:, :2])


def test_colour_purpose_and_colliders(tmp_path: Path) -> None:
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        seen = usd.mesh("/s/seen", TETRA, TETRA_FACES)
        usd.display_colour(seen, [0.25, 0.5, 0.75, 1.0])
        usd.purpose(seen, guide=False)
        usd.collider(seen, convex_hull=False)
        hull = usd.mesh("/s/hull", TETRA, TETRA_FACES)
        usd.purpose(hull, guide=True)
        usd.collider(hull, convex_hull=True)
        stage = _open(tmp_path, usd.finish())
    seen_prim, hull_prim = stage.GetPrimAtPath("/s/seen"), stage.GetPrimAtPath("/s/hull")
    assert [tuple(c) for c in UsdGeom.Gprim(seen_prim).GetDisplayColorAttr().Get()] == [(0.25, 0.5, 0.75)]
    assert UsdGeom.Imageable(seen_prim).GetPurposeAttr().Get() == UsdGeom.Tokens.render
    assert UsdGeom.Imageable(hull_prim).GetPurposeAttr().Get() == UsdGeom.Tokens.guide
    assert seen_prim.HasAPI(UsdPhysics.CollisionAPI) and not seen_prim.HasAPI(UsdPhysics.MeshCollisionAPI)
    assert hull_prim.HasAPI(UsdPhysics.CollisionAPI) and hull_prim.HasAPI(UsdPhysics.MeshCollisionAPI)
    approximation = UsdPhysics.MeshCollisionAPI(hull_prim).GetApproximationAttr().Get()
    assert approximation == UsdPhysics.Tokens.convexHull


@pytest.mark.parametrize(
    ("gravity", "direction", "magnitude"),
    [((0, 0, -9.81), (0, 0, -1), 9.81), ((0, 0.3, -0.4), (0, 0.6, -0.8), 0.5), ((0, 0, 0), None, 0)],
)
def test_the_physics_scene_holds_gravity_as_direction_and_magnitude(
    tmp_path: Path, gravity: tuple[float, ...], direction: tuple[float, ...] | None, magnitude: float
) -> None:
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        usd.physics_scene(gravity)
        stage = _open(tmp_path, usd.finish())
    scene = UsdPhysics.Scene(stage.GetPrimAtPath("/PhysicsScene"))
    assert scene and scene.GetGravityMagnitudeAttr().Get() == pytest.approx(magnitude)
    authored = scene.GetGravityDirectionAttr()
    if direction is None:
        assert not authored.HasAuthoredValue()  # the schema's fallback (0, 0, 0) means "down the up axis"
    else:
        assert tuple(authored.Get()) == pytest.approx(direction)


def test_poses_and_their_time_samples_compose_as_usd_reads_them(tmp_path: Path) -> None:
    half = np.sqrt(0.5)
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        body = usd.xform("/s/body")
        assert isinstance(body, UsdGeom.Xform)
        usd.place(body, [1.0, 2.0, 3.0], [half, 0.0, 0.0, half])  # 90 degrees about +Z
        usd.sample_pose(body, 0.0, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
        usd.sample_pose(body, 10.0, [2.0, 0.0, 0.0], [half, 0.0, 0.0, half])
        usd.timeline(25.0, 0.0, 10.0)
        stage = _open(tmp_path, usd.finish())
    assert (stage.GetTimeCodesPerSecond(), stage.GetFramesPerSecond()) == (25.0, 25.0)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 10.0)
    prim = stage.GetPrimAtPath("/s/body")
    ops = UsdGeom.Xformable(prim).GetOrderedXformOps()
    assert [op.GetOpType() for op in ops] == [UsdGeom.XformOp.TypeTranslate, UsdGeom.XformOp.TypeOrient]
    assert [op.GetPrecision() for op in ops] == [UsdGeom.XformOp.PrecisionDouble] * 2
    assert ops[0].Get() == (1.0, 2.0, 3.0)  # the default value, besides the samples
    assert ops[0].GetTimeSamples() == [0.0, 10.0] and ops[1].GetTimeSamples() == [0.0, 10.0]

    def local(code: float) -> np.ndarray:
        return np.asarray(UsdGeom.XformCache(Usd.TimeCode(code)).GetLocalToWorldTransform(prim))

    # USD matrices act on row vectors: row 3 is the translation, row 0 where +X goes
    np.testing.assert_allclose(local(0.0), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(local(10.0)[3, :3], [2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(local(10.0)[0, :3], [0.0, 1.0, 0.0], atol=1e-12)
    mid = local(5.0)  # linear translation, spherical orientation: 45 degrees
    np.testing.assert_allclose(mid[3, :3], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(mid[0, :3], [half, half, 0.0], atol=1e-9)


def _input_source(shader: Any, name: str) -> tuple[str, str]:
    (source,) = shader.GetInput(name).GetConnectedSources()[0]
    return str(source.source.GetPath()), str(source.sourceName)


def test_a_textured_material_is_a_preview_surface_as_its_specification_asks(tmp_path: Path) -> None:
    with UsdBuilder(tmp_path / "s.usda", "s") as usd:
        material = usd.material("/s/M", (0.5, 0.25, 1.0), 0.75, 0.4, "c.png", "n.png", 0.5)
        plain = usd.material("/s/P", (1.0, 0.0, 0.0), 1.0, 0.9)
        only_normal = usd.material("/s/N", (1.0, 1.0, 1.0), 1.0, 1.0, normal_map="n.png")
        mesh = usd.mesh("/s/mesh", TETRA, TETRA_FACES, uvs=TETRA[:, :2])
        usd.bind(mesh, material)
        assert isinstance(plain, UsdShade.Material) and isinstance(only_normal, UsdShade.Material)
        stage = _open(tmp_path, usd.finish())
    bound, _ = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/s/mesh")).ComputeBoundMaterial()
    assert str(bound.GetPath()) == "/s/M"
    surface = UsdShade.Shader(stage.GetPrimAtPath("/s/M/PreviewSurface"))
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    ((surface_source,), _) = bound.GetSurfaceOutput().GetConnectedSources()
    assert str(surface_source.source.GetPath()) == "/s/M/PreviewSurface"
    assert surface_source.sourceName == "surface"  # UsdPreviewSurface's one output
    assert tuple(surface.GetInput("diffuseColor").GetAttr().Get()) == (0.5, 0.25, 1.0)
    assert surface.GetInput("opacity").Get() == 0.75 and surface.GetInput("roughness").Get() == pytest.approx(0.4)
    assert _input_source(surface, "diffuseColor") == ("/s/M/DiffuseTexture", "rgb")
    assert _input_source(surface, "normal") == ("/s/M/NormalTexture", "rgb")
    reader = UsdShade.Shader(stage.GetPrimAtPath("/s/M/stReader"))
    assert reader.GetIdAttr().Get() == "UsdPrimvarReader_float2"
    assert reader.GetInput("varname").Get() == "st" and reader.GetInput("varname").GetTypeName() == "string"
    for name, file, space in (("DiffuseTexture", "c.png", "sRGB"), ("NormalTexture", "n.png", "raw")):
        image = UsdShade.Shader(stage.GetPrimAtPath(f"/s/M/{name}"))
        assert image.GetIdAttr().Get() == "UsdUVTexture"
        assert image.GetInput("file").Get().path == file and image.GetInput("sourceColorSpace").Get() == space
        assert _input_source(image, "st") == ("/s/M/stReader", "result")
        assert image.GetOutput("rgb").GetTypeName() == "float3"
    normal = UsdShade.Shader(stage.GetPrimAtPath("/s/M/NormalTexture"))
    assert tuple(normal.GetInput("scale").Get()) == (1.0, 1.0, 2.0, 1.0)  # strength 0.5
    assert tuple(normal.GetInput("bias").Get()) == (-0.5, -0.5, -1.0, 0.0)
    # plain: a colour and no textures, nothing connected
    flat = UsdShade.Shader(stage.GetPrimAtPath("/s/P/PreviewSurface"))
    assert not flat.GetInput("diffuseColor").HasConnectedSource() and not flat.GetInput("normal")
    assert not stage.GetPrimAtPath("/s/P/stReader") and not stage.GetPrimAtPath("/s/N/DiffuseTexture")
    strong = UsdShade.Shader(stage.GetPrimAtPath("/s/N/NormalTexture"))
    assert tuple(strong.GetInput("scale").Get()) == (2.0, 2.0, 2.0, 1.0)  # the specification's numbers at strength 1
    assert tuple(strong.GetInput("bias").Get()) == (-1.0, -1.0, -1.0, 0.0)
    assert not UsdShade.Shader(stage.GetPrimAtPath("/s/N/PreviewSurface")).GetInput("diffuseColor").HasConnectedSource()
