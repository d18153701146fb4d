"""The project's one USD writer (:mod:`meshtool.export.usd_write`), read back by usd-core's own tools.

Ground truth: the stage as ``pxr`` opens it (its metadata, prim types, points and extents), usd-core's
validators (0 errors), and the file bytes of two builds of the same calls.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from meshtool.errors import OutputError
from meshtool.export.usd_write import UsdBuilder, prim_name

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom, UsdPhysics, UsdShade, UsdValidation  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=float)
TETRA_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("head", "head"),
        ("3d head", "_3d_head"),
        ("robot/base_link", "robot_base_link"),
        ("a-b", "a_b"),
        ("mat.001", "mat_001"),
        ("  ..  ", "fallback"),
        ("Größe", "Gr_e"),
        ("_3d", "_3d"),
    ],
)
def test_prim_name_is_valid_and_idempotent(name: str, expected: str) -> None:
    got = prim_name(name, "fallback")
    assert got == expected
    assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", got)
    assert prim_name(got, "fallback") == got


def _build(out: Path) -> bytes:
    with UsdBuilder(out, "3d asset") as usd:
        geom = usd.group(usd.root, "Geom")
        assert usd.group(usd.root, "Geom") == geom  # one scope, however often it is asked for
        first = usd.mesh(usd.child(geom, "part-1"), TETRA, TETRA_FACES, uvs=TETRA[:, :2])
        second = usd.mesh(usd.child(geom, "part_1"), TETRA + 5.0, TETRA_FACES)
        usd.place(second, [0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])
        usd.collider(second, convex_hull=True)
        usd.purpose(second, guide=True)
        material = usd.material(usd.child(usd.group(usd.root, "Materials"), "red"), (1.0, 0.0, 0.0), 1.0, 0.5)
        usd.bind(first, material)
        usd.physics_scene([0.0, 0.0, -9.81])
        return usd.finish()


@pytest.mark.parametrize("suffix", [".usda", ".usdc", ".usd"])
def test_same_calls_give_the_same_bytes_and_a_valid_stage(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"a{suffix}"
    data = _build(out)
    assert data == _build(tmp_path / f"b{suffix}")
    assert data.startswith(b"#usda 1.0" if suffix == ".usda" else b"PXR-USDC")
    out.write_bytes(data)
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert str(stage.GetDefaultPrim().GetPath()) == "/_3d_asset"
    assert stage.GetRootLayer().customLayerData["generator"].startswith("meshtool ")
    paths = [str(p.GetPath()) for p in stage.Traverse()]
    assert "/_3d_asset/Geom/part_1" in paths and "/_3d_asset/Geom/part_1_2" in paths  # one rule, clashes numbered
    assert stage.GetPrimAtPath("/_3d_asset/Geom").IsA(UsdGeom.Scope)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/_3d_asset/Geom/part_1"))
    np.testing.assert_array_equal(np.array(mesh.GetPointsAttr().Get()), TETRA)
    assert [tuple(v) for v in mesh.GetExtentAttr().Get()] == [(0, 0, 0), (1, 2, 3)]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == TETRA_FACES.ravel().tolist()
    material, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
    assert str(material.GetPath()) == "/_3d_asset/Materials/red"
    hull = stage.GetPrimAtPath("/_3d_asset/Geom/part_1_2")
    assert hull.HasAPI(UsdPhysics.CollisionAPI) and hull.HasAPI(UsdPhysics.MeshCollisionAPI)
    assert UsdGeom.Imageable(hull).GetPurposeAttr().Get() == UsdGeom.Tokens.guide
    world = np.asarray(UsdGeom.XformCache().GetLocalToWorldTransform(hull))
    np.testing.assert_allclose(world[3, :3], [0.5, 0.0, 0.0])
    found = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators()).Validate(stage)
    assert [e.GetMessage() for e in found if e.GetType() == UsdValidation.ValidationErrorType.Error] == []


def test_a_wrong_suffix_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=r"USD output must end in \.usda, \.usdc or \.usd"):
        UsdBuilder(tmp_path / "scene.obj", "x")
    assert list(tmp_path.iterdir()) == []


def test_save_writes_atomically_and_leaves_no_scratch(tmp_path: Path) -> None:
    out = tmp_path / "s.usda"
    usd = UsdBuilder(out, "s")
    scratch = Path(usd._tmp.name)
    usd.mesh(usd.child(usd.root, "m"), TETRA, TETRA_FACES)
    usd.save()
    assert out.read_text().startswith("#usda 1.0") and not scratch.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["s.usda"]


def test_only_the_writer_creates_usd_stages() -> None:
    """One USD writer: no other module of either package creates a stage or sets its frame itself."""
    creators = re.compile(r"Usd\.Stage\.Create(New|InMemory)|SetStageUpAxis|SetStageMetersPerUnit")
    found = sorted(
        str(path.relative_to(ROOT))
        for package in ("meshtool", "simrun")
        for path in (ROOT / package).rglob("*.py")
        if creators.search(path.read_text(encoding="utf-8"))
    )
    assert found == ["meshtool/export/usd_write.py"]
