"""Playback: render modes, play summaries, commands, video and snapshots (headless)."""

import io
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import needs_gl
from PIL import Image

from simrun import load_scene
from simrun.cli.main import main
from simrun.run.play import load_commands, play
from simrun.run.render import MODES, FrameRenderer

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


@needs_gl
def test_each_render_mode_gives_a_distinct_non_blank_image():
    world = load_scene(SCENES / "head_on_table.toml")
    world.run(0.5)
    images = {}
    for mode in MODES[:-1]:
        renderer = FrameRenderer(world.model, 160, 120, mode, data=world.data)
        images[mode] = renderer.render(world.data).astype(int)
        renderer.close()
        assert images[mode].std() > 5  # not blank
    for a in images:
        for b in images:
            if a < b:
                assert np.abs(images[a] - images[b]).mean() > 0.2, (a, b)


def test_play_applies_commands_and_summarises():
    world = load_scene(SCENES / "boebot.toml")
    commands = load_commands(SCENES / "square.commands.toml")
    assert [c.call for c in commands][:3] == ["rotate_degrees", "drive_distance", "rotate_degrees"]
    start = world.body("boebot").xpos.copy()
    result = play(world, 40.0, commands)
    summary = result.to_dict()
    assert summary["simulated_s"] == 40.0 and summary["steps"] == 20000
    # legs of 0.3 + 0.8 + 0.6 + 0.8 + 0.3 m; the body origin is the axle midpoint, so turns add nothing
    assert summary["distances_m"]["boebot"] == pytest.approx(2.8, abs=0.03)
    assert np.linalg.norm(world.body("boebot").xpos[:2] - start[:2]) < 0.02  # back where it started
    assert summary["warnings"] == {}


def test_play_json_cli_headless():
    result = CliRunner().invoke(main, ["play", str(SCENES / "pioneer_room.toml"), "--duration", "1", "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert set(summary) == {
        "simulated_s",
        "wall_s",
        "steps",
        "steps_per_s",
        "realtime_factor",
        "frames",
        "distances_m",
        "sensor_samples",
        "warnings",
    }
    assert summary["frames"] == 0 and summary["sensor_samples"] == {"laser": 10}
    assert summary["steps"] == 500 and summary["distances_m"] == {"p3dx": pytest.approx(0.0, abs=1e-3)}


@needs_gl
def test_video_gif_mp4_frames_and_snapshot(tmp_path):
    runner = CliRunner()
    scene = str(SCENES / "boebot.toml")
    commands = str(SCENES / "square.commands.toml")
    gif = tmp_path / "run.gif"
    result = runner.invoke(
        main,
        [
            "play",
            scene,
            "--duration",
            "2",
            "--commands",
            commands,
            "--video",
            str(gif),
            "--fps",
            "5",
            "--size",
            "96x64",
        ],
    )
    assert result.exit_code == 0, result.output
    image = Image.open(gif)
    assert image.format == "GIF" and image.size == (96, 64) and image.n_frames >= 2
    mp4 = tmp_path / "run.mp4"
    assert (
        runner.invoke(main, ["play", scene, "--duration", "1", "--video", str(mp4), "--size", "96x64"]).exit_code == 0
    )
    assert mp4.read_bytes()[4:8] == b"ftyp"
    frames = tmp_path / "frames"
    assert (
        runner.invoke(
            main, ["play", scene, "--duration", "1", "--frames", str(frames), "--fps", "4", "--render-mode", "physics"]
        ).exit_code
        == 0
    )
    assert sorted(p.name for p in frames.iterdir()) == [f"frame_{k:05d}.png" for k in range(4)]
    shot = tmp_path / "shot.png"
    assert runner.invoke(main, ["snapshot", scene, "-o", str(shot), "--size", "64x48"]).exit_code == 0
    assert Image.open(io.BytesIO(shot.read_bytes())).size == (64, 48)


def test_play_usage_errors(tmp_path):
    runner = CliRunner()
    scene = str(SCENES / "boebot.toml")
    assert runner.invoke(main, ["play", scene, "--size", "big"]).exit_code == 2
    result = runner.invoke(main, ["play", scene, "--render-mode", "none", "--video", str(tmp_path / "x.gif")])
    assert result.exit_code == 1 and "cannot write video" in result.stderr
    bad = tmp_path / "c.toml"
    bad.write_text('[[commands]]\nt = 1.0\nentity = "boebot"\ncall = "fly"\n')
    result = runner.invoke(main, ["play", scene, "--commands", str(bad), "--duration", "2"])
    assert result.exit_code == 1 and "has no command 'fly'" in result.stderr


def test_view_without_a_display_says_so_in_one_line(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    result = CliRunner().invoke(main, ["view", str(SCENES / "boebot.toml")])
    assert result.exit_code == 1
    assert len(result.stderr.splitlines()) == 1 and "no display" in result.stderr and "--video" in result.stderr


def test_teleop_keys_drive_the_robot():
    from simrun.run.viewer import KEY_LEFT, KEY_SPACE, KEY_UP, Teleop
    from simrun.services.drive_service import DriveService

    world = load_scene(SCENES / "boebot.toml")
    teleop = Teleop(DriveService(world, "boebot"))
    start = world.body("boebot").xpos.copy()
    for key in (KEY_UP, KEY_UP, KEY_LEFT):
        teleop.key(key)
    assert (teleop.linear, teleop.angular) == (pytest.approx(0.1), 0.5)
    for _ in range(10):
        teleop.refresh()
        world.run(0.2)
    assert np.linalg.norm(world.body("boebot").xpos[:2] - start[:2]) > 0.1
    teleop.key(KEY_SPACE)
    world.run(1.0)
    assert abs(world.body("boebot").cvel[3]) < 0.01
