"""JointService loop design (issue 29): force loops on a floating body, weak velocity servos.

Ground truth: MuJoCo's joint positions against the designed critically damped responses (no overshoot).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simrun import World, WorldOptions
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.services.joint_service import BANDWIDTH, JointService

#: A light free base (0.2 kg) with a 1 kg, 0.5 m arm on a motor-driven hinge: with the base held the hinge
#: sees the arm's inertia about its end, m L^2 / 3; free, the arm turns nearly about its own centre.
FLOATING = """<mujoco><worldbody>
  <body name="base" pos="0 0 1"><freejoint/><geom type="box" size=".05 .05 .05" mass="0.2"/>
    <body name="arm"><joint name="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 .5 0 0" size=".02" mass="1"/></body>
  </body></worldbody>
  <actuator><motor joint="hinge" ctrlrange="-20 20"/></actuator>
</mujoco>"""
#: A 1 kg cart on a slide with a weak velocity servo (kv 1 N s/m): its own damping ratio around the
#: service's 4 pi rad/s position loop would be 1 / (2 sqrt(1 * 1 * 4 pi)) = 0.14.
WEAK = """<mujoco><worldbody>
  <body name="cart" pos="0 0 1"><joint name="slide" type="slide" axis="1 0 0"/>
    <geom type="box" size=".05 .05 .05" mass="1"/></body></worldbody>
  <actuator><velocity joint="slide" kv="1"/></actuator>
</mujoco>"""


def _world(tmp_path: Path, text: str) -> World:
    (tmp_path / "m.xml").write_text(text)
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)), base_dir=tmp_path)
    world.insert(MjcfRobot(name="m", file="m.xml"))
    return world


def _track(world: World, service: JointService, joints: list[str], seconds: float) -> np.ndarray:
    """Each joint's position every step for ``seconds`` (rows: steps)."""
    rows = []
    while world.time < seconds - 1e-9:
        world.step()
        rows.append([world.data.joint(f"m/{j}").qpos[0] for j in joints])
    return np.asarray(rows)


def test_a_force_loop_on_a_floating_body_follows_its_design(tmp_path: Path) -> None:
    """The loop sees the hinge's inertia with the base free (Schur complement): a 0.3 rad step follows the
    designed response, (3 w^2 s + w^3) / (s + w)^3: 1 - exp(-x) (1 + x - x^2), x = w t (25 % overshoot at
    x = 3, from the integral's zero), within 5 % of the step (measured 1.8 %; designed for the inertia with
    the base held, the diagonal of the mass matrix, the loop swung out to 11.7 times the step)."""
    world = _world(tmp_path, FLOATING)
    service = JointService(world, "m")
    assert service.kinds() == {"hinge": "force"}
    service.set_positions(["hinge"], [0.3])
    path = _track(world, service, ["hinge"], 2.0)[:, 0]
    x = BANDWIDTH * np.arange(1, len(path) + 1) * world.model.opt.timestep
    design = 1.0 - np.exp(-x) * (1.0 + x - x * x)
    assert np.abs(path - 0.3 * design).max() <= 0.05 * 0.3
    assert world.warnings() == {}


def test_a_weak_velocity_servo_is_driven_critically_damped(tmp_path: Path) -> None:
    """1 - (1 + w t) exp(-w t) of the step within 5 % (measured 0.8 %), no overshoot (the loop damped by the
    servo alone overshot by 64 % and strayed from that by 64 % of the step)."""
    world = _world(tmp_path, WEAK)
    service = JointService(world, "m")
    assert service.kinds() == {"slide": "velocity"}
    service.set_positions(["slide"], [0.05])
    path = _track(world, service, ["slide"], 1.5)[:, 0]
    assert path.max() <= 0.05 * 1.01
    times = np.arange(1, len(path) + 1) * world.model.opt.timestep
    w = BANDWIDTH
    expected = 0.05 * (1.0 - (1.0 + w * times) * np.exp(-w * times))
    assert np.abs(path - expected).max() == pytest.approx(0.0, abs=0.05 * 0.05)  # within 5 % of the step


#: A 2 kg cart on x and z slides riding on a 0.1 kg ball of radius 0.1 m, the ball turned by a motor about y:
#: on the ground the ball cannot roll without carrying the cart, so its joint sees (2.1 kg) r^2 + its own
#: 4e-4 kg m^2, 53 times the inertia with the cart free (what the loop was designed for before issue 37).
ROLLER = """<mujoco><worldbody>
  <body name="cart" pos="0 0 0.1"><joint name="x" type="slide" axis="1 0 0"/><joint name="z" type="slide" axis="0 0 1"/>
    <geom type="box" size=".1 .05 .02" pos="0 0 .15" mass="2" contype="0" conaffinity="0"/>
    <body name="wheel"><joint name="roll" axis="0 1 0"/><geom type="sphere" size=".1" mass="0.1"/></body>
  </body></worldbody>
  <actuator><motor joint="roll" ctrlrange="-50 50"/></actuator>
</mujoco>"""
#: The floating test's arm welded to the world, on a motor whose force follows its control through a 50 ms
#: filter (dm_control's dog: every actuator so): ``tau w = 1.26`` at 4 Hz, where the loop that ignored the
#: filter, ``tau s^4 + s^3 + 3 w s^2 + 3 w^2 s + w^3``, is unstable (Routh: it needs ``tau w < 8 / 9``).
FILTERED = """<mujoco><worldbody>
  <body name="arm" pos="0 0 1"><joint name="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 .5 0 0" size=".02" mass="1"/></body></worldbody>
  <actuator><general joint="hinge" dyntype="filter" dynprm="0.05" gainprm="100" ctrlrange="-1 1"/></actuator>
</mujoco>"""


def _step(tmp_path: Path, text: str, joint: str, gravity: float, seconds: float) -> np.ndarray:
    """A 0.3 rad step of ``joint`` after 0.5 s at rest: its displacement every step for ``seconds``."""
    (tmp_path / "m.xml").write_text(text)
    from simrun import Ground

    world = World(WorldOptions(gravity=(0.0, 0.0, gravity)), base_dir=tmp_path)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="m", file="m.xml"))
    service = JointService(world, "m")
    assert service.kinds() == {joint: "force"}
    world.run(0.5)
    start = float(world.data.joint(f"m/{joint}").qpos[0])
    service.set_positions([joint], [start + 0.3])
    return _track(world, service, [joint], 0.5 + seconds)[:, 0] - start


def test_a_rolling_joint_carrying_its_body_settles(tmp_path: Path) -> None:
    """The loop adds the inertia the contacts make its joint carry (MuJoCo's constraint rows, capped for the
    moment the contact lets go) and slows its integral for the rest: the ball settles on the target (the
    last second within 0.5 % of the step; measured 0.31 %). Designed for the ball alone, it swung +-3 rad,
    ever wider. Ground truth: the simulator's joint position."""
    path = _step(tmp_path, ROLLER, "roll", -9.81, 4.0)
    last = path[-round(1.0 / 0.002) :]
    assert np.abs(last - 0.3).max() <= 0.005 * 0.3
    assert path.max() < 2 * 0.3  # measured 1.74 times the step at its peak


def test_a_filtered_force_actuator_is_driven_through_its_filter(tmp_path: Path) -> None:
    """The control is chosen so that the filtered activation reaches the loop's wanted force in one control
    period: the step settles (within 1e-3 of it after 1 s, measured 1e-7, no ringing; the first 40 ms are the filter's
    slew at full control). Ignoring the filter, the same step ran away to 83 times itself."""
    path = _step(tmp_path, FILTERED, "hinge", 0.0, 3.0)
    times = np.arange(1, len(path) + 1) * 0.002
    assert np.abs(path[times >= 1.0] - 0.3).max() <= 1e-3 * 0.3
    assert path.max() <= 1.35 * 0.3  # the design's own overshoot is 25 %; measured 29 %
    x = BANDWIDTH * times
    design = 1.0 - np.exp(-x) * (1.0 + x - x * x)
    assert np.abs(path - 0.3 * design).max() <= 0.2 * 0.3  # measured 16 %: the filter's slew at the start


@pytest.mark.parametrize("seconds", [0.6, 0.606])
def test_a_run_with_contacts_restored_from_a_checkpoint_continues_bit_for_bit(tmp_path: Path, seconds: float) -> None:
    """The contact inertia is computed from the state alone, at every tick: a new world and service restored
    mid-run (at 0.6 s, and 6 ms after) from the snapshot through JSON end exactly where the uninterrupted run
    does. (Issue 41: holding it for 4 or 10 ms windows made gymnasium's walker2d miss its targets in
    bench/mjcf_gravity.py, so it is not held.)"""
    import mujoco

    from simrun import Ground

    (tmp_path / "m.xml").write_text(ROLLER)

    def build() -> tuple[World, JointService]:
        world = World(base_dir=tmp_path)
        world.insert(Ground(name="ground"))
        world.insert(MjcfRobot(name="m", file="m.xml"))
        return world, JointService(world, "m")

    world, service = build()
    service.set_positions(["roll"], [0.5])
    world.run(seconds)
    kind = mujoco.mjtState.mjSTATE_INTEGRATION
    saved = np.zeros(mujoco.mj_stateSize(world.model, kind))
    mujoco.mj_getState(world.model, world.data, saved, kind)
    snap = json.loads(json.dumps(service.snapshot()))  # as a checkpoint file carries it
    world.run(1.0)
    again, restored = build()
    mujoco.mj_setState(again.model, again.data, saved, kind)
    restored.restore(snap)
    again.run(1.0)
    np.testing.assert_array_equal(again.data.qpos, world.data.qpos)
