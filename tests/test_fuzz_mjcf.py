"""The ``mjcf`` fuzz target (tests/fuzz/target_mjcf.py, issue 42 item 5), quickly: a few dozen seeded mutations.

``make fuzz FUZZ_TARGETS=mjcf`` runs the same target for minutes (docs/testing.md, "Fuzzing"); here
``tests/fuzz/run.py`` runs it for a fixed seed and 40 inputs from the fixture models only (dm_control's models
need the bench environment), each in the harness's child process under its per-input deadline and memory cap:
every input must end as a loaded robot or a one-line ``SimrunError``, and both must occur.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FUZZ = ROOT / "tests" / "fuzz"
INPUTS = 40


def test_forty_seeded_mutations_load_or_are_refused_in_one_line(tmp_path: Path) -> None:
    out = tmp_path / "fuzz"
    env = {**os.environ, "MUJOCO_GL": "egl", "FUZZ_MJCF_SOURCES": "fixtures"}
    command = [sys.executable, str(FUZZ / "run.py"), "--targets", "mjcf", "--seed", "1", "--max-inputs", str(INPUTS)]
    command += ["--seconds", "240", "--out", str(out), "--memory-mb", "3072"]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    stats = json.loads((out / "summary.json").read_text())["targets"]["mjcf"]
    assert stats["tried"] == INPUTS and stats["crashed"] == 0, stats
    assert not stats["crashes"] and not stats["hangs"], stats
    assert stats["accepted"] > 0 and stats["refused"] > 0, stats  # both ends reached
    assert stats["accepted"] + stats["refused"] == INPUTS
    assert not (out / "crashes").exists()


@pytest.fixture()
def target() -> Iterator[object]:
    sys.path.insert(0, str(FUZZ))
    try:
        import target_mjcf
        import targets  # noqa: F401  (run_mjcf writes its input with targets.write_input)

        yield target_mjcf
    finally:
        sys.path.remove(str(FUZZ))


def test_a_hostile_input_is_refused_and_the_hook_sees_the_readers_opens(tmp_path: Path, target: object) -> None:
    """A model including the outside file and naming the FIFO: one line; the hook saw the model opened, no more."""
    from simrun.errors import SimrunError

    run = target.run_mjcf  # type: ignore[attr-defined]
    opened = target._OPENED  # type: ignore[attr-defined]
    model = b"<mujoco><include file='@OUTSIDE@/secret.obj'/><worldbody/></mujoco>"
    (tmp_path / "a").mkdir()
    with pytest.raises(SimrunError) as info:
        run({"sub/m.xml": model}, tmp_path / "a")
    message = str(info.value)
    assert "\n" not in message and "outside the scene's folder" in message and "secret.obj" in message, message
    assert any(path.endswith("m.xml") for path, _ in opened), opened  # the hook records the reader's opens
    assert not any("secret" in path for path, _ in opened), opened
    (tmp_path / "b").mkdir()
    fifo = b"<mujoco><asset><mesh name='p' file='pipe'/></asset><worldbody><geom type='mesh' mesh='p'/></worldbody>"
    fifo += b"</mujoco>"
    with pytest.raises(SimrunError, match="FIFO"):
        run({"m.xml": fifo}, tmp_path / "b")
    (tmp_path / "c").mkdir()
    run({"m.xml": b"<mujoco><worldbody><body><joint/><geom size='.1'/></body></worldbody></mujoco>"}, tmp_path / "c")


def test_dm_control_models_come_from_the_bench_environment_or_a_note(
    target: object, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Without a bench environment: a note, no seed; with ``.bench-mjcf/``: its dm_control models, each its
    ``<mujoco>`` file first (the check is skipped where ``make bench-mjcf`` has not run)."""
    monkeypatch.setenv("FUZZ_MJCF_SOURCES", "dm_control")
    real = target.BENCH_ENV  # type: ignore[attr-defined]
    monkeypatch.setattr(target, "BENCH_ENV", tmp_path / "no-bench-env")
    assert target.mjcf_seeds(tmp_path) == []  # type: ignore[attr-defined]
    assert "no dm_control (make bench-mjcf makes it): its models skipped" in capsys.readouterr().err
    monkeypatch.setattr(target, "BENCH_ENV", real)
    if target._site_packages() is None:  # type: ignore[attr-defined]
        pytest.skip(f"{real} has no dm_control (make bench-mjcf)")
    seeds = target.mjcf_seeds(tmp_path)  # type: ignore[attr-defined]
    assert len(seeds) > 30 and "dm_control" not in capsys.readouterr().err
    assert all(ET.fromstring(next(iter(s.values()))).tag == "mujoco" for s in seeds)
