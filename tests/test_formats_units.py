"""The formats registry, the recognisers and the typed pack view, called in process with exact expectations.

tests/test_formats_registry.py checks the registry against the code that uses it (real writers, real
readers); this file pins each function's own answers (names, suffixes, messages, edge cases), so a change to
one of them is seen (mutation testing of meshtool/formats.py, recognise.py and packfile/view.py).
"""

from __future__ import annotations

import dataclasses
import json
import os
import struct
from pathlib import Path

import numpy as np
import pytest

from meshtool import formats
from meshtool.files import recognise
from meshtool.formats import MeshFormat
from meshtool.packfile import load
from meshtool.packfile.view import DEFAULT_COLOUR, asset_view, unique_name, unique_names

ROOT = Path(__file__).resolve().parent.parent
HEAD = ROOT / "fixtures" / "scenes" / "head.mbin"


# -- formats -------------------------------------------------------------------------------------------------


def test_mesh_suffixes_and_labels() -> None:
    assert formats.mesh_suffixes() == (".obj", ".stl", ".ply", ".gltf", ".glb", ".dae")
    assert formats.mesh_labels() == "OBJ, STL, PLY, glTF, GLB, COLLADA"


@pytest.mark.parametrize(
    ("name", "expected", "placed"),
    [("a.obj", "obj", "z"), ("A.STL", "stl", "z"), ("m.Ply", "ply", "z"), ("s.gltf", "gltf", "y"),
     ("s.GLB", "glb", "y"), ("c.dae", "collada", "z")],
)  # fmt: skip
def test_mesh_format_by_suffix_and_how_a_urdf_places_it(name: str, expected: str, placed: str) -> None:
    row = formats.mesh_format(name)
    assert row is not None and row.name == expected and formats.mesh_format(Path(name)) is row
    assert row.placed_up() == placed and formats.mesh_format_named(expected) is row
    assert callable(row.read())


def test_unknown_names_and_suffixes() -> None:
    assert formats.mesh_format("x.off") is None and formats.mesh_format("noext") is None
    assert formats.output_for("x.txt") is None and formats.output_for("x") is None
    with pytest.raises(KeyError):
        formats.mesh_format_named("off")
    with pytest.raises(KeyError):
        formats.output_named("txt")


def test_fallbacks_of_the_rows() -> None:
    rows = {row.name: row for row in formats.MESH_FORMATS}
    assert (rows["stl"].fallback_up, rows["stl"].suggested_unit) == ("z", "mm")
    assert rows["obj"].text and not any(rows[n].text for n in ("stl", "ply", "gltf", "glb", "collada"))
    assert rows["ply"].fallback_reason == "PLY defines no up axis; Y-up assumed, as for OBJ"
    assert {n for n, r in rows.items() if r.up == "spec"} == {"gltf", "glb"}
    assert rows["collada"].up == "declared" and rows["collada"].units == "declared"


@pytest.mark.parametrize(
    ("name", "suffix"),
    [("mbin", ".mbin"), ("usd", ".usd"), ("html", ".html"), ("mjcf", ".xml"), ("glb", ".glb"), ("simlog", ".simlog")],
)
def test_default_suffix(name: str, suffix: str) -> None:
    assert formats.suffix(name) == suffix


def test_output_rows_by_suffix() -> None:
    assert formats.output_for("page.HTM") is formats.output_named("html")
    assert formats.output_for(Path("a.usdc")) is formats.output_named("usd")
    assert formats.output_for("m.xml") is formats.output_named("mjcf")


@pytest.mark.parametrize(
    ("path", "name", "message"),
    [
        ("x.usdz", "usd", "USD output must end in .usda, .usdc or .usd"),
        ("x.gltf", "glb", "GLB output must end in .glb"),
        ("x.mjcf", "mjcf", "MJCF output must end in .xml"),
        ("x.txt", "html", "HTML output must end in .html or .htm"),
    ],
)
def test_check_suffix_says_what_fits(path: str, name: str, message: str) -> None:
    assert formats.check_suffix(Path(path), name) == message
    ok = formats.output_named(name).suffixes[-1].upper()
    assert formats.check_suffix(Path("x" + ok), name) is None


def test_register_refuses_a_taken_name_or_suffix_and_always_unregisters() -> None:
    def row(name: str, suffixes: tuple[str, ...]) -> MeshFormat:
        return MeshFormat(name, name.upper(), suffixes, "x:read", "evidence", "y", "why", "evidence")

    for taken in (row("stl", (".xyz",)), row("xyz", (".stl",)), row("xyz", (".abc", ".obj"))):
        with pytest.raises(ValueError, match="registered already"), formats.register_mesh_format(taken):
            pass  # pragma: no cover
    before = list(formats.MESH_FORMATS)
    with pytest.raises(RuntimeError), formats.register_mesh_format(row("xyz", (".xyz",))) as added:
        assert formats.mesh_format("a.xyz") is added and formats.mesh_suffixes()[-1] == ".xyz"
        raise RuntimeError
    assert before == formats.MESH_FORMATS


def test_magic_rows_recognise_by_their_prefix(tmp_path: Path) -> None:
    gif = formats.output_named("gif")
    assert gif.magic == (b"GIF87a", b"GIF89a") and not gif.marked and gif.recognise == ""
    for data, expected in ((b"GIF89a....", True), (b"GIF87a", True), (b"GIF8", False), (b"", False)):
        target = tmp_path / "a.gif"
        target.write_bytes(data)
        assert gif.recogniser()(target, len(data)) is expected


# -- recognise -----------------------------------------------------------------------------------------------


def test_read_head(tmp_path: Path) -> None:
    target = tmp_path / "f"
    target.write_bytes(b"0123456789" * 300_000)  # 3 MB: more than one read
    assert recognise.read_head(target, 5) == b"01234"
    assert recognise.read_head(target, 2_500_001)[-3:] == b"890"  # type: ignore[index]
    assert len(recognise.read_head(target, 10**8) or b"") == 3_000_000
    assert recognise.read_head(target, 0) == b""
    assert recognise.read_head(tmp_path / "missing", 4) is None
    assert recognise.read_head(tmp_path, 4) is None  # a folder
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert recognise.read_head(fifo, 4) is None  # never blocks on a pipe
    link = tmp_path / "link"
    link.symlink_to(target)
    assert recognise.read_head(link, 4) is None  # never follows a link


def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    target = tmp_path / name
    target.write_bytes(data)
    return target


@pytest.mark.parametrize(
    ("data", "expected"),
    [(b"# meshtool 0.1 normalized OBJ\nv 0 0 0\n", True), (b"# simrun (meshtool 0.1): mesh\n", True),
     (b"# Blender v3\n", False), (b"v 0 0 0\n# meshtool\n", False), (b"", False)],
)  # fmt: skip
def test_is_obj(tmp_path: Path, data: bytes, expected: bool) -> None:
    assert recognise.is_obj(_write(tmp_path, "m.obj", data), len(data)) is expected


@pytest.mark.parametrize(
    ("data", "expected"),
    [(b"<mujoco model='m'/>", True), (b"\xef\xbb\xbf  <?xml version='1.0'?>\n<!-- a -->\n<mujoco/>", True),
     (b"<?xml version='1.0'?><robot/>", False), (b"<!-- never closed <mujoco/>", False), (b"<?xml <mujoco/>", False),
     (b"", False)],
)  # fmt: skip
def test_is_mjcf(tmp_path: Path, data: bytes, expected: bool) -> None:
    assert recognise.is_mjcf(_write(tmp_path, "m.xml", data), len(data)) is expected


def test_is_mp4_and_marks(tmp_path: Path) -> None:
    assert recognise.is_mp4(_write(tmp_path, "a.mp4", b"\0\0\0\x20ftypisom"), 12)
    assert not recognise.is_mp4(_write(tmp_path, "b.mp4", b"\0\0\0\x20moov"), 8)
    page = b'<!doctype html><meta name="generator" content="simrun (meshtool 0.1)">'
    assert recognise.is_html(_write(tmp_path, "a.html", page), len(page))
    assert not recognise.is_html(_write(tmp_path, "b.html", b"<!doctype html>" + b" " * 600 + page), 700)
    tree = json.dumps({"asset": {"generator": "meshtool 0.1", "version": "2.0"}}).encode()
    assert recognise.is_gltf(_write(tmp_path, "a.gltf", tree), len(tree))
    other = json.dumps({"asset": {"generator": "Blender", "version": "2.0"}}).encode()
    assert not recognise.is_gltf(_write(tmp_path, "b.gltf", other), len(other))


def _msh(nv: int, nn: int, nt: int, nf: int, extra: int = 0) -> bytes:
    return struct.pack("<4i", nv, nn, nt, nf) + b"\0" * (4 * (3 * nv + 3 * nn + 2 * nt + 3 * nf) + extra)


@pytest.mark.parametrize(
    ("data", "expected"),
    [(_msh(4, 0, 0, 2), True), (_msh(4, 4, 4, 2), True), (_msh(4, 0, 0, 2, extra=4), False),
     (_msh(0, 0, 0, 0), False), (struct.pack("<4i", 4, -1, 0, 2) + b"\0" * 60, False), (b"\0" * 15, False)],
)  # fmt: skip
def test_is_msh(tmp_path: Path, data: bytes, expected: bool) -> None:
    assert recognise.is_msh(_write(tmp_path, "m.msh", data), len(data)) is expected


def _glb(tree: object, version: int = 2, chunk: int = 0x4E4F534A, length: int | None = None) -> bytes:
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    size = len(text) if length is None else length
    return struct.pack("<4sII", b"glTF", version, 20 + len(text)) + struct.pack("<II", size, chunk) + text


@pytest.mark.parametrize(
    ("data", "expected"),
    [(_glb({"asset": {"generator": "meshtool 0.1"}}), True), (_glb({"asset": {"generator": "simrun (x)"}}), True),
     (_glb({"asset": {"generator": "trimesh"}}), False), (_glb({"asset": {}}), False), (_glb([1]), False),
     (_glb({"asset": {"generator": 3}}), False), (_glb({"asset": {"generator": "meshtool"}}, version=1), False),
     (_glb({"asset": {"generator": "meshtool"}}, chunk=0), False),
     (_glb({"asset": {"generator": "meshtool"}}, length=10**6), False), (b"glTF\2\0\0\0", False)],
)  # fmt: skip
def test_is_glb(tmp_path: Path, data: bytes, expected: bool) -> None:
    assert recognise.is_glb(_write(tmp_path, "m.glb", data), len(data)) is expected


def test_is_usd_needs_the_generator(tmp_path: Path) -> None:
    plain = b'#usda 1.0\n(\n    defaultPrim = "a"\n)\ndef Xform "a" {}\n'
    assert not recognise.is_usd(_write(tmp_path, "a.usda", plain), len(plain))
    stamped = b'#usda 1.0\n(\n    customLayerData = {\n        string generator = "meshtool 0.1"\n    }\n)\n'
    assert recognise.is_usd(_write(tmp_path, "b.usda", stamped), len(stamped))
    other = stamped.replace(b"meshtool 0.1", b"Blender")
    assert not recognise.is_usd(_write(tmp_path, "c.usda", other), len(other))
    assert not recognise.is_usd(_write(tmp_path, "d.usda", b"#usda broken ((("), 16)
    assert not recognise.is_usd(_write(tmp_path, "e.usd", b"PXR-USDC garbage"), 16)


def test_is_mbin(tmp_path: Path) -> None:
    data = HEAD.read_bytes()
    assert recognise.is_mbin(_write(tmp_path, "a.mbin", data), len(data))
    assert not recognise.is_mbin(_write(tmp_path, "b.mbin", data[:40]), 40)
    assert not recognise.is_mbin(_write(tmp_path, "c.mbin", b"MBIN" + b"\0" * 60), 64)


# -- the typed view ------------------------------------------------------------------------------------------


def test_unique_names_suffix_the_repeats() -> None:
    assert unique_names(["a", "b", "a", "a", "a_2"]) == ["a", "b", "a_2", "a_3", "a_2_2"]
    assert unique_names([]) == []
    assert unique_name("a", {"a", "a_2"}) == "a_3" and unique_name("b", {"a"}) == "b"


def test_view_of_a_pack() -> None:
    with load(HEAD) as packed:
        view = asset_view(packed)
        positions = np.asarray(packed.positions, np.float64)
        indices = np.asarray(packed.indices, np.int64)
        (first, count, material, _), *_ = np.asarray(packed.submeshes).tolist()
        assert (view.up, view.unit) == ("z", "m") and np.array_equal(view.positions, positions)
        assert np.array_equal(view.indices, indices)
        (part,) = view.parts
        assert (part.index, part.material) == (0, material)
        assert np.all(np.diff(part.vertices) > 0) and np.array_equal(part.positions, positions[part.vertices])
        assert np.array_equal(part.vertices[part.faces], indices[first : first + count])
        assert part.normals is None and np.array_equal(part.uvs, np.asarray(packed.uvs, np.float64)[part.vertices])
        (texture,) = view.textures
        assert (texture.file, texture.stem, texture.data[:4]) == ("head_1.png", "head_1", b"\x89PNG")
        (mat,) = view.materials
        assert mat.name == "Head_Material" and mat.colour_map == 0 and mat.normal_map is None
        assert mat.rgba == (1.0, 1.0, 1.0, mat.alpha) and mat.normal_scale == 1.0
        assert mat.diffuse == tuple(float(c) for c in packed.materials[0]["colors"]["Kd"][:3])
        assert len(view.hulls) == len(packed.hulls) and view.hulls[0][0].dtype == np.float64


def test_view_defaults_without_colours_uvs_or_recorded_names() -> None:
    with load(HEAD) as packed:
        bare = dataclasses.replace(
            packed,
            uvs=None,
            normals=np.asarray(packed.positions, np.float32),
            materials=[{"maps": packed.materials[0]["maps"], "scalars": {"d": 0.5}}],
            meta={**packed.meta, "textures": []},
        )
        view = asset_view(bare)
        (mat,) = view.materials
        assert mat.name == "material_0" and mat.diffuse == DEFAULT_COLOUR and mat.alpha == 0.5
        assert mat.colour_map is None and mat.rgba == (*DEFAULT_COLOUR, 0.5)  # no uvs: no map to draw
        assert view.textures[0].file == "tex0.png" and view.parts[0].uvs is None
        assert np.array_equal(view.parts[0].normals, np.asarray(packed.positions, np.float64)[view.parts[0].vertices])
        none = asset_view(dataclasses.replace(packed, materials=[]))
        assert none.materials == [] and none.parts[0].material == -1
