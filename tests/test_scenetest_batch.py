"""``simrun test`` on the batch layer (meshtool/work/batch.py): a run killed mid-way or past ``--timeout`` is
an error for that run only, the others go on, and ``-j 1 --timeout`` is a hard deadline (a worker process).

Ground truth: process facts. The crashing scene's controller sends its own worker SIGKILL during the first
step (as a native crash would end it); the long scene asks for an hour of simulation, so an answer within
seconds means it was stopped; the short scene passes in any process.
"""

from __future__ import annotations

import time
from pathlib import Path

from simrun.scenetest import TestOptions, run_tests

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
KILL = "import os\nimport signal\n\n\ndef step(world):\n    os.kill(os.getpid(), signal.SIGKILL)\n"


def test_a_killed_run_and_a_late_run_are_errors_and_the_rest_go_on(tmp_path: Path) -> None:
    scene = (SCENES / "boebot.toml").read_text(encoding="utf-8")
    (tmp_path / "kill.py").write_text(KILL, encoding="utf-8")
    (tmp_path / "a_crash.toml").write_text(scene + '\n[test]\nduration = 1.0\ncommands = "kill.py"\n')
    (tmp_path / "b_long.toml").write_text(scene + "\n[test]\nduration = 3600.0\n")
    (tmp_path / "c_short.toml").write_text(scene + "\n[test]\nduration = 0.5\n")
    started = time.monotonic()
    report = run_tests([tmp_path], TestOptions(seeds=[0], jobs=1, timeout=10.0))
    elapsed = time.monotonic() - started
    by_scene = {}
    for run in report.runs:
        by_scene.setdefault(Path(run.case.display).stem, []).append(run.result)
    died = "internal error: the worker process running it died (signal 9)"
    assert [r.error for r in by_scene["a_crash"]] == [died]
    assert all(r.internal and r.status == "error" for r in by_scene["a_crash"])
    late = "the run did not finish within 10 s and was stopped (--timeout)"
    assert [(r.status, r.error, r.internal) for r in by_scene["b_long"]] == [("error", late, False)]
    assert [r.status for r in by_scene["c_short"]] == ["passed"]
    assert elapsed < 300  # the run of an hour was stopped, not waited for
    assert all(where.startswith("worker ") for where in report.where)  # -j 1 with a deadline: worker processes
    assert report.internal() and report.counts() == {"passed": 1, "failed": 0, "error": 2}
