"""The CLI on every mesh format: obj2bin on a folder of all five, normalize, validate."""

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin
from meshtool.packfile import load

MIXED = Path("formats") / "mixed"


def run(cmd, *args):
    return CliRunner().invoke(cmd, [str(a) for a in args], catch_exceptions=False)


def test_obj2bin_folder_of_five_formats_writes_one_valid_mbin_each(fixtures, tmp_path):
    out = tmp_path / "packs"
    result = run(obj2bin, fixtures / MIXED, "-o", out)
    assert result.exit_code == 0, result.output
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*.mbin"))
    assert written == ["box.mbin", "bracket.mbin", "crate.mbin", "link/link_cm_zup.mbin", "scan.mbin"]
    expected = {  # triangles, textures, source role
        "box.mbin": (12, 0, "obj"),
        "bracket.mbin": (12, 0, "stl"),
        "crate.mbin": (12, 1, "glb"),
        "link/link_cm_zup.mbin": (12, 1, "collada"),
        "scan.mbin": (12, 0, "ply"),
    }
    for rel, (triangles, textures, role) in expected.items():
        with load(out / rel, verify=True) as packed:  # checksums and structure verified
            assert packed.indices.shape == (triangles, 3), rel
            assert len(packed.textures) == textures, rel
            assert packed.meta["sources"][0]["role"] == role, rel
            assert np.isfinite(packed.positions).all()
    with load(out / "link" / "link_cm_zup.mbin") as packed:  # COLLADA cm, Z-up: metres, not rotated
        extent = np.asarray(packed.positions).max(axis=0) - np.asarray(packed.positions).min(axis=0)
        np.testing.assert_allclose(extent, [0.2, 0.1, 0.05], rtol=1e-6)
    again = run(obj2bin, fixtures / MIXED, "-o", out)  # nothing changed: every pack is up to date
    assert again.exit_code == 0 and "0 written, 5 unchanged" in again.output


def test_same_stem_in_two_formats_gets_two_packs(fixtures, tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "part.stl").write_bytes((fixtures / MIXED / "bracket.stl").read_bytes())
    (src / "part.ply").write_bytes((fixtures / MIXED / "scan.ply").read_bytes())
    result = run(obj2bin, src, "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").glob("*.mbin")) == ["part.mbin", "part_stl.mbin"]


def test_normalize_json_names_the_format(fixtures, tmp_path):
    result = run(main, "normalize", fixtures / MIXED / "link" / "link_cm_zup.dae", "-o", tmp_path, "--json")
    assert result.exit_code == 0, result.output
    manifest = json.loads((tmp_path / "link_cm_zup" / "asset.json").read_text())
    assert manifest["sources"][0]["role"] == "collada"
    assert manifest["transform"]["units"] == "cm" and manifest["transform"]["up_rule"] == "format"
    assert sorted(manifest["files"]["textures"]) == ["paint.png"]


def test_validate_reads_every_format(fixtures):
    result = run(main, "validate", fixtures / "formats" / "validate", "--format", "json")
    report = json.loads(result.stdout)
    found = {Path(a["path"]).name: sorted({f["rule"] for f in a["findings"]}) for a in report["assets"]}
    assert found == {"flipped.stl": ["S012"], "model.gltf": ["S013"]}
    assert result.exit_code == 1  # S013 is an error
