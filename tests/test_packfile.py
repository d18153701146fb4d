import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from meshtool.errors import PackFormatError
from meshtool.packfile import format as fmt
from meshtool.packfile import pack, parse
from meshtool.packfile.encode import oct_decode, oct_encode
from meshtool.read.obj.mtl import Material, TextureMap
from meshtool.repair.mesh import TriMesh
from meshtool.repair.normalise import NormalisedAsset, NormaliseOptions, prepare

coord = st.floats(-100, 100, allow_nan=False, width=32)


def tiny_png(seed):
    """A real 2x2 PNG (the reader checks the PNG's chunks), different per seed."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.new("RGB", (2, 2), (seed % 256, 40, 80)).save(buffer, format="PNG")
    return buffer.getvalue()


def make_asset(positions, faces, uvs=None, normals=None, colors=None, materials=1, textures=0, parts=1):
    m = faces.shape[0]
    face_material = np.sort(np.arange(m) % materials) if m else np.zeros(0, dtype=np.int64)
    face_part = (np.arange(m) % parts) if m else np.zeros(0, dtype=np.int64)
    order = np.lexsort((face_part, face_material))
    names = [f"tex{k}.png" for k in range(textures)]
    mats = [
        Material(
            f"m{k}",
            0,
            {"Kd": (0.1 * k, 0.5, 1.0)},
            {"Ns": 10.0},
            2,
            {"map_Kd": TextureMap(names[k % textures], {"-s": ("2.0",)}, 0)} if textures else {},
        )
        for k in range(materials)
    ]
    mesh = TriMesh(
        positions=positions,
        colors=colors,
        texcoords=uvs if uvs is not None else np.zeros((0, 2)),
        normals=normals if normals is not None else np.zeros((0, 3)),
        faces=faces[order],
        face_uv=faces[order] if uvs is not None else np.full((m, 3), -1),
        face_normal=faces[order] if normals is not None else np.full((m, 3), -1),
        face_material=face_material[order],
        face_part=face_part[order],
        face_lines=np.zeros(m, dtype=np.int64),
        material_names=[m.name for m in mats],
        part_names=[f"p{k}" for k in range(parts)],
        source_polygons=m,
        degenerate=0,
    )
    png = {n: tiny_png(k) for k, n in enumerate(names)}
    manifest = {"name": "t", "sources": [], "stats": {}, "findings": []}
    return NormalisedAsset("t", dict(png), manifest, [], mesh, mats, png)


@st.composite
def assets(draw):
    n = draw(st.integers(3, 40))
    positions = draw(arrays(np.float64, (n, 3), elements=coord))
    m = draw(st.integers(1, 30))
    faces = draw(arrays(np.int64, (m, 3), elements=st.integers(0, n - 1)))
    uvs = draw(st.one_of(st.none(), arrays(np.float64, (n, 2), elements=st.floats(-2, 2, width=32))))
    normals = None
    if draw(st.booleans()):
        raw = draw(arrays(np.float64, (n, 3), elements=st.floats(-1, 1, width=32)))
        raw[np.linalg.norm(raw, axis=1) < 1e-3] = [0, 0, 1]
        normals = raw / np.linalg.norm(raw, axis=1, keepdims=True)
    colors = draw(st.one_of(st.none(), arrays(np.float64, (n, 3), elements=st.floats(0, 1))))
    materials = draw(st.integers(1, 4))
    textures = draw(st.integers(0, 3))
    parts = draw(st.integers(1, 3))
    return make_asset(positions, faces, uvs, normals, colors, materials, textures, parts)


def corners(mesh_positions, indices):
    return np.asarray(mesh_positions)[np.asarray(indices, dtype=np.int64)]


@settings(max_examples=120, deadline=None)
@given(assets())
def test_lossless_round_trip(asset):
    data = pack(asset)
    assert pack(asset) == data  # deterministic
    p = parse(data)
    src = asset.mesh
    # every triangle corner keeps its position, uv, normal and colour exactly (as float32 / u8)
    np.testing.assert_array_equal(corners(p.positions, p.indices), src.positions[src.faces].astype(np.float32))
    if src.texcoords.size:
        np.testing.assert_array_equal(corners(p.uvs, p.indices), src.texcoords[src.face_uv].astype(np.float32))
    else:
        assert p.uvs is None
    if src.normals.size:
        np.testing.assert_array_equal(corners(p.normals, p.indices), src.normals[src.face_normal].astype(np.float32))
    else:
        assert p.normals is None
    if src.colors is not None:
        expected = np.rint(src.colors[src.faces] * 255).astype(np.uint8)
        np.testing.assert_array_equal(corners(p.colors, p.indices)[..., :3], expected)
    assert p.indices.dtype == np.uint16
    # submeshes tile the triangles, one run per (material, part)
    sub = p.submeshes.astype(np.int64)
    assert sub[0, 0] == 0 and (sub[1:, 0] == (sub[:-1, 0] + sub[:-1, 1])).all() and sub[:, 1].sum() == len(p.indices)
    for first, count, material, part in sub.tolist():
        assert (src.face_material[first : first + count] == material).all()
        assert (src.face_part[first : first + count] == part).all()
    assert [bytes(t) for t in p.textures] == [asset.textures[n] for n in sorted(asset.textures)]
    assert [m["name"] for m in p.materials] == [m.name for m in asset.materials]
    assert p.hulls == []
    for s in p.sections:
        assert s.offset % 64 == 0 and s.crc_ok


@settings(max_examples=120, deadline=None)
@given(assets())
def test_quantized_round_trip_within_stated_bounds(asset):
    p = parse(pack(asset, quantize=True))
    src = asset.mesh
    q = p.meta["quantization"]
    err = np.abs(corners(p.positions, p.indices).astype(np.float64) - src.positions[src.faces]).max(axis=(0, 1))
    np.testing.assert_array_less(err, np.asarray(q["positions"]["max_abs_error_m"]) + 1e-12)
    span = np.ptp(src.positions, axis=0)
    np.testing.assert_array_less(err, span / 65535 * 0.5 + np.abs(src.positions).max() * 1e-6 + 1e-9)
    if src.texcoords.size:
        uv_err = np.abs(corners(p.uvs, p.indices) - src.texcoords[src.face_uv]).max(axis=(0, 1))
        np.testing.assert_array_less(uv_err, np.asarray(q["uvs"]["max_abs_error"]) + 1e-12)
    if src.normals.size:
        dots = (corners(p.normals, p.indices) * src.normals[src.face_normal]).sum(axis=2)
        angle = np.degrees(np.arccos(np.clip(dots, -1, 1))).max()
        assert angle <= q["normals"]["max_angle_error_deg"] + 1e-4
        assert angle < 0.02


def test_u32_indices_when_there_are_many_vertices():
    n = 70000
    positions = np.stack([np.arange(n), np.arange(n) % 7, np.arange(n) % 13], axis=1).astype(np.float64)
    faces = np.stack([np.arange(n - 2), np.arange(1, n - 1), np.arange(2, n)], axis=1)
    p = parse(pack(make_asset(positions, faces)))
    assert p.indices.dtype == np.uint32
    np.testing.assert_array_equal(p.indices, faces)


def test_oct_normals_are_accurate():
    rng = np.random.default_rng(3)
    v = rng.normal(size=(5000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    back = oct_decode(oct_encode(v))
    assert np.degrees(np.arccos(np.clip((v * back).sum(axis=1), -1, 1))).max() < 0.02


def test_arrays_are_read_only_views(tmp_path):
    from meshtool.packfile import load

    data = pack(
        prepare(
            __import__("pathlib").Path(__file__).parent.parent / "fixtures/head/Head 1.obj",
            NormaliseOptions(units="cm"),
        )
    )
    path = tmp_path / "h.mbin"
    path.write_bytes(data)
    with load(path) as p:
        assert not p.positions.flags.writeable and not p.indices.flags.writeable
        assert p.positions.base is not None  # a view of the map, not a copy
        with pytest.raises(ValueError):
            p.positions[0, 0] = 1.0


# ------------------------------------------------------------------------------------------------ corruption


@pytest.fixture(scope="module")
def golden_bytes():
    from pathlib import Path

    return (Path(__file__).parent.parent / "fixtures" / "golden" / "head.mbin").read_bytes()


def table_end(data):
    count = int(np.frombuffer(data, dtype=fmt.HEADER, count=1)[0]["section_count"])
    return fmt.HEADER_SIZE + count * fmt.ENTRY_SIZE


def test_every_header_and_table_byte_flip_is_caught(golden_bytes):
    for k in range(table_end(golden_bytes)):
        damaged = bytearray(golden_bytes)
        damaged[k] ^= 0x41
        with pytest.raises(PackFormatError):
            parse(bytes(damaged), verify=False)


def test_truncation_at_every_section_boundary_is_caught(golden_bytes):
    p = parse(golden_bytes)
    cuts = (
        {0, 7, 63, table_end(golden_bytes)} | {s.offset for s in p.sections} | {s.offset + s.length for s in p.sections}
    )
    for cut in sorted(c for c in cuts if c < len(golden_bytes)):
        with pytest.raises(PackFormatError) as info:
            parse(golden_bytes[:cut])
        assert info.value.offset is not None


def test_data_corruption_is_caught_by_checksums(golden_bytes):
    p = parse(golden_bytes)
    for s in p.sections:
        if s.length:
            damaged = bytearray(golden_bytes)
            damaged[s.offset + s.length // 2] ^= 0xFF
            with pytest.raises(PackFormatError, match=f"section '{s.kind}' checksum mismatch") as info:
                parse(bytes(damaged))
            assert info.value.offset == s.offset


def rewrite(data, edit):
    """Apply edit(header, table) and fix the table checksum, as a hostile writer would."""
    buf = bytearray(data)
    header = np.frombuffer(buf, dtype=fmt.HEADER, count=1).copy()
    count = int(header[0]["section_count"])
    table = np.frombuffer(buf, dtype=fmt.ENTRY, count=count, offset=64).copy()
    edit(header, table)
    raw_table = table.tobytes()
    head = header.tobytes()
    header[0]["table_crc"] = zlib.crc32(head[:32] + raw_table)
    buf[:64] = header.tobytes()
    buf[64 : 64 + len(raw_table)] = raw_table
    return bytes(buf)


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda h, t: h[0].__setitem__("major", 2), "unsupported format version 2.0"),
        (lambda h, t: t[0].__setitem__("shape", (2**62, 3)), "does not match"),
        (lambda h, t: t[0].__setitem__("length", 2**63), "does not match"),
        (lambda h, t: t[1].__setitem__("offset", t[0]["offset"]), "overlap"),
        (lambda h, t: t[0].__setitem__("offset", 2**60), "outside the data area"),
        (lambda h, t: t[0].__setitem__("offset", t[0]["offset"] + 4), "outside the data area"),
        (lambda h, t: t[0].__setitem__("dtype", 9), "dtype code 9"),
        (lambda h, t: t[2].__setitem__("kind", b"POS "), "appears 2 times"),
    ],
)
def test_hostile_tables(golden_bytes, edit, words):
    with pytest.raises(PackFormatError, match=words):
        parse(rewrite(golden_bytes, edit))


def test_huge_section_count_is_refused_before_reading(golden_bytes):
    buf = bytearray(golden_bytes)
    buf[16:20] = (2**32 - 1).to_bytes(4, "little")
    with pytest.raises(PackFormatError, match="does not fit"):
        parse(bytes(buf))


def test_out_of_range_index_with_valid_checksums(golden_bytes):
    p = parse(golden_bytes)
    idx = next(s for s in p.sections if s.kind == "IDX ")
    buf = bytearray(golden_bytes)
    buf[idx.offset : idx.offset + 2] = (60000).to_bytes(2, "little")
    fixed = rewrite(
        bytes(buf),
        lambda h, t: t[next(k for k, e in enumerate(t) if e["kind"] == b"IDX ")].__setitem__(
            "crc", zlib.crc32(bytes(buf[idx.offset : idx.offset + idx.length]))
        ),
    )
    with pytest.raises(PackFormatError, match="an index is 60000 but there are 61 vertices"):
        parse(fixed)
    assert parse(fixed, verify=False).indices[0, 0] == 60000  # without verify only bounds are checked


def test_text_mode_damage_is_named(golden_bytes):
    with pytest.raises(PackFormatError, match="text-mode transfer"):
        parse(golden_bytes.replace(b"\r\n", b"\n", 1))


def test_deflated_sections_cannot_claim_or_produce_more_than_stated(golden_bytes):
    meta_k = next(k for k, s in enumerate(parse(golden_bytes).sections) if s.kind == "META")
    with pytest.raises(PackFormatError, match="does not match"):
        parse(rewrite(golden_bytes, lambda h, t: t[meta_k].__setitem__("shape", (2**40, 0))))
    with pytest.raises(PackFormatError, match="inflates to a size other than its shape states"):
        parse(rewrite(golden_bytes, lambda h, t: t[meta_k].__setitem__("shape", (int(t[meta_k]["shape"][0]) - 1, 0))))


@pytest.mark.parametrize("golden", ["head.mbin", "crate_quantized.mbin", "features.mbin"])
@pytest.mark.parametrize("verify", [True, False])
def test_random_damage_never_escapes_as_another_error(golden, verify):
    from pathlib import Path

    data = (Path(__file__).parent.parent / "fixtures" / "golden" / golden).read_bytes()
    rng = np.random.default_rng(11)
    for _ in range(400):
        damaged = bytearray(data)
        for pos in rng.integers(0, len(data), size=rng.integers(1, 4)):
            damaged[pos] = rng.integers(0, 256)
        try:
            p = parse(bytes(damaged), verify=verify)
        except PackFormatError:
            continue
        # what still parses is usable: shapes agree and (when verified) indices are in range
        assert p.positions.shape[1] == 3 and p.indices.shape[1] == 3
        if verify:
            assert int(p.indices.max(initial=0)) < p.positions.shape[0]


def test_meshtool_load_is_the_public_entry_point():
    import meshtool
    from meshtool.packfile import load

    assert meshtool.load is load and meshtool.pack is pack


# ------------------------------------------------------------------------------------------------ writer limits


@pytest.mark.parametrize("quantize", [False, True])
@pytest.mark.parametrize("value", [4e38, -1e300, float("inf"), float("nan")])
def test_the_writer_never_stores_infinity(value, quantize):
    """Coordinates beyond float32's range (3.4028235e38) are an error before packing, not +-inf in the file."""
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, value, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 1, 3]])
    with pytest.raises(PackFormatError, match="beyond float32's range") as info:
        pack(make_asset(positions, faces), quantize)
    assert info.value.code == "non-finite"


def test_the_largest_float32_still_packs():
    big = float(np.finfo(np.float32).max)
    positions = np.array([[0.0, 0.0, 0.0], [big, 0.0, 0.0], [0.0, -big, 0.0], [0.0, 0.0, 1.0]])
    p = parse(pack(make_asset(positions, np.array([[0, 1, 2], [0, 1, 3]]))))
    assert np.isfinite(p.positions).all() and float(p.positions.max()) == big


def test_non_finite_material_numbers_are_refused_by_the_writer():
    asset = make_asset(np.eye(4, 3), np.array([[0, 1, 2], [0, 1, 3]]))
    asset.materials[0].scalars["Ns"] = float("nan")
    with pytest.raises(PackFormatError, match="non-finite number"):
        pack(asset)


def test_small_files_read_whole_load_as_mapped_ones(tmp_path, monkeypatch):
    """A file under SMALL_FILE_BYTES is read into memory, a larger one mapped: the same mesh either way."""
    from meshtool.packfile import load, read

    data = (Path(__file__).parent.parent / "fixtures" / "golden" / "head.mbin").read_bytes()
    path = tmp_path / "h.mbin"
    path.write_bytes(data)
    with load(path) as small:
        assert small._map is None  # read whole
        monkeypatch.setattr(read, "SMALL_FILE_BYTES", 0)
        with load(path) as mapped:
            assert mapped._map is not None
            for name in ("positions", "indices", "normals", "uvs", "submeshes"):
                a, b = getattr(small, name), getattr(mapped, name)
                assert (a is None) == (b is None)
                if a is not None:
                    assert a.dtype == b.dtype and np.array_equal(a, b)
            assert small.meta == mapped.meta and small.materials == mapped.materials
            assert [bytes(t) for t in small.textures] == [bytes(t) for t in mapped.textures]
    empty = tmp_path / "empty.mbin"
    empty.write_bytes(b"")
    with pytest.raises(PackFormatError, match="empty file"):
        load(empty)


def test_a_layout_seen_before_still_checks_its_content(golden_bytes):
    """The second file of a known layout reuses the section plan, never the first file's verdict."""
    from meshtool.packfile.read import forget_checks

    forget_checks()
    first = parse(golden_bytes)
    again = parse(golden_bytes)
    assert np.array_equal(first.positions, again.positions) and again.sections[0] is not first.sections[0]
    pos = next(s for s in first.sections if s.kind == "POS ")
    damaged = bytearray(golden_bytes)
    damaged[pos.offset] ^= 0x01
    with pytest.raises(PackFormatError, match="section 'POS ' checksum mismatch"):
        parse(bytes(damaged))


def _with_section_byte(data, section, at, value, fix_entry_crc):
    """``data`` with one byte of ``section`` set, its entry's checksum fixed or not, the table checksum fixed."""
    buf = bytearray(data)
    buf[section.offset + at] = value
    if not fix_entry_crc:
        return rewrite(bytes(buf), lambda h, t: None)
    k = next(i for i, s in enumerate(parse(data).sections) if s.offset == section.offset)
    crc = fmt.checksum(bytes(buf[section.offset : section.offset + section.length]), 0)
    return rewrite(bytes(buf), lambda h, t: t[k].__setitem__("crc", crc))


def test_files_of_one_layout_keep_their_own_checksums(golden_bytes):
    """The layout caches are keyed by the table without its checksums (a distinct file per entity): each file's
    table checksum and section checksums are still its own, and checked."""
    from meshtool.packfile.read import forget_checks

    forget_checks()
    first = parse(golden_bytes)
    pos = next(s for s in first.sections if s.kind == "POS ")
    other = _with_section_byte(golden_bytes, pos, 0, golden_bytes[pos.offset] ^ 0x01, fix_entry_crc=True)
    assert other[64 : table_end(other)] != golden_bytes[64 : table_end(golden_bytes)]
    second = parse(other)  # the same layout, other contents: read, with its own checksums
    assert [s.crc for s in second.sections if s.kind == "POS "] != [pos.crc]
    assert all(s.crc_ok for s in second.sections)
    assert not np.array_equal(first.raw["POS "], second.raw["POS "])
    stale = _with_section_byte(golden_bytes, pos, 0, golden_bytes[pos.offset] ^ 0x01, fix_entry_crc=False)
    with pytest.raises(PackFormatError, match="section 'POS ' checksum mismatch"):
        parse(stale)
    damaged = bytearray(other)
    damaged[64 + 40] ^= 0x10  # the first entry's checksum, the table checksum left as it was
    with pytest.raises(PackFormatError, match="section table checksum mismatch"):
        parse(bytes(damaged), verify=False)
    forget_checks()
    parse(golden_bytes)
    again = bytearray(golden_bytes)
    again[32] ^= 0x01  # the table checksum itself, of a layout seen before
    with pytest.raises(PackFormatError, match="section table checksum mismatch"):
        parse(bytes(again), verify=False)


def _json_section(text):
    from meshtool.packfile.read import Section

    data = text.encode()
    return data, Section("META", "bytes", (len(data),), 0, len(data), 0, fmt.ENC_PLAIN, 0)


@pytest.mark.parametrize(
    "literal",
    ["1e999", "-1E+309", "1e0400", "2" + "0" * 209 + "e99", "-" + "9" * 300, "1" + "0" * 400 + ".5"],
)
def test_a_json_literal_that_overflows_is_refused(literal):
    from meshtool.packfile.read import _json

    data, s = _json_section(f'{{"a": [1.5, {literal}]}}')
    if literal.lstrip("-").isdigit():  # an integer stays an integer (no float to overflow)
        assert _json(data, s, "x", dict)["a"][1] == int(literal)
        return
    with pytest.raises(PackFormatError, match="float range"):
        _json(data, s, "x", dict)


def test_the_largest_decimal_literals_that_do_not_overflow_are_read():
    from meshtool.packfile.read import _json

    for literal, value in (("1" + "0" * 209 + "e99", 1e308), ("1.7e308", 1.7e308), ("4.9e-324", 5e-324)):
        data, s = _json_section(f'{{"a": {literal}}}')
        assert _json(data, s, "x", dict) == {"a": value}


@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=8), st.integers(-400, 400))
@settings(max_examples=200, deadline=None)
def test_json_decoding_is_the_checked_decoding(values, exponent):
    """Every JSON section decodes to the value the number-by-number finiteness check gives, or is refused as
    it refuses."""
    import json

    from meshtool.packfile import verify as check
    from meshtool.packfile.read import _json

    text = json.dumps({"v": values, "e": "x", "n": 0.0}).replace('"x"', f"1.25e{exponent}")
    data, s = _json_section(text)
    try:
        expected = json.loads(text, parse_constant=check.reject_constant, parse_float=check.finite_float)
    except ValueError:
        with pytest.raises(PackFormatError):
            _json(data, s, "x", dict)
        return
    assert _json(data, s, "x", dict) == expected


def test_load_checksums_the_sections_only_when_verifying(tmp_path, golden_bytes):
    """``load(verify=False)`` reads a file whose array bytes were changed; the default verified load refuses it."""
    from meshtool.packfile import load

    positions = next(s for s in parse(golden_bytes).sections if s.kind == "POS ")
    damaged = bytearray(golden_bytes)
    damaged[positions.offset] ^= 0x01  # a float's lowest mantissa bit: still finite
    path = tmp_path / "damaged.mbin"
    path.write_bytes(bytes(damaged))
    assert load(path, verify=False).positions.shape == parse(golden_bytes).positions.shape
    with pytest.raises(PackFormatError, match="section 'POS ' checksum mismatch"):
        load(path)


def test_an_empty_file_is_named_empty(tmp_path):
    from meshtool.packfile import load

    (tmp_path / "empty.mbin").write_bytes(b"")
    with pytest.raises(PackFormatError, match=r"empty file, not an \.mbin") as caught:
        load(tmp_path / "empty.mbin")
    assert caught.value.offset == 0
    (tmp_path / "one.mbin").write_bytes(b"\x89")  # one byte: a truncated file, not an empty one
    with pytest.raises(PackFormatError, match="truncated: 1 bytes, the header alone is 64"):
        load(tmp_path / "one.mbin")
