"""``simrun test --timeout``: a run that never ends is stopped at its deadline wherever it runs (issue 42 item 3).

Every way a batch runs is tried from the command line: one run alone with ``-j 1``, several with ``-j 1`` and
``-j 2``, and a local Dask cluster. The hanging runs are a controller that loops forever in Python, one that
sleeps for an hour, and a scene that asks for ten hours of simulation; a short scene beside them must still
pass. Ground truth: the report (the scene and seed of each stopped run, with the deadline's words), the exit
code, and the wall clock only as a loose bound (a run of an hour stopped within a minute was stopped, not
waited for).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BOEBOT = (ROOT / "fixtures" / "scenes" / "boebot.toml").read_text(encoding="utf-8")
SIMRUN = str(Path(sys.executable).parent / "simrun")
LOOP = "def step(world):\n    while True:\n        pass\n"
SLEEP = "import time\n\n\ndef step(world):\n    time.sleep(3600)\n"
LATE = "the run did not finish within 3 s and was stopped (--timeout)"
#: Far above the 3 s deadline plus start-up, far below the hour a hanging run asks for.
BOUND_S = 90.0


@pytest.fixture
def scenes(tmp_path: Path) -> Path:
    """loop.toml (a controller that never returns), sleep.toml, long.toml (10 h simulated), short.toml."""
    (tmp_path / "loop.py").write_text(LOOP, encoding="utf-8")
    (tmp_path / "sleep.py").write_text(SLEEP, encoding="utf-8")
    tests = {
        "loop": 'duration = 1.0\ncommands = "loop.py"\n',
        "sleep": 'duration = 1.0\ncommands = "sleep.py"\n',
        "long": "duration = 36000.0\n",
        "short": "duration = 0.2\n",
    }
    for name, table in tests.items():
        (tmp_path / f"{name}.toml").write_text(f"{BOEBOT}\n[test]\n{table}", encoding="utf-8")
    return tmp_path


def simrun_test(folder: Path, *args: str) -> tuple[int, dict[tuple[str, int], tuple[str, str | None]], float]:
    """Exit code, ``(scene, seed) -> (status, error)`` of the JSON report, and the wall-clock seconds."""
    out = folder / "report.json"
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    started = time.monotonic()
    done = subprocess.run(
        [SIMRUN, "test", *args, "--timeout", "3", "--format", "json", "-o", str(out), "--no-progress"],
        capture_output=True,
        text=True,
        cwd=folder,
        env=env,
        timeout=300,
    )
    elapsed = time.monotonic() - started
    assert "Traceback" not in done.stderr, done.stderr
    runs = json.loads(out.read_text(encoding="utf-8"))["runs"]
    return done.returncode, {(r["scene"], r["seed"]): (r["status"], r["error"]) for r in runs}, elapsed


def test_one_run_alone_with_one_job_ends_at_its_deadline(scenes: Path) -> None:
    """One run and -j 1 (before: in this process, where the deadline was not enforced)."""
    code, runs, elapsed = simrun_test(scenes, "loop.toml", "-j", "1")
    assert code == 1
    assert runs == {("loop.toml", 0): ("error", LATE)}
    assert elapsed < BOUND_S


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_local_workers_stop_each_late_run_and_go_on(scenes: Path, jobs: str) -> None:
    code, runs, elapsed = simrun_test(scenes, "loop.toml", "sleep.toml", "short.toml", "--seeds", "0,1", "-j", jobs)
    assert code == 1
    for seed in (0, 1):
        assert runs[("loop.toml", seed)] == ("error", LATE)
        assert runs[("sleep.toml", seed)] == ("error", LATE)
        assert runs[("short.toml", seed)] == ("passed", None)
    assert elapsed < BOUND_S * 2


def test_dask_stops_each_late_run_and_goes_on(scenes: Path) -> None:
    """A local Dask cluster of one worker: every hanging run is an error at its deadline, the short run passes.

    With one worker the short run comes after three abandoned ones on the same process: they were stopped
    (their threads interrupted), or the short run would share the worker with them.
    """
    pytest.importorskip("distributed")
    code, runs, elapsed = simrun_test(
        scenes, "loop.toml", "long.toml", "sleep.toml", "short.toml", "--executor", "dask", "-j", "1"
    )
    assert code == 1
    assert runs == {
        ("loop.toml", 0): ("error", LATE),
        ("long.toml", 0): ("error", LATE),
        ("sleep.toml", 0): ("error", LATE),
        ("short.toml", 0): ("passed", None),
    }
    assert elapsed < BOUND_S
