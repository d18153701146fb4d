"""Rendering never changes what is simulated or reported (issue 14 item 2).

The reported distance used to follow the video frame rate (3.319 m without video, 3.245 / 3.257 / 3.273 m
at 5 / 15 / 30 fps) because the robots' positions were sampled at whatever points the frames split the run.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import needs_gl

from simrun.cli.main import main
from simrun.run.play import load_commands, play
from simrun.scene.scene_file import load_scene

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
#: Long enough for a turn, a straight leg and the start of a second turn of the square.
SECONDS = 9.0
#: Summary fields that measure the machine or the rendering, not the simulation.
WALL_FIELDS = ("wall_s", "steps_per_s", "realtime_factor", "frames")


def _run(fps: float | None) -> tuple[dict, np.ndarray, int]:
    world = load_scene(SCENES / "boebot.toml")
    world.check_bindings()
    commands = load_commands(SCENES / "square.commands.toml")
    taken: list[float] = []
    sink = (lambda data: taken.append(float(data.time))) if fps else None
    result = play(world, SECONDS, commands, sink, fps or 15.0)
    return result.to_dict(), np.concatenate([world.data.qpos, world.data.qvel]), len(taken)


@pytest.mark.parametrize("fps", [5.0, 7.0, 15.0, 30.0, 60.0])
def test_frame_sink_changes_neither_state_nor_summary(fps):
    plain, plain_state, _ = _run(None)
    seen, seen_state, frames = _run(fps)
    assert frames == pytest.approx(SECONDS * fps, abs=1)  # the sink really ran at that rate
    assert plain["distances_m"]["boebot"] > 0.3  # the robot drove: the comparison means something
    assert np.array_equal(plain_state, seen_state)
    for key in WALL_FIELDS:
        plain.pop(key), seen.pop(key)
    assert seen == plain


def test_distance_is_the_path_sampled_on_a_fixed_grid():
    """Ground truth from the simulator: the body's xy path sampled every 20 ms by stepping the world alone."""
    world = load_scene(SCENES / "boebot.toml")
    world.check_bindings()
    commands = load_commands(SCENES / "square.commands.toml")
    expected = 0.0
    reference = load_scene(SCENES / "boebot.toml")
    reference.check_bindings()
    pending = list(commands)
    previous = np.array(reference.body("boebot").xpos[:2])
    for _ in range(int(SECONDS / 0.02)):
        for _ in range(10):  # 10 steps of 2 ms, applying each command at its step
            while pending and pending[0].t <= reference.data.time + 0.001:
                pending.pop(0).apply(reference)
            reference.step(1)
        now = np.array(reference.body("boebot").xpos[:2])
        expected += float(np.linalg.norm(now - previous))
        previous = now
    result = play(world, SECONDS, commands, lambda data: None, 15.0)
    assert result.distances["boebot"] == pytest.approx(expected, rel=1e-9)


@needs_gl
def test_cli_summary_and_recording_identical_with_and_without_video(tmp_path):
    runner = CliRunner()
    base = [
        "play",
        str(SCENES / "boebot.toml"),
        "--duration",
        "6",
        "--commands",
        str(SCENES / "square.commands.toml"),
        "--json",
    ]
    outputs = {}
    for label, extra in {
        "none": [],
        "5": ["--video", str(tmp_path / "a.gif"), "--fps", "5", "--size", "64x48"],
        "15": ["--video", str(tmp_path / "b.gif"), "--fps", "15", "--size", "64x48"],
        "30": ["--frames", str(tmp_path / "frames"), "--fps", "30", "--size", "64x48"],
    }.items():
        record = tmp_path / f"{label}.simlog"
        result = runner.invoke(main, [*base, "--record", str(record), *extra])
        assert result.exit_code == 0, result.output
        summary = json.loads(result.stdout)
        for key in WALL_FIELDS:
            summary.pop(key)
        outputs[label] = (summary, record.read_bytes())
    assert len(list((tmp_path / "frames").iterdir())) == pytest.approx(6 * 30, abs=1)
    first = outputs["none"]
    for label, (summary, recording) in outputs.items():
        assert summary == first[0], label
        assert recording == first[1], label
