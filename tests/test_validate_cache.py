"""The validate cache: a cached run and a fresh run agree after every change that can alter a result.

Each scenario validates a folder twice with the cache (the second run all hits), changes something that
the asset's bytes do not show, and then requires the cached run to equal a fresh run without cache.
"""

import os
import shutil

import pytest
from conftest import FIXTURES
from PIL import Image

from meshtool.validate import ValidateOptions, render, validate
from meshtool.validate import physics as plugins_module

CLEAN = FIXTURES / "validate" / "clean"
BROKEN_PNG = b"\x89PNG\r\n\x1a\n this is not an image"


def summary(report):
    return [(a.path, [(f.code, f.message, f.path, f.line) for f in a.findings]) for a in report.assets]


def warm(paths, cache):
    """Validate twice with the cache; the second run must be served from it."""
    first = validate(paths, ValidateOptions(cache_dir=cache))
    second = validate(paths, ValidateOptions(cache_dir=cache))
    assert second.checked == 0 and second.cache_hits == len(first.assets)
    assert render(second, "json") == render(first, "json")
    return first


def agree(paths, cache):
    """The cached run equals a fresh one; returns the fresh report."""
    cached = validate(paths, ValidateOptions(cache_dir=cache))
    fresh = validate(paths, ValidateOptions())
    assert summary(cached) == summary(fresh)
    assert render(cached, "json") == render(fresh, "json")
    return cached, fresh


def png(path, colour=(90, 160, 60)):
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.new("RGB", (4, 4), colour).save(path)


def box(folder, mtllib="box.mtl", mtl="newmtl box\nKd 0.8 0.8 0.8\nmap_Kd tex.png\n", mtl_at="box.mtl"):
    """The clean fixture box with its own MTL (naming ``tex.png``) at ``mtl_at``."""
    folder.mkdir(parents=True, exist_ok=True)
    text = (CLEAN / "box.obj").read_text()
    lines = [f"mtllib {mtllib}" if line.startswith("mtllib") else line for line in text.splitlines()]
    lines = [("usemtl box" if line.startswith("usemtl") else line) for line in lines]
    (folder / "box.obj").write_text("\n".join(lines) + "\n")
    (folder / mtl_at).parent.mkdir(parents=True, exist_ok=True)
    (folder / mtl_at).write_text(mtl)
    return folder / "box.obj"


def codes(report):
    return sorted({f.code for a in report.assets for f in a.findings})


def test_texture_added_beside_an_mtl_in_a_subfolder(tmp_path):
    obj = box(tmp_path / "a", mtllib="materials/box.mtl", mtl_at="materials/box.mtl")
    first = warm([obj.parent], tmp_path / "cache")
    assert "S003" in codes(first)
    png(obj.parent / "materials" / "tex.png")
    cached, _ = agree([obj.parent], tmp_path / "cache")
    assert "S003" not in codes(cached) and cached.checked == 1


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_symlink_retargeted(tmp_path):
    obj = box(tmp_path / "a")
    png(obj.parent / "good.png")
    (obj.parent / "broken.png").write_bytes(BROKEN_PNG)
    os.symlink("good.png", obj.parent / "tex.png")
    assert "S003" not in codes(warm([obj], tmp_path / "cache"))
    os.remove(obj.parent / "tex.png")
    os.symlink("broken.png", obj.parent / "tex.png")
    cached, _ = agree([obj], tmp_path / "cache")
    assert "S003" in codes(cached)


def test_exact_case_broken_texture_beside_the_upper_case_one(tmp_path):
    obj = box(tmp_path / "a")
    png(obj.parent / "TEX.PNG")
    first = warm([obj], tmp_path / "cache")
    assert codes(first) == ["S007"]  # found only ignoring case
    (obj.parent / "tex.png").write_bytes(BROKEN_PNG)  # now the exact name wins, and it is broken
    cached, _ = agree([obj], tmp_path / "cache")
    assert "S003" in codes(cached)
    assert cached.failed(strict=False)


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_texture_folder_link_retargeted(tmp_path):
    """A link to a folder (textures -> set_a) retargeted to a folder without the texture."""
    obj = box(tmp_path / "a", mtl="newmtl box\nKd 0.8 0.8 0.8\nmap_Kd textures/tex.png\n")
    png(obj.parent / "set_a" / "tex.png")
    (obj.parent / "set_b").mkdir()
    os.symlink("set_a", obj.parent / "textures")
    assert "S003" not in codes(warm([obj], tmp_path / "cache"))
    os.remove(obj.parent / "textures")
    os.symlink("set_b", obj.parent / "textures")
    cached, _ = agree([obj], tmp_path / "cache")
    assert "S003" in codes(cached)


def test_model_root_marker_appearing_above_the_folder(tmp_path):
    """A package.xml two folders up makes the package a model root: ../materials/tex.png now resolves."""
    package = tmp_path / "pkg"
    obj = box(package / "meshes" / "visual", mtl="newmtl box\nKd 0.8 0.8 0.8\nmap_Kd ../../materials/tex.png\n")
    png(package / "materials" / "tex.png")
    first = warm([obj], tmp_path / "cache")
    (package / "package.xml").write_text("<package><name>pkg</name></package>\n")
    cached, fresh = agree([obj], tmp_path / "cache")
    assert summary(fresh) != summary(first) and cached.checked == 1


def test_physics_plugin_removed(tmp_path, monkeypatch):
    """Uninstalling the physics plugin (or changing its version) is a change of every result."""
    obj = box(tmp_path / "a")
    png(obj.parent / "tex.png")
    first = warm([obj], tmp_path / "cache")
    assert "physics" in first.assets[0].stats
    import meshtool.plugins

    monkeypatch.setattr(meshtool.plugins, "entry_points", lambda **kw: [])  # the plugin's and the environment's lookup
    plugins_module.physics_plugin.cache_clear()
    try:
        cached, _ = agree([obj], tmp_path / "cache")
        assert "physics" not in cached.assets[0].stats and cached.checked == 1
        assert any("no physics plugin" in n for n in cached.assets[0].notes)
    finally:
        plugins_module.physics_plugin.cache_clear()


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_pack_source_link_retargeted(tmp_path):
    """K003 follows the source beside the pack: a link to it retargeted to a changed copy makes it stale."""
    folder = tmp_path / "p"
    folder.mkdir()
    shutil.copy(CLEAN / "box.mbin", folder / "box.mbin")
    (folder / "v1").mkdir()
    for name in ("box.obj", "box.mtl", "box.png"):
        shutil.copy(CLEAN / name, folder / "v1" / name)
    shutil.copytree(folder / "v1", folder / "v2")
    with open(folder / "v2" / "box.obj", "a") as handle:
        handle.write("# edited\n")
    for name in ("box.obj", "box.mtl", "box.png"):
        os.symlink(f"v1/{name}", folder / name)
    assert codes(warm([folder / "box.mbin"], tmp_path / "cache")) == []
    os.remove(folder / "box.obj")
    os.symlink("v2/box.obj", folder / "box.obj")
    cached, _ = agree([folder / "box.mbin"], tmp_path / "cache")
    assert codes(cached) == ["K003"]


def test_a_cache_inside_the_asset_folder_still_hits(tmp_path):
    obj = box(tmp_path / "a")
    png(obj.parent / "tex.png")
    warm([obj.parent], obj.parent / ".cache")  # the cache's own files do not count as a change


def test_unrelated_files_above_do_not_invalidate(tmp_path):
    obj = box(tmp_path / "a")
    png(obj.parent / "tex.png")
    warm([obj], tmp_path / "cache")
    (tmp_path / "notes.txt").write_text("unrelated")  # not a marker or a description file
    assert validate([obj], ValidateOptions(cache_dir=tmp_path / "cache")).cache_hits == 1
