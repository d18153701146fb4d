import pytest

from meshtool.errors import MtlParseError
from meshtool.read.obj.mtl import format_mtl, parse_map_statement, parse_mtl

FULL = """# every statement
newmtl shiny metal
Ka 0.1 0.2 0.3
Kd 0.5
Ks 1 1 1
Ke 0 0 0.5
Kt 0.9 0.9 0.9
Ns 250
Ni 1.45
Tr 0.25
illum 2
map_Ka -s 1 1 1 amb.png
map_Kd -o 0.5 0.5 -s 2 2 -clamp on -blendu off -blendv off -imfchan r -mm 0 1 -texres 512 -t 0.1 my texture.png
map_Ks "quoted spec.png"
map_Bump -bm 0.5 bump map.png
norm normal.png
disp -mm 0.1 2 disp.png
refl -type sphere sky.png
map_d -imfchan m alpha.png
decal -cc on decal.png
bump bumpmap2.jpg -bm 1.5
"""


def test_every_statement_is_parsed_as_numbers():
    (m,) = parse_mtl(FULL.encode(), "full.mtl").materials
    assert m.name == "shiny metal"
    assert m.colors == {
        "Ka": (0.1, 0.2, 0.3),
        "Kd": (0.5, 0.5, 0.5),
        "Ks": (1.0, 1.0, 1.0),
        "Ke": (0.0, 0.0, 0.5),
        "Tf": (0.9, 0.9, 0.9),
    }
    assert m.scalars == {"Ns": 250.0, "Ni": 1.45, "d": 0.75}
    assert all(isinstance(v, float) for v in m.scalars.values())
    assert m.illum == 2


def test_texture_options_and_names():
    (m,) = parse_mtl(FULL, "full.mtl").materials
    kd = m.maps["map_Kd"]
    assert kd.file == "my texture.png"
    assert kd.options == {
        "-o": ("0.5", "0.5"),
        "-s": ("2.0", "2.0"),
        "-clamp": ("on",),
        "-blendu": ("off",),
        "-blendv": ("off",),
        "-imfchan": ("r",),
        "-mm": ("0.0", "1.0"),
        "-texres": ("512.0",),
        "-t": ("0.1",),
    }
    assert kd.line == 13
    assert m.maps["map_Ks"].file == "quoted spec.png"
    assert m.maps["map_Ka"].options == {"-s": ("1.0", "1.0", "1.0")}
    # map_Bump and bump share one key; the later statement (option after the name) wins
    assert m.maps["bump"].file == "bumpmap2.jpg"
    assert m.maps["bump"].options == {"-bm": ("1.5",)}
    assert m.maps["refl"].options == {"-type": ("sphere",)}
    assert m.maps["disp"].options == {"-mm": ("0.1", "2.0")}
    assert {k: t.file for k, t in m.maps.items()} == {
        "map_Ka": "amb.png",
        "map_Kd": "my texture.png",
        "map_Ks": "quoted spec.png",
        "bump": "bumpmap2.jpg",
        "norm": "normal.png",
        "disp": "disp.png",
        "refl": "sky.png",
        "map_d": "alpha.png",
        "decal": "decal.png",
    }


@pytest.mark.parametrize(
    ("rest", "name", "options"),
    [
        (r"C:\Users\sama-sama\Desktop\Head 1\Head 1.bmp", r"C:\Users\sama-sama\Desktop\Head 1\Head 1.bmp", {}),
        ("-colorspace sRGB -o 0.1 diffuse.jpg", "diffuse.jpg", {"-colorspace": ("sRGB",), "-o": ("0.1",)}),
        ("fuze uv.jpg", "fuze uv.jpg", {}),
        ("texture -1.png", "texture -1.png", {}),
        ("-s 2", None, None),
    ],
)
def test_map_statement(rest, name, options):
    parsed = parse_map_statement(rest)
    if name is None:
        assert parsed is None
    else:
        assert parsed == (name, options)


def test_bad_statements_become_findings_and_reading_goes_on():
    data = b"Kd 1 1 1\nnewmtl a\nKd red\nNs\nillum 2.5\nmap_Kd\nsharpness 60\nnewmtl a\nKd 0 0 0\nnewmtl b\nKd 0 1 0\n"
    mtl = parse_mtl(data, "bad.mtl")
    assert [m.name for m in mtl.materials] == ["a", "b"]
    assert mtl.materials[1].colors["Kd"] == (0.0, 1.0, 0.0)
    got = sorted((f.code, f.line) for f in mtl.findings)
    assert got == [
        ("material-duplicate", 8),
        ("mtl-statement-invalid", 3),
        ("mtl-statement-invalid", 4),
        ("mtl-statement-invalid", 5),
        ("mtl-statement-invalid", 6),
        ("mtl-statement-outside-material", 1),
        ("mtl-statement-unsupported", 7),
    ]


def test_crlf_and_latin1_names():
    mtl = parse_mtl("newmtl Métal\r\nKd 1 0 0\r\nmap_Kd béton.png\r\n".encode("latin-1"), "l.mtl")
    (m,) = mtl.materials
    assert m.name == "Métal"
    assert m.maps["map_Kd"].file == "béton.png"


def test_binary_mtl_is_an_error():
    with pytest.raises(MtlParseError, match="binary data"):
        parse_mtl(b"\x00\x01\x02newmtl", "x.mtl")


def test_format_round_trips():
    mtl = parse_mtl(FULL, "full.mtl")
    text = format_mtl(mtl.materials, "header")
    again = parse_mtl(text, "again.mtl")
    assert format_mtl(again.materials, "header") == text
    assert again.materials[0].maps["map_Kd"].options == mtl.materials[0].maps["map_Kd"].options
