"""JointService's ``profile`` and ``integral`` options (issue 37: the options the built-in arms' service uses),
and velocity targets that outlive a cancelled trajectory. Ground truth: the simulator's controls and joints."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from simrun import EntityError, World, WorldOptions
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.services.joint_service import JointService

#: Two hinges on ``<position>`` servos (one geared 2), and a velocity servo, without gravity.
SERVOS = """<mujoco><worldbody>
  <body name="a" pos="0 0 1"><joint name="one" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
  <body name="b" pos="1 0 1"><joint name="two" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
  <body name="c" pos="2 0 1"><joint name="spin" axis="0 0 1"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
</worldbody>
<actuator>
  <position name="one" joint="one" kp="50" kv="3"/>
  <position name="two" joint="two" kp="50" kv="3" gear="2"/>
  <velocity name="spin" joint="spin" kv="5"/>
</actuator></mujoco>"""


def _world(tmp_path: Path, **options: object) -> tuple[World, JointService]:
    (tmp_path / "servos.xml").write_text(SERVOS)
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)), base_dir=tmp_path)
    world.insert(MjcfRobot(name="s", file="servos.xml"))
    return world, JointService(world, "s", **options)  # type: ignore[arg-type]


def test_a_cosine_move_writes_the_cosine_profile_into_a_position_servo(tmp_path: Path) -> None:
    """``profile="cosine"``, ``integral=False``: at each tick the servo's control is ``gear * (a + (b - a)
    (1 - cos(pi u)) / 2)`` exactly, ``u`` the fraction of the move's time; it ends exactly on the goal."""
    world, service = _world(tmp_path, profile="cosine", integral=False, rate=50.0)
    model, data = world.model, world.data
    one, two = model.actuator("s/one").id, model.actuator("s/two").id
    service.move_to(["one", "two"], [0.6, -0.4], 1.0)
    for _ in range(round(1.0 / 0.02) - 1):
        world.run(0.02)
        u = (world.time - 0.02) / 1.0  # the last tick was one period ago
        blend = 0.5 - 0.5 * math.cos(math.pi * u)
        assert data.ctrl[one] == pytest.approx(0.6 * blend, abs=1e-12)
        assert data.ctrl[two] == pytest.approx(2.0 * -0.4 * blend, abs=1e-12)  # gear 2: the actuator's length
    world.run(0.1)
    assert not service.busy
    assert (data.ctrl[one], data.ctrl[two]) == (0.6, 2.0 * -0.4)  # exactly
    world.run(3.0)
    assert float(data.joint("s/one").qpos[0]) == pytest.approx(0.6, abs=1e-3)
    assert float(data.joint("s/two").qpos[0]) == pytest.approx(-0.4, abs=1e-3)


def test_the_linear_profile_is_the_default_and_halfway_is_halfway(tmp_path: Path) -> None:
    world, service = _world(tmp_path, integral=False, rate=50.0)
    assert service.profile == "linear" and not service.integral
    service.move_to(["one"], [0.5], 1.0)
    world.run(0.52)  # the tick at 0.5 s
    assert world.data.ctrl[world.model.actuator("s/one").id] == pytest.approx(0.25, abs=1e-12)


def test_without_the_integral_a_servo_held_off_its_target_gets_the_target_alone(tmp_path: Path) -> None:
    """A servo pushed off its target by a constant external torque: with the integral (default) the service
    shifts the servo's target until the joint is there; without it the control stays the target."""
    results = {}
    for integral in (True, False):
        world, service = _world(tmp_path, integral=integral)
        model, data = world.model, world.data
        data.qfrc_applied[model.joint("s/one").dofadr[0]] = 5.0  # N m: 0.1 rad of the 50 N m/rad spring
        service.set_positions(["one"], [0.2])
        world.run(4.0)
        results[integral] = (float(data.joint("s/one").qpos[0]), float(data.ctrl[model.actuator("s/one").id]))
    assert results[True][0] == pytest.approx(0.2, abs=2e-3)
    assert results[False] == (pytest.approx(0.3, abs=2e-3), 0.2)


def test_a_velocity_target_keeps_running_when_another_joints_trajectory_is_cancelled(tmp_path: Path) -> None:
    world, service = _world(tmp_path)
    service.set_velocities(["spin"], [0.5])
    service.move_to(["one"], [0.4], 2.0)
    world.run(0.5)
    service.set_positions(["one"], [0.1])  # cancels the move
    start = float(world.data.joint("s/spin").qpos[0])
    world.run(1.0)
    assert float(world.data.joint("s/spin").qpos[0]) - start == pytest.approx(0.5, rel=0.02)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"profile": "sine"}, "profile must be one of linear, cosine, got 'sine'"),
        ({"integral": 1}, "integral must be true or false, got 1"),
    ],
)
def test_bad_options_are_refused(tmp_path: Path, options: dict[str, object], message: str) -> None:
    with pytest.raises(EntityError, match=message):
        _world(tmp_path, **options)
