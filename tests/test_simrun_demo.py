"""The demo (issue 14 item 7): `make demo` drives the Boe-Bot around the box, every command runs, the robot
is lit and large enough to recognise in the GIF (fixtures/scenes/boebot.toml + square.commands.toml).

Ground truth is the simulator's own state (body poses, geom distances) and MuJoCo's segmentation render.
"""

from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import needs_gl

from simrun.run.play import load_commands
from simrun.run.render import FrameRenderer
from simrun.run.session import DEFAULT_SIZE
from simrun.scene.scene_file import load_scene

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
#: The demo's length (Makefile: simrun play ... --duration 40).
DURATION = 40.0


def _demo_run(every: float, sample) -> dict:
    """Run the demo, applying each command at its step; ``sample(world, t)`` every ``every`` simulated seconds."""
    world = load_scene(SCENES / "boebot.toml")
    world.check_bindings()
    commands = load_commands(SCENES / "square.commands.toml")
    drive = world.service("DriveService", "boebot")
    model, data = world.model, world.data
    dt = model.opt.timestep
    applied, last_busy, path = [], 0.0, []
    pending = list(commands)
    next_sample = 0.0
    for _ in range(round(DURATION / dt)):
        while pending and pending[0].t <= data.time + 0.5 * dt:
            command = pending.pop(0)
            command.apply(world)
            applied.append(float(data.time))
        if data.time + 0.5 * dt >= next_sample:
            sample(world, float(data.time))
            path.append(np.array(world.body("boebot").xpos[:2]))
            next_sample += every
        world.step(1)
        if drive.busy:
            last_busy = float(data.time)
    return {"world": world, "applied": applied, "commands": commands, "last_busy": last_busy, "path": path}


@pytest.fixture(scope="module")
def physics():
    model_data: dict = {"distance": np.inf}

    def sample(world, t):
        model, data = world.model, world.data
        if "box0" not in model_data:
            model_data["box0"] = np.array(world.body("box").xpos)
        root = model.body("boebot").id
        robot = [g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == root]
        box = [g for g in range(model.ngeom) if model.geom_bodyid[g] == model.body("box").id]
        fromto = np.zeros(6)
        for g1 in robot:
            for g2 in box:
                model_data["distance"] = min(
                    model_data["distance"], mujoco.mj_geomDistance(model, data, g1, g2, 1.0, fromto)
                )

    run = _demo_run(0.02, sample)
    run.update(model_data)
    return run


def test_every_command_runs_and_finishes_within_the_demo(physics):
    assert len(physics["applied"]) == len(physics["commands"]) == 10
    for command, when in zip(physics["commands"], physics["applied"], strict=True):
        assert when == pytest.approx(command.t, abs=0.002)
    assert physics["last_busy"] < DURATION - 0.1  # the last drive_distance has ended before the GIF does


def test_the_square_goes_around_the_box_without_touching_it(physics):
    world = physics["world"]
    box = np.array(world.body("box").xpos)
    assert np.linalg.norm(box - physics["box0"]) < 1e-3  # never pushed
    assert physics["distance"] > 0.02  # metres between the robot's and the box's geoms, over the whole run
    path = np.array(physics["path"])
    assert np.linalg.norm(path[-1] - path[0]) < 0.05  # back where it started
    angles = np.unwrap(np.arctan2(path[:, 1] - box[1], path[:, 0] - box[0]))
    assert abs(angles[-1] - angles[0]) == pytest.approx(2 * np.pi, abs=0.3)  # one full turn around the box


@needs_gl
def test_the_gif_is_lit_and_the_robot_is_at_least_60_pixels_tall():
    width, height = DEFAULT_SIZE  # the Makefile leaves --size at its default
    heights, brightness = [], []
    state = {}

    def sample(world, t):
        model, data = world.model, world.data
        if "seg" not in state:
            assert model.vis.global_.cameraid == model.camera("view").id  # play's default view is the main camera
            state["frames"] = FrameRenderer(model, width, height, "visual", None, data)
            state["seg"] = mujoco.Renderer(model, height, width)
            state["seg"].enable_segmentation_rendering()
            root = model.body("boebot").id
            state["robot"] = np.array([model.body_rootid[model.geom_bodyid[g]] == root for g in range(model.ngeom)])
        frame = state["frames"].render(data)
        brightness.append(float(frame.mean()))
        state["seg"].update_scene(data, camera="view")
        ids = state["seg"].render()[..., 0]
        mask = (ids >= 0) & state["robot"][np.clip(ids, 0, model.ngeom - 1)]
        rows = np.flatnonzero(mask.any(axis=1))
        heights.append(int(rows[-1] - rows[0] + 1) if rows.size else 0)
        if rows.size:
            robot_pixels = frame[mask]
            assert robot_pixels.mean() > 60, t  # the robot itself is lit, not a dark blob

    _demo_run(1.0, sample)
    assert len(heights) == DURATION
    assert min(heights) >= 60, heights
    assert min(brightness) > 100, brightness
