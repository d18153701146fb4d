"""Byte-identical reports whatever the executor and the number of workers (issue 38, item 4), and the one
progress line of the batch commands written into a log with ``--progress``.

``meshtool validate`` (JSON and JUnit from one run) and ``simrun test`` (JSON; its text, JUnit and GitHub
output are compared the same way in tests/test_scenetest_run.py) each run with ``-j 1`` (this process),
``-j 2`` (two worker processes) and ``--executor dask -j 2`` (a real ``dask.distributed`` LocalCluster of two
worker *processes*), and the report files must be equal byte for byte. Ground truth for the findings and the
runs: the fixtures' own expectations (a clean asset is clean, an inside-out one has G006; the box on the
square's path fails the run it blocks, tests/test_scenetest_run.py).
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest
from click.testing import CliRunner

from meshtool.cli.main import main as meshtool_main
from meshtool.cli.main import obj2bin
from simrun.cli.main import main as simrun_main

pytest.importorskip("distributed")

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
EXECUTORS = {"-j1": ["-j", "1"], "-j2": ["-j", "2"], "dask": ["--executor", "dask", "-j", "2"]}
#: ``[ 2/12] 16%  0.4 items/s  eta 0:25  last: NAME`` (docs/ci.md, docs/scene-tests.md).
LINE = re.compile(r"^\[ *(\d+)/(\d+)\] (\d+)%  (-|\d+\.\d) items/s  eta (-|\d+:\d\d(:\d\d)?)  last: (.+)$")


def progress_lines(stderr: str) -> list[re.Match[str]]:
    return [m for m in map(LINE.match, stderr.splitlines()) if m]


def assert_progress(stderr: str, total: int) -> None:
    """Plain progress lines into a log: counting up, the last one says every item is done."""
    lines = progress_lines(stderr)
    assert lines, stderr
    done = [int(m.group(1)) for m in lines]
    assert done == sorted(done) and {int(m.group(2)) for m in lines} == {total}
    assert done[-1] == total and lines[-1].group(3) == "100" and lines[-1].group(5) == "0:00"


@pytest.fixture(scope="module")
def assets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A clean textured box, an inside-out mesh, a missing MTL and an STL."""
    root = tmp_path_factory.mktemp("identical") / "assets"
    for name in ("clean", "G006_inside_out", "S002_mtl_missing"):
        shutil.copytree(FIXTURES / "validate" / name, root / name)
    shutil.copytree(FIXTURES / "formats" / "stl", root / "stl")
    return root


def test_validate_json_and_junit_are_the_same_bytes_on_every_executor(
    assets: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(assets.parent)  # reports name the assets relative to the working folder
    reports = {}
    for name, args in EXECUTORS.items():
        out = tmp_path / name
        out.mkdir()
        argv = ["validate", "assets", "--no-cache", "--progress", "-o", str(out / "r.json"), "-o", str(out / "r.xml")]
        result = CliRunner().invoke(meshtool_main, [*argv, *args])
        assert result.exit_code == 1, result.output  # the missing MTL is an error
        reports[name] = ((out / "r.json").read_bytes(), (out / "r.xml").read_bytes())
        total = len(json.loads(reports[name][0])["assets"])
        assert_progress(result.stderr, total)
    assert reports["-j2"] == reports["-j1"] and reports["dask"] == reports["-j1"]
    data = json.loads(reports["-j1"][0])
    status = {a["path"].split("/")[1]: a["status"] for a in data["assets"]}
    assert status["clean"] == "clean" and status["S002_mtl_missing"] == "error"
    codes = {f["rule"] for a in data["assets"] if "G006" in a["path"] for f in a["findings"]}
    assert "G006" in codes
    junit = ET.fromstring(reports["-j1"][1])
    assert junit.get("tests") == str(len(data["assets"]))


def test_simrun_test_json_is_the_same_bytes_on_every_executor(tmp_path: Path) -> None:
    scene = FIXTURES / "scenes" / "boebot_square.toml"
    reports = {}
    for name, args in EXECUTORS.items():
        out = tmp_path / f"{name}.json"
        argv = ["test", str(scene), "--vary", "box.y=0.7:1.0:2", "--progress", "--format", "json", "-o", str(out)]
        result = CliRunner().invoke(simrun_main, [*argv, *args])
        assert result.exit_code == 1, result.output  # the box at y = 0.7 blocks the square
        reports[name] = out.read_bytes()
        assert_progress(result.stderr, 2)
        labels = [m.group(7) for m in progress_lines(result.stderr)]
        assert all(re.search(r"boebot_square\.toml seed=0 box\.y=(0\.7|1) ", label) for label in labels), labels
    assert reports["-j2"] == reports["-j1"] and reports["dask"] == reports["-j1"]
    runs = json.loads(reports["-j1"])["runs"]
    assert [r["status"] for r in runs] == ["failed", "passed"]


def test_obj2bin_dir_progress_into_a_log_and_none_without_asking(tmp_path: Path) -> None:
    src = tmp_path / "src"
    shutil.copytree(FIXTURES / "formats" / "stl", src / "stl")
    shutil.copytree(FIXTURES / "head", src / "head")
    argv = [str(src), "-o", str(tmp_path / "out"), "--units", "cm", "--no-cache", "--no-check"]
    shown = CliRunner().invoke(obj2bin, [*argv, "--progress"])
    assert shown.exit_code == 0, shown.output
    written = len(list((tmp_path / "out").rglob("*.mbin")))
    assert_progress(shown.stderr, written)
    assert {m.group(7) for m in progress_lines(shown.stderr)} <= {p.name for p in src.rglob("*") if p.is_file()}
    quiet = CliRunner().invoke(obj2bin, argv)  # not a terminal, no --progress: no progress line
    assert quiet.exit_code == 0 and not progress_lines(quiet.stderr) and "unchanged" in quiet.stdout


def test_validate_on_a_terminal_draws_the_batch_line_in_place(assets: Path, tmp_path: Path) -> None:
    """On a pseudo-terminal (what a user's terminal receives): the spinner, then the batch line, redrawn with
    ``\\r\\x1b[K``; ``--no-progress`` draws nothing there."""
    import os
    import pty
    import subprocess
    import sys

    from meshtool.work.progress import CLEAR, FRAMES

    def on_terminal(*extra: str) -> str:
        master, slave = pty.openpty()
        argv = [sys.executable, "-m", "meshtool.cli.main", "validate", str(assets / "clean"), "--no-cache", *extra]
        env = {**os.environ, "COLUMNS": "200"}
        child = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=tmp_path, env=env)
        os.close(slave)
        shown = bytearray()
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not chunk:
                break
            shown += chunk
        os.close(master)
        assert child.wait(timeout=300) in (0, 1)
        return shown.decode()

    drawn = [p for p in on_terminal("-j", "1").split(CLEAR) if p[:1] in FRAMES and p[1:2] == " "]
    batch = [p[2:].split(" -- ")[0] for p in drawn if LINE.match(p[2:].split(" -- ")[0])]
    assert batch and batch[0].startswith("[1/2] 50%  ") and "clean/box." in batch[0], drawn  # box.mbin, box.obj
    assert CLEAR not in on_terminal("-j", "1", "--no-progress")
