"""PackMeta (meshtool/stages.py): the typed META, which files a pack read, whether it is still current.

Ground truth: the META section's JSON decoded with the standard library from the file's own bytes (not through
PackMeta), the fixture folders' files on disk, and files changed on disk by the test.
"""

import json
import shutil
import struct
import zlib
from pathlib import Path

import pytest

from meshtool.packfile import PackMeta, parse
from meshtool.pipeline import ConvertOptions, is_current, pack_file, source_states

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
#: (fixture folder, mesh file, the files on disk it is made from besides itself)
CASES = [
    ("multi_material", "crate.obj", {"crate.mtl", "checker.tga", "wood grain.jpg"}),
    ("formats/gltf/external", "cube.gltf", None),  # buffers and images: whatever the folder holds
    ("formats/gltf", "embedded_texture.glb", set()),  # images inside the GLB are not files of their own
]


def _meta_json(data: bytes) -> dict:
    """META decoded from the bytes as docs/mbin-spec.md lays them out (64-byte header and table entries)."""
    count, table = struct.unpack_from("<II", data, 16)
    for k in range(count):
        at = table + 64 * k
        kind = data[at : at + 4]
        offset, length = struct.unpack_from("<QQ", data, at + 24)
        if kind == b"META":
            stored = data[offset : offset + length]
            try:
                return json.loads(zlib.decompress(stored))
            except zlib.error:
                return json.loads(zlib.decompress(stored, -15))
    raise AssertionError("no META section")


def _copy(tmp_path: Path, folder: str) -> Path:
    target = tmp_path / "asset"
    shutil.copytree(FIXTURES / folder, target)
    return target


@pytest.mark.parametrize(("folder", "mesh", "others"), CASES, ids=[c[1] for c in CASES])
def test_pack_meta_reads_what_the_file_stores(tmp_path, folder, mesh, others):
    src = _copy(tmp_path, folder) / mesh
    made = pack_file(src, ConvertOptions(check=False))
    stored = _meta_json(made.data)
    with parse(made.data, mesh) as packed:
        meta = packed.pack_meta
    assert dict(meta.raw) == stored
    assert meta.textures == tuple(stored["textures"])
    assert meta.parts == tuple(stored["parts"])
    assert meta.stats == stored["stats"]
    assert meta.transform == stored["transform"]
    assert meta.tool_version == stored["tool"]["version"]
    assert [s.path for s in meta.sources] == [s["path"] for s in stored["sources"]]
    assert meta.options == ConvertOptions(check=False).fingerprint()


@pytest.mark.parametrize(("folder", "mesh", "others"), CASES, ids=[c[1] for c in CASES])
def test_the_files_a_pack_read_are_the_files_on_disk(tmp_path, folder, mesh, others):
    root = _copy(tmp_path, folder)
    src = root / mesh
    made = pack_file(src, ConvertOptions(check=False))
    with parse(made.data, mesh) as packed:
        files = packed.pack_meta.source_files([src.parent])
    assert files[0] == src
    assert all(p.is_file() for p in files)
    names = {p.relative_to(root).as_posix() for p in files[1:]}
    if others is not None:
        assert names == others
    else:  # the external glTF: its buffer and every image in the folder it names
        assert "cube.bin" in names and all((root / n).is_file() for n in names)
    assert sorted(made.inputs) == sorted(files)  # obj2bin's inputs (the mesh included) are the same answer


def test_a_pack_stops_being_current_when_a_texture_changes(tmp_path):
    root = _copy(tmp_path, "multi_material")
    src = root / "crate.obj"
    options = ConvertOptions(check=False)
    with parse(pack_file(src, options).data, src.name) as packed:
        meta = packed.pack_meta
    assert is_current(meta, src, options)
    assert all(now == entry.sha256 for entry, _, now in source_states(meta, [src.parent]))
    (root / "checker.tga").write_bytes((root / "checker.tga").read_bytes() + b"\0")
    assert not is_current(meta, src, options)
    changed = [entry.path for entry, _, now in source_states(meta, [src.parent]) if now != entry.sha256]
    assert changed == ["checker.tga"]
    (root / "crate.mtl").unlink()
    missing = [entry.path for entry, _, now in source_states(meta, [src.parent]) if now is None]
    assert missing == ["crate.mtl"]
    assert not is_current(meta, src, ConvertOptions(check=False, quantize=True))


@pytest.mark.parametrize(
    "raw",
    [{}, {"sources": "x"}, {"sources": [1, {"path": 3}], "options": []}, {"textures": {"a": 1}, "hull_parts": "ab"}],
)
def test_a_foreign_meta_reads_as_empty_fields_and_is_never_current(tmp_path, raw):
    meta = PackMeta(raw)
    assert meta.sources == () and meta.textures == () and meta.hull_parts == ()
    assert meta.source_files([tmp_path]) == []
    assert not is_current(raw, tmp_path / "a.obj", ConvertOptions())
