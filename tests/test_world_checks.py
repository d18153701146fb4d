"""``simrun check`` and ``World.scene_warnings``: initial penetrations and ground that holds a fixed robot.

Ground truth: the fixtures' analytic geometry (sphere radii and centre distances, a capsule's height).
"""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from simrun import Ground, Pose, World
from simrun.cli.main import main
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.world.checks import PENETRATION, scene_warnings

CHECKS = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf" / "checks"
RADIUS, APART = 0.05, 0.07  # overlap.xml: the spheres' radius and centre distance, m


def _world(file: str, **kw: object) -> World:
    world = World(base_dir=CHECKS)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="bot", file=file, **kw))  # type: ignore[arg-type]
    return world


def test_two_overlapping_geoms_are_named_with_their_depth() -> None:
    world = _world("overlap.xml")
    depth_cm = (2 * RADIUS - APART) * 100  # 3.0 cm
    assert scene_warnings(world) == [
        f"initial penetration: geoms 'bot/left' and 'bot/right' start {depth_cm:.1f} cm inside each other "
        f"(over {PENETRATION * 1000:g} mm); MuJoCo pushes them apart at the first steps"
    ]
    world.run(0.5)
    assert scene_warnings(world) == world.scene_warnings()  # measured at the initial state, not now


def test_a_fixed_planar_arm_on_the_ground_is_warned_and_a_free_one_is_not() -> None:
    fixed = _world("planar_arm.xml")
    assert fixed.scene_warnings() == [
        "ground holds a fixed robot: geoms 'bot/link' and 'ground/plane' touch (3.0 mm inside) at the start; "
        "the ground's friction acts against its joints: raise the robot or remove the ground"
    ]
    assert _world("planar_arm.xml", pose=Pose((0.0, 0.0, 0.01))).scene_warnings() == []  # 7 mm clear
    assert _world("planar_arm.xml", free=True).scene_warnings() == []  # its root moves: it rests on the link


def test_simrun_check_prints_the_warnings_in_order_and_in_json(tmp_path: Path) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(
        '[[entities]]\ntype = "Ground"\nname = "ground"\n\n'
        f'[[entities]]\ntype = "MjcfRobot"\nname = "arm"\nfile = "{CHECKS / "planar_arm.xml"}"\n\n'
        f'[[entities]]\ntype = "MjcfRobot"\nname = "balls"\nfile = "{CHECKS / "overlap.xml"}"\n'
    )
    runner = CliRunner()
    result = runner.invoke(main, ["check", str(scene), "--duration", "0.2"])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("warning:")]
    assert [line.split(": ", 3)[2] for line in lines] == ["initial penetration", "ground holds a fixed robot"]
    assert "2 scene warnings (above)" in result.output
    document = json.loads(runner.invoke(main, ["check", str(scene), "--duration", "0.2", "--json"]).stdout)
    assert document["warnings"] == [line.split(": ", 2)[2] for line in lines]
