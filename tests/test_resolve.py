import os
from pathlib import Path

import pytest

from meshtool.errors import ResolveError
from meshtool.files.resolve import Resolver


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    asset = tmp_path / "asset"
    (asset / "Textures").mkdir(parents=True)
    (asset / "Textures" / "Wood.PNG").write_bytes(b"w")
    (asset / "Head 1.bmp").write_bytes(b"h")
    (asset / "sub").mkdir()
    (asset / "sub" / "a.mtl").write_bytes(b"m")
    (tmp_path / "outside.png").write_bytes(b"secret")
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "common.png").write_bytes(b"c")
    return asset


@pytest.mark.parametrize(
    ("ref", "expected", "rule"),
    [
        ("Head 1.bmp", "Head 1.bmp", "exact"),
        ("Textures/Wood.PNG", "Textures/Wood.PNG", "exact"),
        ("Textures\\Wood.PNG", "Textures/Wood.PNG", "backslash"),
        ("textures/wood.png", "Textures/Wood.PNG", "case-insensitive"),
        ("TEXTURES\\WOOD.png", "Textures/Wood.PNG", "case-insensitive"),
        (r"C:\Users\sama-sama\Desktop\Head 1\Head 1.bmp", "Head 1.bmp", "trailing-components"),
        (r"\\fileserver\share\models\Textures\Wood.PNG", "Textures/Wood.PNG", "trailing-components"),
        ("file:///home/designer/asset/Head%201.bmp", "Head 1.bmp", "trailing-components"),
        ("model://robot/Textures/wood.png", "Textures/Wood.PNG", "trailing-components"),
        ("/etc/Head 1.bmp", "Head 1.bmp", "trailing-components"),
        ("elsewhere/Head 1.bmp", "Head 1.bmp", "basename"),
        ('"Head 1.bmp"', "Head 1.bmp", "exact"),
        ("sub/../Head 1.bmp", "Head 1.bmp", "exact"),
    ],
)
def test_rules(tree, ref, expected, rule):
    r = Resolver(tree)
    res = r.resolve(ref, tree, "texture", "x.mtl", 3)
    assert res.found == (tree / expected).resolve()
    assert res.rule == rule
    assert r.display(res.found) == expected
    if rule == "exact":
        assert res.findings == []
    else:
        (f,) = res.findings
        assert (f.code, f.path, f.line) == ("texture-reference-repaired", "x.mtl", 3)


def test_basename_beside_the_obj_when_referenced_from_a_subfolder(tree):
    res = Resolver(tree).resolve("missing/dir/head 1.BMP", tree / "sub", "texture", "sub/a.mtl", 1)
    assert res.found == (tree / "Head 1.bmp").resolve()
    assert res.rule == "basename"


@pytest.mark.parametrize("ref", ["../outside.png", "../../../../../../etc/passwd", "/etc/hostname"])
def test_never_leaves_the_root(tree, ref):
    res = Resolver(tree).resolve(ref, tree, "mtl", "x.obj", 1)
    assert res.found is None
    codes = [f.code for f in res.findings]
    assert codes[-1] == "mtl-missing"
    if ref.startswith(".."):
        assert codes[0] == "reference-outside-root"


def test_symlink_out_of_the_root_is_refused(tree):
    os.symlink(tree.parent / "outside.png", tree / "link.png")
    res = Resolver(tree).resolve("link.png", tree, "texture", "x.mtl", 1)
    assert res.found is None
    assert [f.code for f in res.findings] == ["reference-outside-root", "texture-missing"]
    with pytest.raises(ResolveError):
        Resolver(tree).read(tree / "link.png")


def test_search_path_allows_a_folder(tree):
    shared = tree.parent / "shared"
    assert Resolver(tree).resolve("../shared/common.png", tree, "texture", "x", 1).found is None
    res = Resolver(tree, [shared]).resolve("../shared/common.png", tree, "texture", "x", 1)
    assert res.found == (shared / "common.png").resolve()
    assert res.rule == "exact"
    res = Resolver(tree, [shared]).resolve("C:\\tex\\COMMON.png", tree, "texture", "x", 1)
    assert res.rule == "search-path"
    assert Resolver(tree, [shared]).display(res.found) == "<search-path 1>/common.png"


def test_read_source_errors(tree):
    with pytest.raises(ResolveError, match="does not exist"):
        Resolver(tree).read_source(tree / "nope.obj")
    with pytest.raises(ResolveError, match="is a folder"):
        Resolver(tree).read_source(tree / "sub")
