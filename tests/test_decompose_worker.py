"""Decomposition budget and the CoACD worker's lifetime (issue 16 item 8)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from meshtool.hulls.compute import HullOptions, compute_hulls
from meshtool.repair.normalise import NormaliseOptions, prepare

BOWL = Path(__file__).resolve().parent.parent / "fixtures" / "bowl" / "bowl.obj"
pytest.importorskip("coacd")


def _workers(marker: str) -> list[int]:
    """PIDs of live (not zombie) coacd_worker processes whose command line contains ``marker``."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if "meshtool.hulls.coacd_worker" in cmdline and marker in cmdline and state != "Z":
            pids.append(int(entry))
    return pids


def _wait(condition, seconds: float = 30.0) -> bool:  # type: ignore[no-untyped-def]
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def test_spent_budget_gives_convex_hulls_with_a_warning(monkeypatch):
    asset = prepare(BOWL, NormaliseOptions(up="z"))
    monkeypatch.setattr("meshtool.hulls.decompose.Budget.left", lambda self: 0.0)
    monkeypatch.setattr("meshtool.hulls.decompose.decompose", lambda *a, **k: pytest.fail("decompose called"))
    result = compute_hulls(asset.mesh, HullOptions(mode="decompose", time_budget_s=60, cache_dir=None), "bowl.obj")
    (warn,) = [f for f in result.findings if f.code == "decompose-budget"]
    assert warn.severity.value == "warning" and "1 part(s)" in warn.message
    assert len(result.hulls) == 1


def test_budget_left_limits_a_run_and_the_worker_is_cleaned_up(monkeypatch, tmp_path):
    monkeypatch.setenv("MESHTOOL_TEST_COACD_DELAY_S", "60")
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)
    monkeypatch.setattr("meshtool.hulls.decompose.Budget.left", lambda self: 1.0)
    asset = prepare(BOWL, NormaliseOptions(up="z"))
    result = compute_hulls(asset.mesh, HullOptions(mode="decompose", cache_dir=None), "bowl.obj")
    (failed,) = [f for f in result.findings if f.code == "decompose-failed"]
    assert "did not finish within 1 s" in failed.message and len(result.hulls) == 1
    assert _wait(lambda: not _workers(str(tmp_path)), 10)
    assert not list(tmp_path.glob("meshtool-coacd-*"))


PARENT = """
import sys
from pathlib import Path
from meshtool.hulls.decompose import decompose
from meshtool.hulls.compute import HullOptions
from meshtool.repair.normalise import NormaliseOptions, prepare
asset = prepare(Path(sys.argv[1]), NormaliseOptions(up="z"))
decompose(asset.mesh.positions, asset.mesh.faces, HullOptions(mode="decompose", cache_dir=None))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_worker_and_folder_go_when_the_parent_is_killed(tmp_path, sig):
    env = {**os.environ, "MESHTOOL_TEST_COACD_DELAY_S": "120", "TMPDIR": str(tmp_path)}
    parent = subprocess.Popen([sys.executable, "-c", PARENT, str(BOWL)], env=env)
    try:
        assert _wait(lambda: len(_workers(str(tmp_path))) == 2, 60), "supervisor and CoACD run did not start"
        assert len(list(tmp_path.glob("meshtool-coacd-*"))) == 1
        parent.send_signal(sig)
        parent.wait(30)
        assert _wait(lambda: not _workers(str(tmp_path)), 30), "a worker outlived its parent"
        assert _wait(lambda: not list(tmp_path.glob("meshtool-coacd-*")), 10), "the temporary folder was left"
    finally:
        parent.kill()
        parent.wait()
        for pid in _workers(str(tmp_path)):
            os.kill(pid, signal.SIGKILL)
