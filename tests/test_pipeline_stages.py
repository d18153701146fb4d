"""Following a file through meshtool enters each stage's entry once (issue 38: one composer).

The commands run in this process (click's runner; ``obj2bin DIR`` with one job converts here) with the real
stages; a profile hook (:func:`sys.setprofile`, also set for new threads) counts the calls of each entry's code
object, whatever name or alias reached it. Nothing is replaced: the counts are of the functions that ran.
"""

from __future__ import annotations

import json
import shutil
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import CodeType, FrameType
from typing import Any

import pytest
from click.testing import CliRunner
from test_layering import STAGE_ENTRIES

from meshtool.cli.main import main, obj2bin
from meshtool.frame.decide import decide_frame
from meshtool.frame.declared import decide_asset_frame, source_frame
from meshtool.hulls.compute import compute_hulls
from meshtool.packfile.write import pack
from meshtool.read import read_mesh
from meshtool.read.source_asset import read_source_asset
from meshtool.read.triangles import read_triangles
from meshtool.repair.convert import convert_asset
from meshtool.repair.mesh import build_mesh

#: The entries in the order the composer enters them for one file (each stage's inner entries right after it).
READ_TO_REPAIR: tuple[Callable[..., Any], ...] = (
    read_source_asset,
    read_mesh,
    read_triangles,
    decide_asset_frame,
    source_frame,
    decide_frame,
    convert_asset,
    build_mesh,
)
WHOLE = (*READ_TO_REPAIR, compute_hulls, pack)
STAGE = {
    read_source_asset: "read",
    read_mesh: "read",
    read_triangles: "read",
    decide_asset_frame: "frame",
    source_frame: "frame",
    decide_frame: "frame",
    convert_asset: "repair",
    build_mesh: "repair",
    compute_hulls: "hulls",
    pack: "packfile",
}


class EntryCounter:
    """The calls of the watched functions, in order, as their ``__qualname__``."""

    def __init__(self, functions: tuple[Callable[..., Any], ...]) -> None:
        self.codes: dict[CodeType, str] = {f.__code__: f.__qualname__ for f in functions}
        self.calls: list[str] = []
        self._lock = threading.Lock()

    def hook(self, frame: FrameType, event: str, _arg: Any) -> None:
        if event == "call":
            name = self.codes.get(frame.f_code)
            if name is not None:
                with self._lock:
                    self.calls.append(name)

    def counts(self) -> dict[str, int]:
        return {name: self.calls.count(name) for name in self.codes.values()}


@contextmanager
def counting(functions: tuple[Callable[..., Any], ...] = WHOLE) -> Iterator[EntryCounter]:
    counter = EntryCounter(functions)
    before, before_threads = sys.getprofile(), threading.getprofile()
    threading.setprofile(counter.hook)
    sys.setprofile(counter.hook)
    try:
        yield counter
    finally:
        sys.setprofile(before)
        threading.setprofile(before_threads)  # type: ignore[arg-type]


def names(functions: tuple[Callable[..., Any], ...]) -> list[str]:
    return [f.__qualname__ for f in functions]


def invoke(command: Any, *args: Any) -> Any:
    result = CliRunner().invoke(command, [str(a) for a in args], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result


@pytest.fixture
def assets(fixtures: Path, tmp_path: Path) -> Path:
    """A folder of three assets in three formats: an OBJ with an MTL and two textures, an STL, a GLB."""
    folder = tmp_path / "assets"
    shutil.copytree(fixtures / "multi_material", folder / "crate")
    stl = sorted((fixtures / "formats").rglob("*.stl"))[0]
    glb = sorted((fixtures / "formats").rglob("*.glb"))[0]
    (folder / "parts").mkdir()
    shutil.copy(stl, folder / "parts" / stl.name)
    shutil.copy(glb, folder / "parts" / glb.name)
    return folder


def test_the_watched_entries_are_the_layering_tests_stage_entries():
    """The entries counted here are those tests/test_layering.py keeps out of every module but the composer."""
    import importlib

    listed = {getattr(importlib.import_module(m), n).__code__: stage for (m, n), stage in STAGE_ENTRIES.items()}
    assert listed == {f.__code__: stage for f, stage in STAGE.items()}
    assert set(WHOLE) == set(STAGE)


def test_obj2bin_file_enters_each_stage_once(assets: Path, tmp_path: Path):
    out = tmp_path / "crate.mbin"
    with counting() as counter:
        invoke(obj2bin, assets / "crate" / "crate.obj", "-o", out)
    assert out.is_file()
    assert counter.calls == names(WHOLE)  # each once, in the composer's order
    by_name = {f.__qualname__: STAGE[f] for f in WHOLE}
    stages = [by_name[c] for c in counter.calls]
    runs = [s for k, s in enumerate(stages) if k == 0 or stages[k - 1] != s]
    # the frame decides on the vertices the read stage marked kept: repair is entered once, after it
    assert runs == ["read", "frame", "repair", "hulls", "packfile"]


def test_obj2bin_dir_enters_each_stage_once_per_file(assets: Path, tmp_path: Path):
    out = tmp_path / "out"
    with counting() as counter:
        result = invoke(obj2bin, assets, "-o", out, "--json", "-j", "1")
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*.mbin"))
    assert len(written) == 3, (written, result.output)
    assert counter.calls == names(WHOLE) * 3
    assert set(counter.counts().values()) == {3}


def test_obj2bin_dir_enters_no_stage_for_an_unchanged_file(assets: Path, tmp_path: Path):
    out = tmp_path / "out"
    invoke(obj2bin, assets, "-o", out, "-j", "1")
    crate = assets / "crate" / "crate.obj"
    crate.write_bytes(crate.read_bytes() + b"# touched\n")
    with counting() as counter:
        invoke(obj2bin, assets, "-o", out, "-j", "1")
    assert counter.calls == names(WHOLE)  # only the changed OBJ is read and converted again


def test_meshtool_normalize_and_hulls_enter_read_to_repair_once(assets: Path, tmp_path: Path):
    src = assets / "crate" / "crate.obj"
    with counting() as counter:
        invoke(main, "normalize", src, "-o", tmp_path / "norm")
    assert counter.calls == names(READ_TO_REPAIR)
    with counting() as counter:
        report = json.loads(invoke(main, "hulls", src, "--json").stdout)
    assert report["status"] == "ok"
    assert counter.calls == [*names(READ_TO_REPAIR), compute_hulls.__qualname__]  # hulls packs nothing


def test_meshtool_mjcf_of_a_mesh_file_enters_each_stage_once(assets: Path, tmp_path: Path):
    glb = next((assets / "parts").glob("*.glb"))
    with counting() as counter:
        invoke(main, "mjcf", glb, "-o", tmp_path / "model")
    assert list((tmp_path / "model").rglob("*.xml"))
    assert counter.calls == names(WHOLE)


def test_the_counter_sees_an_entry_entered_twice(assets: Path):
    """The hook counts every call: a composer that read a file twice would fail the tests above."""
    from meshtool.frame.modelroot import model_root_resolver

    src = assets / "crate" / "crate.obj"
    resolver, _ = model_root_resolver(src)
    with counting() as counter:
        first = read_source_asset(src, resolver)
        read_source_asset(src, resolver)
    assert counter.counts()[read_source_asset.__qualname__] == 2
    assert counter.calls == names((read_source_asset, read_mesh, read_triangles)) * 2
    assert first.library and first.sources[0]["role"] == "obj"


def test_meshtool_validate_of_an_obj_enters_each_stage_once(assets: Path, tmp_path: Path):
    report = tmp_path / "report.json"
    with counting() as counter:  # one job, no deadline: checked in this process
        invoke(main, "validate", assets / "crate", "-j", "1", "--no-cache", "--timeout", "0", "-o", report, "-q")
    assert json.loads(report.read_text())["assets"]
    assert counter.calls == names(WHOLE)


def test_meshtool_urdf_enters_each_stage_once_per_mesh_file(fixtures: Path, tmp_path: Path):
    robot = fixtures / "urdf" / "meshbot" / "meshbot.urdf"
    uses = robot.read_text().count("meshes/wheel.obj")
    with counting() as counter:
        invoke(main, "urdf", robot, "-o", tmp_path / "robot")
    assert uses > 1  # one mesh file, used by several links: read and packed once
    assert counter.calls == names(WHOLE)
