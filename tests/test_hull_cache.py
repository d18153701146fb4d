"""The finished hulls of a decomposed part are cached: a cached conversion runs neither CoACD nor qhull."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import meshtool.hulls.compute
import meshtool.hulls.decompose
from meshtool.hulls.compute import HullOptions, compute_hulls
from meshtool.repair.normalise import NormaliseOptions, prepare

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"


def _halves(points, faces, options, timeout_s=None, problems=None):  # a stand-in decomposition: the two halves along x
    middle = float(np.median(points[:, 0]))
    return [points[points[:, 0] <= middle + 1e-9], points[points[:, 0] >= middle - 1e-9]], False, None


def _fail(*_args, **_kwargs):
    raise AssertionError("called although the finished hulls are cached")


def test_second_run_reads_finished_hulls(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    mesh = prepare(FIXTURES / "bowl" / "bowl.obj", NormaliseOptions()).mesh
    options = HullOptions(mode="decompose", cache_dir=tmp_path)
    monkeypatch.setattr(meshtool.hulls.decompose, "decompose", _halves)
    first = compute_hulls(mesh, options, "bowl.obj")
    assert len(first.hulls) == 2 and first.cache_hits == 0
    assert list(tmp_path.glob("*/*.hulls.npz"))
    monkeypatch.setattr(meshtool.hulls.decompose, "decompose", _fail)
    monkeypatch.setattr(meshtool.hulls.compute, "convex_hull", _fail)
    second = compute_hulls(mesh, options, "bowl.obj")
    assert second.cache_hits == 1
    for a, b in zip(first.hulls, second.hulls, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.faces, b.faces)
        assert a.part == b.part
    assert [f.code for f in first.findings] == [f.code for f in second.findings]


def test_damaged_hull_entry_is_recomputed(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    mesh = prepare(FIXTURES / "bowl" / "bowl.obj", NormaliseOptions()).mesh
    options = HullOptions(mode="decompose", cache_dir=tmp_path)
    monkeypatch.setattr(meshtool.hulls.decompose, "decompose", _halves)
    first = compute_hulls(mesh, options, "bowl.obj")
    for entry in tmp_path.glob("*/*.hulls.npz"):
        entry.write_bytes(b"not an npz")
    again = compute_hulls(mesh, options, "bowl.obj")
    assert again.cache_hits == 0 and len(again.hulls) == len(first.hulls)
