"""simrun test end to end: the fixtures pass, the box-in-the-path variation fails exactly the runs geometry says,
every failure re-simulates bit for bit, reports are identical whatever the executor, exit codes as validate's.

The failing example's ground truth is the square's geometry (fixtures/scenes/square.commands.toml): the
Boe-Bot (start (1, 1)) drives legs along y = 0.7 and y = 1.3; a 0.2 m box centred at y meets a robot
0.10 m wide (track 0.09 m + one wheel width) when |y - 0.7| or |y - 1.3| is below 0.1 + 0.05 m.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from simrun.scenetest import TestOptions, TestReport, run_tests
from simrun.scenetest.reports import render
from simrun.scenetest.spec import load_case
from simrun.scenetest.task import RunTask, run_task
from simrun.scenetest.vary import parse_vary

ROOT = Path(__file__).parent.parent
SCENES = ROOT / "fixtures" / "scenes"
SQUARE = SCENES / "boebot_square.toml"
SIMRUN = [str(Path(sys.executable).parent / "simrun")]
GRID = "box.y=0.5:1.5:11"
HALF_BOX, HALF_ROBOT = 0.1, 0.05


def blocked(y: float) -> bool:
    """Whether a box centred at ``y`` is on the square's path (see the module)."""
    return min(abs(y - 0.7), abs(y - 1.3)) < HALF_BOX + HALF_ROBOT


def simrun(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    return subprocess.run([*SIMRUN, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=600)


@pytest.fixture(scope="module")
def grid_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[TestReport, Path]:
    record = tmp_path_factory.mktemp("failed")
    options = TestOptions(seeds=[3], axes=[parse_vary(GRID)], record_dir=record)
    return run_tests([SQUARE], options), record


def test_fixtures_pass_as_junit(tmp_path: Path) -> None:
    out = tmp_path / "r.xml"
    done = simrun("test", str(SCENES), "--seeds", "0:2", "-j", "2", "--format", "junit", "-o", str(out))
    assert done.returncode == 0, done.stderr
    root = ET.parse(out).getroot()
    scenes = sorted(p for p in SCENES.glob("*.toml") if not p.name.endswith(".commands.toml"))
    assert root.get("tests") == str(2 * len(scenes)) and root.get("failures") == "0" and root.get("errors") == "0"
    names = [s.get("name") for s in root.iter("testsuite")]
    assert names == [p.as_posix() for p in scenes]
    for case in root.iter("testcase"):
        seed = [p.get("value") for p in case.iter("property") if p.get("name") == "seed"]
        assert seed in (["0"], ["1"]) and f"seed={seed[0]}" in (case.get("name") or "")
    square = next(s for s in root.iter("testsuite") if s.get("name", "").endswith("boebot_square.toml"))
    case = next(square.iter("testcase"))
    assert {p.get("name") for p in case.iter("property")} == {
        "seed",
        "jitter.boebot.x",
        "jitter.boebot.y",
        "jitter.boebot.yaw",
    }
    assert "expect 'home' (position)" in (case.findtext("system-out") or "")


def test_box_in_the_path_fails_exactly_where_geometry_says(grid_report: tuple[TestReport, Path]) -> None:
    report, _ = grid_report
    assert len(report.runs) == 11
    for run in report.runs:
        y = run.values["box.y"]
        assert run.result.status == ("failed" if blocked(y) else "passed"), (run.label, run.result.outcomes)
        if blocked(y):
            failing = {o.id for o in run.result.outcomes if not o.passed}
            assert "box-untouched" in failing and "home" in failing
            touch = next(o for o in run.result.outcomes if o.id == "box-untouched")
            assert "boebot/" in touch.detail and "box/" in touch.detail and touch.time is not None
    assert {run.values["box.y"] for run in report.runs if run.result.status == "failed"} == {
        0.6,
        0.7,
        0.8,
        1.2,
        1.3,
        1.4,
    }


def test_every_failure_resimulates_bit_for_bit(grid_report: tuple[TestReport, Path], tmp_path: Path) -> None:
    report, record = grid_report
    failed = [r for r in report.runs if r.result.status == "failed"]
    assert failed and all(r.recording and r.resim for r in failed)
    moved = tmp_path / "elsewhere"
    shutil.copytree(record, moved)  # the recording carries its scene and files: it works from anywhere
    for run in failed[:2]:
        log = moved / Path(run.recording or "").relative_to(record)
        done = simrun("resim", str(log), cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        assert "bit-identical" in done.stdout
        scene = log.with_suffix(".toml").read_text(encoding="utf-8")
        assert f"box.y={run.values['box.y']!r}" in scene.splitlines()[0]


def test_reports_identical_in_process_pool_and_dask(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    axes = [parse_vary("box.y=0.7:1.0:2")]
    texts = {}
    for executor, jobs in (("local", 1), ("local", 2), ("dask", 2)):
        record = tmp_path / "rec"
        report = run_tests(
            [SQUARE], TestOptions(seeds=[0, 1], axes=axes, jobs=jobs, executor=executor, record_dir=record)
        )
        assert report.counts() == {"passed": 2, "failed": 2, "error": 0}
        texts[(executor, jobs)] = {fmt: render(report, fmt) for fmt in ("text", "json", "junit", "github")}
        if executor == "dask":
            assert all(w.startswith("tcp://") for w in report.where)
    first = texts[("local", 1)]
    assert texts[("local", 2)] == first and texts[("dask", 2)] == first


def test_github_annotations_point_at_the_expectation_line(grid_report: tuple[TestReport, Path]) -> None:
    report, _ = grid_report
    lines = render(report, "github").splitlines()
    text = SQUARE.read_text(encoding="utf-8").splitlines()
    home_line = next(k for k in range(len(text)) if text[k] == 'id = "home"')  # the [[expect]] line is above it
    home = next(line for line in lines if "title=simrun test%3A expect home" in line)
    assert home.startswith(f"::error file={SQUARE.as_posix().replace(':', '%3A')},line={home_line}")
    assert "failed in 6 of 11 run(s)" in home
    assert lines[-1].startswith("::notice")


def test_json_lists_values_and_reproduction(grid_report: tuple[TestReport, Path]) -> None:
    report, _ = grid_report
    data = json.loads(render(report, "json"))
    assert data["summary"]["runs"] == 11 and data["summary"]["failed"] == 6 and not data["summary"]["passed_all"]
    run = next(r for r in data["runs"] if r["status"] == "failed")
    assert set(run["values"]) == {"box.y", "jitter.boebot.x", "jitter.boebot.y", "jitter.boebot.yaw"}
    assert run["reproduce"].startswith("simrun resim ")


def test_task_needs_no_shared_folder(tmp_path: Path) -> None:
    """A scene with a URDF (and meshes) outside its folder runs from its bundle after the folder is gone."""
    work = tmp_path / "src"
    shutil.copytree(SCENES.parent / "urdf", work / "urdf")
    (work / "scenes").mkdir()
    shutil.copy(SCENES / "urdf_arm.toml", work / "scenes" / "urdf_arm.toml")
    case = load_case(work / "scenes" / "urdf_arm.toml")
    assert any(name.endswith(".urdf") for name in case.bundle.files)
    assert any(name.endswith((".stl", ".obj", ".dae", ".STL")) for name in case.bundle.files)
    shutil.rmtree(work)
    task = RunTask(
        0,
        case.bundle.digest,
        "urdf_arm.seed0.toml",
        case.bundle.files[case.bundle.scene],
        0,
        0.2,
        (),
        None,
        case.expectations,
    )
    result = run_task(task, case.bundle)
    assert result.status == "passed", result.error


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--seeds", "5:2"], 2, "usage error: --seeds 5:2"),
        (["--vary", "box.mass"], 2, "usage error: --vary"),
        (["--vary", "ghost.mass=1:2:2"], 2, "no scene has an entity or sensor of that name"),
        (["--scheduler", "tcp://x:1"], 2, "--scheduler needs --executor dask"),
    ],
)
def test_usage_errors(args: list[str], code: int, message: str) -> None:
    done = simrun("test", str(SQUARE), *args)
    assert done.returncode == code and message in done.stderr and "Traceback" not in done.stderr


def test_exit_codes_and_error_lines(tmp_path: Path) -> None:
    missing = simrun("test", str(tmp_path / "missing"))  # a missing input is exit 1, as in every command
    assert missing.returncode == 1 and missing.stderr.endswith("missing: no such file or folder\n")
    bad = tmp_path / "bad.toml"
    bad.write_text('[world]\n\n[[expect]]\nid = "x"\nkind = "position"\nbody = "nobody"\npoint = [0, 0]\nwithin = 1\n')
    done = simrun("test", str(bad))
    assert done.returncode == 1
    assert done.stderr.startswith(f"error: {bad.as_posix()}:3: expect 'x': no body named 'nobody'")
    failing = simrun("test", str(SQUARE), "--vary", "box.y=0.7", "-j", "1")
    assert failing.returncode == 1 and "FAILED" in failing.stdout and "expect 'box-untouched'" in failing.stdout


def test_html_has_a_thumbnail_per_failure(tmp_path: Path) -> None:
    out = tmp_path / "r.html"
    done = simrun("test", str(SQUARE), "--vary", "box.y=0.7:1.0:2", "-j", "1", "--format", "html", "-o", str(out))
    assert done.returncode == 1, done.stderr
    page = out.read_text(encoding="utf-8")
    if "cannot render" in page:
        pytest.skip("no headless OpenGL here")
    assert page.count("data:image/png;base64,") == 1  # one failed run, one picture
    assert "Passed runs (1)" in page


CONTROLLER = """
def step(world):
    world.service("DriveService", "boebot").drive_speed(0.1, 0.1)
"""


def test_python_controller_run_is_recorded_and_resimulated(tmp_path: Path) -> None:
    """A [test] controller module travels in the bundle; its failure re-simulates with --controller."""
    scene = (SCENES / "boebot.toml").read_text(encoding="utf-8")
    (tmp_path / "ctl.py").write_text(CONTROLLER, encoding="utf-8")
    path = tmp_path / "drive.toml"
    path.write_text(
        scene + '\n[test]\nduration = 2.0\ncommands = "ctl.py"\n\n[[expect]]\nid = "stays"\nkind = "position"\n'
        'body = "boebot"\npoint = [1.0, 1.0]\nwithin = 0.05\n',
        encoding="utf-8",
    )
    record = tmp_path / "failed"
    report = run_tests([path], TestOptions(record_dir=record))
    (run,) = report.runs
    assert run.result.status == "failed", run.result.error
    (outcome,) = run.result.outcomes
    assert outcome.miss is not None and 0.05 < outcome.miss + 0.05 < 0.25  # it drove away at about 0.1 m/s
    assert run.resim is not None and "--controller" in run.resim
    done = simrun(*run.resim.split()[1:], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "bit-identical" in done.stdout


def test_a_worker_that_dies_is_an_internal_error(tmp_path: Path) -> None:
    """A run that kills its worker process (as a native crash would) is an error for that run, exit 3."""
    scene = (SCENES / "boebot.toml").read_text(encoding="utf-8")
    (tmp_path / "die.py").write_text("import os\n\ndef step(world):\n    os._exit(7)\n", encoding="utf-8")
    path = tmp_path / "crash.toml"
    path.write_text(scene + '\n[test]\nduration = 1.0\ncommands = "die.py"\n', encoding="utf-8")
    out = tmp_path / "r.json"
    done = simrun("test", str(path), "--seeds", "0:3", "-j", "2", "--format", "json", "-o", str(out))
    assert done.returncode == 3, done.stderr
    runs = json.loads(out.read_text(encoding="utf-8"))["runs"]
    assert [r["status"] for r in runs] == ["error"] * 3
    assert all(r["error"] == "internal error: the worker process running it died (exit code 7)" for r in runs)


def test_workers_die_with_their_parent(tmp_path: Path) -> None:
    """Killing simrun test (SIGKILL: no clean-up runs) ends its busy worker processes too (PR_SET_PDEATHSIG).

    Each run simulates an hour (minutes of work), so a worker gone within seconds was killed, not finished.
    """
    psutil = pytest.importorskip("psutil")
    import signal
    import time

    long = tmp_path / "long.toml"
    long.write_text((SCENES / "boebot.toml").read_text(encoding="utf-8") + "\n[test]\nduration = 3600.0\n")
    parent = subprocess.Popen(
        [*SIMRUN, "test", str(long), "--seeds", "0:2", "-j", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        workers: list = []
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.2)
            workers = [c for c in psutil.Process(parent.pid).children() if "spawn_main" in " ".join(c.cmdline())]
        assert len(workers) == 2
        time.sleep(3)  # both are running their hour now
        assert all(w.is_running() for w in workers)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(10)
        gone, alive = psutil.wait_procs(workers, timeout=10)
        assert not alive and len(gone) == 2
    finally:
        if parent.poll() is None:
            parent.kill()
