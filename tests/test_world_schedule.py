"""World.step's single-step path: between controller ticks one ``world.step()`` is one ``mj_step``.

The world remembers when the next controller is due. These tests hold it to what the full scan does: the same
ticks at the analytic times (a controller at ``rate`` Hz ticks at 0, 1/rate, 2/rate ... s), the same states bit
for bit as batched ``world.step(n)``, and a controller that is added, swapped, restored to an earlier time or
overtaken by a time jump ticks on the very next step.
"""

import math

import mujoco
import numpy as np
import pytest
from test_drive import IDS, ROBOTS

from simrun import Box, Ground, Pose, World
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.robot_state import GPS, Bumper, Encoders
from simrun.services.drive_service import DriveService

SECONDS = 1.0


def stack(robot):
    """A robot with a drive command and sensors at 50 and 10 Hz (the drive benchmark's stack, 36 rays)."""
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(robot(name="r", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=5.0, free=True, pose=Pose((0.6, 0, 0.1))))
    world.compile()
    drive = DriveService(world, "r")
    sensors = [
        Bumper(world, "r"),
        Encoders(world, "r", rate=50),
        GPS(world, "r", rate=10, noise=0.01, seed=3),
        LaserRangeFinder(world, "r", height=0.05, fov_deg=360, rays=36, rate=10),
    ]
    drive.cmd_vel(0.2, 0.5)
    return world, drive, sensors


def state(world):
    data = world.data
    return data.time, data.qpos.copy(), data.qvel.copy(), data.ctrl.copy()


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_single_steps_tick_at_the_analytic_times_and_match_batched_steps(robot):
    single, drive, sensors = stack(robot)
    batched, _, batched_sensors = stack(robot)
    steps = round(SECONDS / single.options.timestep)
    times = {id(s): [] for s in sensors}
    for _ in range(steps):
        single.step()
        for s in sensors:
            if s.reading is not None and (not times[id(s)] or times[id(s)][-1] != s.reading.time):
                times[id(s)].append(s.reading.time)
    batched.step(steps)
    t1, q1, v1, c1 = state(single)
    t2, q2, v2, c2 = state(batched)
    assert t1 == t2 and np.array_equal(q1, q2) and np.array_equal(v1, v2) and np.array_equal(c1, c2)
    for s, b in zip(sensors, batched_sensors, strict=True):
        rate = s.rate
        expected = [k / rate for k in range(math.ceil(SECONDS * rate - 1e-9))]  # 0, 1/rate, ... < SECONDS
        assert s.samples == b.samples == len(expected), type(s).__name__
        assert times[id(s)] == pytest.approx(expected, abs=0.5 * single.options.timestep)
    assert drive.odometry().time == pytest.approx(SECONDS - 0.02, abs=1e-9)  # last 50 Hz tick before 1 s


def test_a_controller_added_between_single_steps_ticks_on_the_next_step():
    world, _, _ = stack(ROBOTS[0])
    for _ in range(7):  # 14 ms: between the 50 Hz ticks at 0 and 20 ms
        world.step()
    added_at = world.time
    gps = GPS(world, "r", rate=10)
    world.step()
    assert gps.samples == 1 and gps.reading.time == added_at
    # swap one controller for another: the list has the same length, the newcomer still ticks at once
    world.controllers.remove(gps)
    encoders = Encoders(world, "r", rate=50)
    swapped_at = world.time
    world.step()
    assert encoders.samples == 1 and encoders.reading.time == swapped_at


def test_a_controller_restored_to_an_earlier_clock_ticks_on_the_next_step():
    world, _, sensors = stack(ROBOTS[0])
    gps = sensors[2]
    world.step()  # GPS ticked at 0; next due at 0.1 s
    snap = gps.snapshot()
    for _ in range(5):
        world.step()
    assert gps.samples == 1
    snap["next_time"] = world.time  # due now, as a checkpoint taken at this time would say
    gps.restore(snap)
    world.step()
    assert gps.samples == 2


def test_time_moved_outside_the_world_is_noticed():
    world, _, sensors = stack(ROBOTS[0])
    encoders = sensors[1]
    for _ in range(3):
        world.step()
    assert encoders.samples == 1
    world.data.time += 0.05  # a user's jump past the next 50 Hz tick (20 ms)
    world.step()
    assert encoders.samples == 2  # the full scan ran and found the encoders due
    mujoco.mj_resetData(world.model, world.data)  # back to t = 0 behind the world's back: no tick is due
    before = encoders.samples
    world.step()
    assert encoders.samples == before and world.time == world.options.timestep


def test_reset_and_recompile_forget_the_schedule():
    world, _, sensors = stack(ROBOTS[0])
    encoders = sensors[1]
    for _ in range(3):
        world.step()
    world.reset()  # controllers back to next_time 0: they tick on the first step
    world.step()
    assert encoders.samples == 1
    world.insert(Box(name="extra", dimensions=(0.1, 0.1, 0.1), pose=Pose((-1, 0, 0.05))))  # a new model
    world.step()  # compiles the new model (time 0 again): every clock restarts, so the encoders sample at once
    assert world.time == world.options.timestep and encoders.samples == 2
    world.step(9)
    assert encoders.samples == 2  # next at 20 ms of the new model's time
    world.step()
    assert encoders.samples == 3


class ReadCountingController:
    """A controller (the registry's protocol, no mock) at 50 Hz that counts how often its schedule is read."""

    def __init__(self, world):
        self.period, self.ticks, self.reads, self._next = 0.02, 0, 0, world.time
        world.controllers.append(self)

    @property
    def next_time(self):
        self.reads += 1
        return self._next

    @next_time.setter
    def next_time(self, value):
        self._next = value

    def tick(self, model, data):
        self.ticks += 1

    def reset(self, model, data):
        self.ticks = 0

    def snapshot(self):
        return {"next_time": self._next}

    def restore(self, state):
        self._next = float(state["next_time"])


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_a_single_step_between_ticks_does_not_look_at_the_controllers(robot):
    world, _, _ = stack(robot)
    counter = ReadCountingController(world)
    world.step()  # t = 0: everything ticks, the schedule is remembered
    assert counter.ticks == 1
    steps_per_tick = round(counter.period / world.options.timestep)
    for _ in range(3):
        reads = counter.reads
        for _ in range(steps_per_tick - 1):  # the steps strictly between two ticks
            world.step()
        assert counter.reads == reads, "a step between ticks scanned the controllers"
        world.step()  # the tick
        assert counter.reads > reads
    assert counter.ticks == 4


class Hovering(Box):
    """A user's entity with a per-step hook: an upward force equal to its weight, so it hovers where it starts."""

    calls = 0

    def before_step(self, model, data):
        body = model.body(self.name).id
        data.xfrc_applied[body, 2] = -model.opt.gravity[2] * model.body_mass[body]
        Hovering.calls += 1


@pytest.mark.parametrize("single", [True, False], ids=["single steps", "batched"])
def test_entity_hooks_run_before_every_step_whatever_the_controllers(single):
    world, _, sensors = stack(ROBOTS[0])
    world.insert(Hovering(name="drone", dimensions=(0.1, 0.1, 0.1), mass=1.0, free=True, pose=Pose((-1, 0, 0.5))))
    sensors = [GPS(world, "r", rate=10), Encoders(world, "r", rate=50)]  # the world was rebuilt: new sensors
    Hovering.calls = 0
    steps = 250
    if single:
        for _ in range(steps):
            world.step()
    else:
        world.step(steps)
    assert Hovering.calls == steps
    assert world.body("drone").xpos[2] == pytest.approx(0.5, abs=1e-9)  # the simulator: it did not fall
    assert [s.samples for s in sensors] == [5, 25]  # 0.5 s at 10 and 50 Hz


def test_zero_steps_change_nothing_and_forget_nothing():
    world, _, sensors = stack(ROBOTS[0])
    encoders = sensors[1]
    world.step()
    world.step(0)
    for _ in range(9):
        world.step()
    assert encoders.samples == 1  # 0 to 18 ms: only the first tick
    world.step()
    assert encoders.samples == 2 and encoders.reading.time == pytest.approx(0.02)
