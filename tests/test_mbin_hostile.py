"""Hostile ``.mbin`` files with VALID checksums: every command refuses them with one ``error:`` line, exit 1.

The generator below tampers with a real file written by ``obj2bin`` and then recomputes every checksum
(section CRC-32s and the table CRC), as an attacker would, so only the content checks of the reader
(docs/mbin-spec.md section 5.3) stand between the file and the consumers. The assembler here is written
from the spec, independently of meshtool's writer.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import xxhash
from click.testing import CliRunner

from meshtool.errors import PackFormatError
from meshtool.hulls.compute import HullOptions
from meshtool.packfile import parse
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import NormaliseOptions

HEADER = struct.Struct("<8sHHIIIQI28s")
ENTRY = struct.Struct("<4sBBH2QQQII16s")
ITEM = {0: 1, 1: 1, 2: 2, 3: 4, 4: 2, 5: 4}


def read_sections(data: bytes) -> tuple[list[list], int]:
    """The table entries (as mutable lists) with their data, and the header flags."""
    flags, count = HEADER.unpack_from(data, 0)[3:5]
    entries = []
    for k in range(count):
        kind, dtype, ndim, index, rows, cols, offset, size, _crc, encoding, _ = ENTRY.unpack_from(data, 64 + 64 * k)
        entries.append([kind, dtype, ndim, index, rows, cols, encoding, bytearray(data[offset : offset + size])])
    return entries, flags


def checksum(blob: bytes, minor: int) -> int:
    """Spec section 3: CRC-32 in 1.0 files, the low 32 bits of XXH3-64 from 1.1 on."""
    return zlib.crc32(blob) if minor == 0 else xxhash.xxh3_64_intdigest(bytes(blob)) & 0xFFFFFFFF


def assemble(entries: list[list], flags: int, minor: int = 0) -> bytes:
    """Header, table and 64-byte aligned data with every checksum recomputed (spec sections 2 and 3).

    The attacks are written as format 1.0 files (CRC-32): every reader must still read 1.0.
    """
    start = -(-(64 + 64 * len(entries)) // 64) * 64
    table, chunks, at = b"", b"", start
    for kind, dtype, ndim, index, rows, cols, encoding, blob in entries:
        crc = checksum(blob, minor)
        table += ENTRY.pack(kind, dtype, ndim, index, rows, cols, at, len(blob), crc, encoding, b"")
        padded = bytes(blob) + b"\0" * (-len(blob) % 64)
        chunks += padded
        at += len(padded)
    head = HEADER.pack(b"\x89MBN\r\n\x1a\n", 1, minor, flags, len(entries), 64, at, 0, b"")
    head = head[:32] + struct.pack("<I", checksum(head[:32] + table, minor)) + head[36:]
    return head + table + b"\0" * (start - 64 - len(table)) + chunks


def entry(entries: list[list], kind: bytes, index: int = 0) -> list:
    return next(e for e in entries if e[0] == kind and e[3] == index)


def json_of(e: list) -> object:
    blob = bytes(e[7])
    return json.loads(zlib.decompress(blob) if e[6] == 3 else blob)


def set_json(e: list, text: str) -> None:
    """Store ``text`` plain (encoding 0), shape (bytes,)."""
    blob = text.encode("utf-8")
    e[4], e[5], e[6], e[7] = len(blob), 0, 0, bytearray(blob)


def set_array(e: list, element: int, value: bytes) -> None:
    """Overwrite element ``element`` (flat) of a plain array section with the raw ``value`` bytes."""
    size = ITEM[e[1]]
    e[7][element * size : (element + 1) * size] = value


# ------------------------------------------------------------------------------------------------ attacks


def edit_meta(change):
    def attack(entries, flags):
        e = entry(entries, b"META")
        meta = json_of(e)
        change(meta)
        set_json(e, json.dumps(meta))
        return entries, flags

    return attack


def edit_matl(change):
    def attack(entries, flags):
        e = entry(entries, b"MATL")
        materials = json_of(e)
        change(materials)
        set_json(e, json.dumps(materials))
        return entries, flags

    return attack


def edit_meta_text(old, new):
    def attack(entries, flags):
        e = entry(entries, b"META")
        text = json.dumps(json_of(e))
        assert old in text
        set_json(e, text.replace(old, new, 1))
        return entries, flags

    return attack


def meta_text(text):
    def attack(entries, flags):
        e = entry(entries, b"META")
        blob = text.encode("utf-8", "surrogateescape")
        e[4], e[5], e[6], e[7] = len(blob), 0, 0, bytearray(blob)
        return entries, flags

    return attack


def poke(kind, element, value):
    def attack(entries, flags):
        set_array(entry(entries, kind), element, value)
        return entries, flags

    return attack


def u32(v):
    return struct.pack("<I", v)


def f32(v):
    return struct.pack("<f", v)


def hull_row(change):
    def attack(entries, flags):
        e = entry(entries, b"HULT")
        rows = np.frombuffer(bytes(e[7]), "<u4").reshape(-1, 4).copy()
        change(rows)
        e[7] = bytearray(rows.tobytes())
        return entries, flags

    return attack


def set_flags(value):
    return lambda entries, flags: (entries, value)


def replace_texture(blob):
    def attack(entries, flags):
        entry(entries, b"TEX ")[7] = bytearray(blob)
        entry(entries, b"TEX ")[4] = len(blob)
        return entries, flags

    return attack


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose IHDR declares ``width`` x ``height`` grey pixels, with one tiny IDAT (not decodable in full).

    The 30000 x 30000 texture bomb of the verifier: an 879 KB ``.mbin`` whose PNG decodes to 900 MB. The
    reader must refuse it from the header (bytes 16..24), before any decoding.
    """

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(1000))) + chunk(b"IEND", b"")
    )


def set_quant(array, key, value):
    def change(meta):
        meta["quantization"][array][key] = value

    return edit_meta(change)


def drop_quant(meta):
    meta["quantization"] = None


# (id, base file, attack, words the error must contain)
ATTACKS = [
    ("hull-face-4e6", "lossless", poke(b"HULF", 5, u32(4_000_000)), "names vertex 4000000"),
    ("hull-face-beyond-own-hull", "lossless", poke(b"HULF", 0, u32(9)), "hull 0 names vertex 9"),
    ("hull-past-arrays", "lossless", hull_row(lambda r: r.__setitem__((0, 0), 10**6)), "do not tile"),
    ("hull-overlap", "lossless", hull_row(lambda r: r.__setitem__((1, 2), 0)), "do not tile"),
    ("hull-too-small", "lossless", hull_row(lambda r: (r.__setitem__((0, 1), 3), r.__setitem__((1, 0), 3))), ""),
    ("hull-vertex-inf", "lossless", poke(b"HULV", 4, f32(float("inf"))), "value 4 is inf"),
    ("position-inf", "lossless", poke(b"POS ", 7, f32(float("-inf"))), "value 7 is -inf"),
    ("position-nan", "lossless", poke(b"POS ", 0, f32(float("nan"))), "value 0 is nan"),
    ("normal-nan", "normals", poke(b"NRM ", 2, f32(float("nan"))), "'NRM '"),
    ("uv-inf", "lossless", poke(b"UV  ", 1, f32(float("inf"))), "'UV  '"),
    ("index-beyond", "lossless", poke(b"IDX ", 3, struct.pack("<H", 65000)), "an index is 65000"),
    ("submesh-material", "lossless", poke(b"SUBM", 2, u32(99)), "names material 99"),
    ("submesh-part", "lossless", poke(b"SUBM", 3, u32(70000)), "names part 70000"),
    ("submesh-empty", "lossless", poke(b"SUBM", 1, u32(0)), "do not tile"),
    ("material-texture-index", "lossless", edit_matl(lambda m: m[1]["maps"]["map_Kd"].update(texture=7)), "texture"),
    ("material-texture-type", "lossless", edit_matl(lambda m: m[1]["maps"]["map_Kd"].update(texture="0")), "texture"),
    ("material-colour-string", "lossless", edit_matl(lambda m: m[0]["colors"].update(Kd="red")), "colors.Kd"),
    ("material-colour-short", "lossless", edit_matl(lambda m: m[0]["colors"].update(Kd=[1, 0])), "colors.Kd"),
    ("material-scalar-string", "lossless", edit_matl(lambda m: m[0]["scalars"].update(d="x")), "scalars.d"),
    ("material-not-object", "lossless", edit_matl(lambda m: m.append(3)), "material 3"),
    ("material-no-name", "lossless", edit_matl(lambda m: m[0].pop("name")), "material 0.name"),
    ("material-colours-list", "lossless", edit_matl(lambda m: m[0].update(colors=[1])), "colors"),
    ("material-illum-string", "lossless", edit_matl(lambda m: m[0].update(illum="2")), "illum"),
    ("meta-textures-count", "lossless", edit_meta(lambda m: m["textures"].pop()), "META.textures"),
    ("meta-textures-type", "lossless", edit_meta(lambda m: m.update(textures=5)), "META.textures"),
    ("meta-texture-traversal", "lossless", edit_meta(lambda m: m["textures"].__setitem__(0, "../../x.png")), ""),
    ("meta-texture-duplicate", "lossless", edit_meta(lambda m: m["textures"].__setitem__(1, m["textures"][0])), ""),
    ("meta-parts-missing", "lossless", edit_meta(lambda m: m.pop("parts")), "part"),
    ("meta-parts-type", "lossless", edit_meta(lambda m: m.update(parts=[1, 2, 3])), "META.parts"),
    ("meta-tool-string", "lossless", edit_meta(lambda m: m.update(tool="meshtool")), "META.tool"),
    ("meta-transform-list", "lossless", edit_meta(lambda m: m.update(transform=[1])), "META.transform"),
    ("meta-sources-path", "lossless", edit_meta(lambda m: m["sources"][0].update(path=3)), "sources[0].path"),
    ("meta-hull-quality", "lossless", edit_meta(lambda m: m["hull_quality"].update(volume_ratio="big")), ""),
    ("meta-hull-quality-type", "lossless", edit_meta(lambda m: m.update(hull_quality=[])), "hull_quality"),
    ("meta-hull-parts", "lossless", edit_meta(lambda m: m["hull_parts"].__setitem__(0, 99)), "hull_parts"),
    ("meta-quantization-list", "quantized", edit_meta(lambda m: m.update(quantization=[])), "quantization"),
    ("meta-quantization-missing", "quantized", edit_meta(drop_quant), "quantization.positions"),
    ("meta-quantization-string", "quantized", set_quant("positions", "lo", ["a", 0, 0]), "lo"),
    ("meta-quantization-huge", "quantized", set_quant("positions", "hi", [1e300, 1e300, 1e300]), "'POS '"),
    ("meta-quantization-reversed", "quantized", set_quant("uvs", "lo", [5.0, 5.0]), "hi below lo"),
    ("meta-nan-literal", "lossless", edit_meta_text('"area_m2": ', '"area_m2": NaN, "x": '), "non-finite"),
    ("meta-overflow-literal", "lossless", edit_meta_text('"area_m2": ', '"area_m2": 1e999, "x": '), "float range"),
    ("meta-huge-integer", "lossless", edit_meta_text('"area_m2": ', '"area_m2": ' + "9" * 5000 + ', "x": '), ""),
    ("meta-not-object", "lossless", meta_text("[]"), "JSON dict"),
    ("meta-not-utf8", "lossless", meta_text("\udcff"), "UTF-8"),
    ("texture-not-png", "lossless", replace_texture(b"GIF89a" + bytes(60)), "not a PNG"),
    ("texture-30000px", "lossless", replace_texture(png_claiming(30000, 30000)), "30000x30000 pixels is over"),
    ("texture-wide", "lossless", replace_texture(png_claiming(16385, 1)), "16385x1 pixels is over"),
    ("texture-2^27", "lossless", replace_texture(png_claiming(16384, 8193)), "16384x8193 pixels is over"),
    ("material-colour-range", "lossless", edit_matl(lambda m: m[0]["colors"].update(Kd=[1e308, -5, 1e-320])), "0..1"),
    ("material-colour-above-1", "lossless", edit_matl(lambda m: m[1]["colors"].update(Ke=[1, 1, 1.5])), "colors.Ke"),
    ("flags-mismatch", "lossless", set_flags(1), "quantised flag"),
    ("flags-unknown", "lossless", set_flags(0x80), "unknown header flags"),
]


@pytest.fixture(scope="module")
def bases(tmp_path_factory):
    """Real files from obj2bin: textured crate (3 materials, 2 textures, a hull per part), quantised, normals."""
    fixtures = Path(__file__).resolve().parent.parent / "fixtures"
    out = tmp_path_factory.mktemp("bases")
    hulls = HullOptions(mode="objects", cache_dir=None)
    made = {}
    for name, src, quantize in (
        ("lossless", fixtures / "multi_material" / "crate.obj", False),
        ("quantized", fixtures / "multi_material" / "crate.obj", True),
        ("normals", fixtures / "features" / "features.obj", False),
    ):
        options = ConvertOptions(
            NormaliseOptions(), quantize, hulls if name != "normals" else HullOptions(cache_dir=None)
        )
        convert(src, out / f"{name}.mbin", options)
        made[name] = (out / f"{name}.mbin").read_bytes()
    return made


def hostile(bases, base, attack) -> bytes:
    entries, flags = read_sections(bases[base])
    entries, flags = attack(entries, flags)
    return assemble(entries, flags)


def test_the_generator_reproduces_the_base_files(bases):
    """Reassembling an untouched file gives the same bytes: the attacks change only what they say."""
    for data in bases.values():
        assert assemble(*read_sections(data), minor=data[10]) == data
        parse(data)


def test_bases_have_what_the_attacks_need(bases):
    with_hulls = parse(bases["lossless"])
    assert len(with_hulls.hulls) >= 2 and len(with_hulls.textures) == 2 and len(with_hulls.materials) == 3
    assert with_hulls.meta["hull_quality"] and with_hulls.meta["hull_parts"]
    assert parse(bases["normals"]).normals is not None
    assert parse(bases["quantized"]).quantized


@pytest.mark.parametrize(("case", "base", "attack", "words"), ATTACKS, ids=[a[0] for a in ATTACKS])
def test_hostile_file_is_refused_with_an_offset(bases, case, base, attack, words):
    data = hostile(bases, base, attack)
    with pytest.raises(PackFormatError) as info:
        parse(data, f"{case}.mbin")
    assert words in info.value.message
    assert info.value.offset is not None and 0 <= info.value.offset < len(data)


@pytest.mark.parametrize(("case", "base", "attack", "words"), ATTACKS, ids=[a[0] for a in ATTACKS])
def test_every_command_exits_1_with_one_error_line(bases, tmp_path, case, base, attack, words):
    from meshtool.cli.main import main

    path = tmp_path / f"{case}.mbin"
    path.write_bytes(hostile(bases, base, attack))
    runner = CliRunner()
    commands = [
        ["info", path],
        ["info", "--json", path],
        ["unpack", path, "-o", tmp_path / "unpacked"],
        ["export", path, "--glb", tmp_path / "x.glb", "--msh", tmp_path / "x.msh"],
        ["export", path, "--usd", tmp_path / "x.usda"],
        ["mjcf", path, "-o", tmp_path / "mjcf"],
    ]
    for args in commands:
        result = runner.invoke(main, [str(a) for a in args], catch_exceptions=False)
        assert result.exit_code == 1, (args, result.output)
        lines = result.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ") and str(path) in lines[0], (args, lines)
        assert "Traceback" not in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # nothing written


@pytest.mark.parametrize(("case", "base", "attack", "words"), ATTACKS, ids=[a[0] for a in ATTACKS])
def test_simrun_refuses_a_hostile_asset(bases, tmp_path, case, base, attack, words):
    """simrun loads .mbin assets through meshtool.load (verify=True): `simrun check` exits 1, one line."""
    from simrun.cli.main import main as simrun_main

    (tmp_path / "bad.mbin").write_bytes(hostile(bases, base, attack))
    (tmp_path / "scene.toml").write_text(
        '[assets]\nbad = "bad.mbin"\n\n[[entities]]\ntype = "MeshEntity"\nname = "bad"\nasset = "bad"\n'
    )
    result = CliRunner().invoke(simrun_main, ["check", str(tmp_path / "scene.toml")], catch_exceptions=False)
    assert result.exit_code == 1, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "bad.mbin" in lines[0], lines
    assert "Traceback" not in result.output


def test_a_texture_with_a_png_signature_that_does_not_decode_is_an_input_error(bases, tmp_path):
    """The reader checks the signature only; `export --glb` reports the undecodable image with exit 1."""
    from meshtool.cli.main import main

    path = tmp_path / "bad_png.mbin"
    path.write_bytes(hostile(bases, "lossless", replace_texture(b"\x89PNG\r\n\x1a\n" + bytes(64))))
    parse(path.read_bytes())  # sound container
    result = CliRunner().invoke(main, ["export", str(path), "--glb", str(tmp_path / "x.glb")])
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith(f"error: {path}: a texture cannot be decoded") and "Traceback" not in result.output
    assert not (tmp_path / "x.glb").exists()


def test_texture_within_the_limits_passes_and_the_bomb_offset_is_the_ihdr(bases, tmp_path):
    """16384 x 8192 (2^27 pixels) is the largest accepted; the refusal points at the IHDR width."""
    parse(hostile(bases, "lossless", replace_texture(png_claiming(16384, 8192))))
    data = hostile(bases, "lossless", replace_texture(png_claiming(30000, 30000)))
    with pytest.raises(PackFormatError) as info:
        parse(data, "bomb.mbin")
    assert data[info.value.offset : info.value.offset + 8] == struct.pack(">II", 30000, 30000)


def test_validate_reports_a_texture_bomb_as_a_corrupt_pack(bases, tmp_path):
    from meshtool.cli.main import main

    (tmp_path / "bomb.mbin").write_bytes(hostile(bases, "lossless", replace_texture(png_claiming(30000, 30000))))
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "bomb.mbin"), "--format", "json", "--no-cache"])
    assert result.exit_code == 1, result.output
    (asset,) = json.loads(result.stdout)["assets"]
    assert [f["rule"] for f in asset["findings"]] == ["K001"]
    assert "over the texture limit" in asset["findings"][0]["message"]
