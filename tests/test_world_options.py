"""A robot's own <option> is the world's unless the scene sets that option (issue 37); overrides are warned.

Ground truth: MuJoCo's own load of the fixture (``model.opt``), and the values the test writes itself.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import pytest
from click.testing import CliRunner

from simrun import EntityError, Ground, Pose, World, WorldOptions, load_scene
from simrun.cli.main import main
from simrun.robots.mjcf_robot import MjcfRobot

FREEBOT = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf" / "keyframe" / "freebot.xml"
#: The fixture's own options (timestep 0.005, RK4, CG, 30 iterations, tolerance 1e-7).
OWN = ("timestep", "integrator", "solver", "iterations", "tolerance")


def _world(options: WorldOptions | None = None, *files: str) -> World:
    world = World(options, base_dir=FREEBOT.parent)
    world.insert(Ground(name="ground"))
    for k, file in enumerate(files or ("freebot.xml",)):
        world.insert(MjcfRobot(name=f"bot{k}", file=file, pose=Pose((k, 0.0, 0.0))))
    return world


def test_the_robots_own_options_are_the_worlds_as_mujoco_loads_them() -> None:
    ref = mujoco.MjModel.from_xml_path(str(FREEBOT))
    world = _world()
    model = world.model
    for name in OWN:
        assert getattr(model.opt, name) == getattr(ref.opt, name), name
    assert model.opt.gravity[2] == pytest.approx(-9.81)  # the world's
    assert world.option_choice()[1] == []
    assert world.scene_warnings() == []
    world.run(0.1)  # in the robot's steps: 20 of 5 ms
    assert world.data.time == pytest.approx(0.1)


def test_an_explicit_world_option_governs_and_the_override_is_warned() -> None:
    ref = mujoco.MjModel.from_xml_path(str(FREEBOT))
    world = _world(WorldOptions(timestep=0.001))
    model = world.model
    assert model.opt.timestep == 0.001
    for name in OWN[1:]:  # the rest is still the robot's
        assert getattr(model.opt, name) == getattr(ref.opt, name), name
    assert world.option_choice()[1] == [
        "option timestep: the world's timestep = 0.001 (set by the scene) overrides 'bot0''s own timestep = 0.005"
    ]
    assert WorldOptions().explicit == frozenset() and WorldOptions(integrator="rk4").explicit == {"integrator"}
    assert WorldOptions().timestep == 0.002 and WorldOptions().integrator == "implicitfast"


def test_two_robots_that_disagree_the_first_wins_and_the_second_is_named(tmp_path: Path) -> None:
    other = tmp_path / "other.xml"
    other.write_text(FREEBOT.read_text().replace('iterations="30"', 'iterations="80"'))
    world = World(base_dir=tmp_path)
    world.insert(MjcfRobot(name="a", file=str(FREEBOT)))
    world.insert(MjcfRobot(name="b", file="other.xml", pose=Pose((1.0, 0.0, 0.0))))
    assert world.model.opt.iterations == 30
    assert world.scene_warnings() == [
        "option iterations: 'b''s own iterations = 80 differs from 'a''s iterations = 30, which the world uses"
    ]


def test_a_scene_sets_options_explicitly_only_where_it_says_so(tmp_path: Path) -> None:
    body = f'[[entities]]\ntype = "MjcfRobot"\nname = "bot"\nfile = "{FREEBOT}"\n'
    (tmp_path / "own.toml").write_text(body)
    (tmp_path / "set.toml").write_text('[world]\nintegrator = "implicitfast"\n\n' + body)
    assert load_scene(tmp_path / "own.toml").model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    world = load_scene(tmp_path / "set.toml")
    assert world.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert world.model.opt.timestep == 0.005
    result = CliRunner().invoke(main, ["check", str(tmp_path / "set.toml"), "--duration", "0.1"])
    assert result.exit_code == 0, result.output
    assert (
        "warning: " + str(tmp_path / "set.toml") + ": option integrator: the world's integrator = IMPLICITFAST "
        "(set by the scene) overrides 'bot''s own integrator = RK4"
    ) in result.output


def test_a_saved_scene_keeps_which_options_were_explicit(tmp_path: Path) -> None:
    """Saved and loaded again: the robot's own timestep stays its own, an explicit integrator stays explicit."""
    from simrun import save_scene

    world = World(WorldOptions(integrator="implicit"), base_dir=tmp_path)
    world.insert(MjcfRobot(name="bot", file=str(FREEBOT)))
    save_scene(world, tmp_path / "saved.toml")
    text = (tmp_path / "saved.toml").read_text()
    assert "timestep" not in text and 'integrator = "implicit"' in text
    again = load_scene(tmp_path / "saved.toml")
    assert again.model.opt.timestep == 0.005  # the robot's
    assert again.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICIT
    assert again.options.explicit == {"integrator"}


@pytest.mark.parametrize("bad", [math.nan, math.inf, -0.002, 0.0])
def test_a_timestep_given_as_nan_or_out_of_range_is_refused_not_taken_as_unset(bad):
    with pytest.raises(EntityError, match="timestep must be in"):
        WorldOptions(timestep=bad)
    assert WorldOptions().explicit == frozenset() and WorldOptions(timestep=0.004).explicit == {"timestep"}
