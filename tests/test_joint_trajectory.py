"""Trajectories (simrun/services/joint_trajectory.py, issue 42): times at least one timestep apart, at most
MAX_POINTS points, each point within its joint's range, and a lookup per tick that finds the segment the
definition gives (``times[k] <= s < times[k + 1]``, checked here by a linear scan, not by the code under test).
Ground truth for following: MuJoCo's ``data.qpos`` at the waypoints' times.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from simrun import EntityError, World
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.services.joint_service import JointService
from simrun.services.joint_trajectory import MAX_POINTS, Trajectory

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"


@pytest.fixture
def arm() -> tuple[World, JointService]:
    """The fixture MJCF arm (timestep 0.002 s, position servos, yaw within +-2.96 rad)."""
    world = World(base_dir=FIXTURES / "mjcf" / "arm")
    world.insert(MjcfRobot(name="arm", file="arm.xml"))
    return world, JointService(world, "arm")


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ([1e-300], r"times\[0\] = 1e-300 s is less than one timestep \(0.002 s\) from now"),
        ([0.5, 0.5], r"times\[1\] = 0.5 s is not after times\[0\] = 0.5 s: times must increase"),
        ([0.5, 0.4], r"times\[1\] = 0.4 s is not after times\[0\] = 0.5 s"),
        ([0.5, 0.501, 0.6], r"times\[1\] = 0.501 s is 0.001 s after times\[0\] = 0.5 s: .*one timestep \(0.002 s\)"),
        ([0.5, 0.5 + 1e-300], r"times\[1\] = 0.5 s is not after times\[0\]"),
        ([0.1, float("nan")], r"times\[1\] = nan: times must be positive finite seconds"),
        ([0.1, -1.0], r"times\[1\] = -1.0: times must be positive finite seconds"),
    ],
)
def test_times_closer_than_a_timestep_are_refused_naming_the_index(
    arm: tuple[World, JointService], times: list[float], message: str
) -> None:
    _, service = arm
    with pytest.raises(EntityError, match=f"^trajectory: {message}"):
        service.trajectory(["yaw"], times, [0.1] * len(times))
    assert not service.busy


def test_points_exactly_one_timestep_apart_are_followed(arm: tuple[World, JointService]) -> None:
    world, service = arm
    times = [0.002 * (k + 1) for k in range(500)]  # one point per step for 1 s, float sums included
    service.trajectory(["yaw"], times, [0.4 * t for t in times])
    world.run(1.5)
    assert not service.busy
    assert float(world.joint("arm/yaw").qpos[0]) == pytest.approx(0.4, abs=0.01)


def test_more_than_max_points_is_refused_before_anything_is_converted(arm: tuple[World, JointService]) -> None:
    _, service = arm
    count = MAX_POINTS + 1
    with pytest.raises(EntityError, match=f"^trajectory: {count} points; a trajectory has at most {MAX_POINTS} "):
        service.trajectory(["yaw"], [object()] * count, [0.0] * count)  # type: ignore[list-item]  # never read: refused by the count


def test_the_segment_of_every_tick_is_the_one_a_linear_scan_finds() -> None:
    """Forward ticks (the cursor), jumps back and ahead (binary search), points landed on exactly."""
    draw = random.Random(42)
    times = [0.0]
    for _ in range(2000):
        times.append(times[-1] + draw.choice([0.002, 0.003, 0.01, 0.5]))
    plan = Trajectory(0.0, times, ["j"], [[0.0]] * len(times))
    queries = [k * 0.002 for k in range(int(times[-1] / 0.002))]  # a 500 Hz clock
    queries += [draw.uniform(0.0, times[-1]) for _ in range(2000)]  # jumps
    queries += times[:-1]  # exactly on the points
    for s in queries:
        if s >= times[-1]:
            continue
        expected = max(i for i, t in enumerate(times) if t <= s)
        assert plan.segment(s) == expected, s


def test_a_long_trajectory_passes_its_points_on_time(arm: tuple[World, JointService]) -> None:
    """MAX_POINTS points, 2 ms apart (200 s): followed where it is at 1, 2 and 3 s (a ramp of 0.1 rad/s)."""
    world, service = arm
    times = [0.002 * (k + 1) for k in range(MAX_POINTS)]
    service.trajectory(["yaw"], times, [min(2.5, 0.1 * t) for t in times])
    for t in (1.0, 2.0, 3.0):
        world.run(t - world.time)
        assert float(world.joint("arm/yaw").qpos[0]) == pytest.approx(0.1 * t, abs=0.01)
    assert service.busy
