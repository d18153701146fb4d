"""Drive-stack overhead: the Boe-Bot scene with services and sensors vs raw mj_step on the same model.

Usage: python bench/drive.py . [--repeat 5] [--out docs/benchmarks.md]   (no corpus needed; pass any path)

Contenders, 5 simulated seconds each on a freshly compiled copy of the scene, interleaved for --repeat
rounds, process CPU and wall-clock (issue 28: every contender measured the same way):
  * raw, single: a Python loop of ``mujoco.mj_step(model, data)``, controls held constant;
  * raw, batched: ``mujoco.mj_step(model, data, nstep=N)``;
  * full, single: the full stack driven by ``world.step()`` once per physics step (a user's own loop);
  * full, batched: ``world.step(N)`` with the DriveService (cmd_vel, odometry), a bumper, encoders at
    50 Hz, GPS at 10 Hz and a 360-ray laser at 10 Hz;
  * laser only, batched: ``world.step(N)`` with just the 360-ray laser at 10 Hz.
Each controller's own cost per tick is measured with ``timeit`` on its ``tick`` in the same run.

Robots (issue 41 item 4): 1, 4 and 16 Boe-Bots, each with the full stack, ``world.step(N)`` against
``mj_step(nstep=N)`` on the same model (goal <= 1.2x at every count), interleaved in the same rounds; the
lasers' own ray casts (``mj_multiRay`` on the compiled model, timed with ``timeit``) give the floor no Python
can go below.

Walkers (issue 41 item 4): gymnasium's ``humanoid.xml`` and ``ant.xml`` (from the bench environment
``.bench-mjcf/`` that ``bench/mjcf_robots.py --install`` installs, as ``make bench`` does; skipped when it is
missing) as an ``MjcfRobot`` on a ground, the world's timestep 2 ms, 5 s in one ``world.step(N)`` with a
``JointService`` (500 Hz, holding the initial pose) against ``mj_step(nstep=N)`` on the same compiled model
(goal <= 1.1x).
"""

from __future__ import annotations

import cProfile
import functools
import platform
import pstats
import sys
import time
import timeit
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from _report import Timing, arguments, interleave, load_average, write_section

from simrun import Box, Ground, Pose, World
from simrun.robots.catalogue import BoeBot
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.robot_state import GPS, Bumper, Encoders
from simrun.services.drive_service import DriveService
from simrun.services.joint_loops import Scratch
from simrun.services.joint_service import JointService

BEGIN, END = "<!-- drive:begin -->", "<!-- drive:end -->"
ROBOTS_BEGIN, ROBOTS_END = "<!-- drive-robots:begin -->", "<!-- drive-robots:end -->"
SECONDS = 5.0
ROBOTS = (1, 4, 16)
#: Goal of issue 41: the full stack's CPU over raw ``mj_step(nstep)`` on the same model, at every robot count.
ROBOTS_GOAL = 1.2


def _robot(k: int) -> str:
    return "bot" if k == 0 else f"bot{k}"


def scene(robots: int = 1) -> World:
    """Ground, ``robots`` Boe-Bots 0.5 m apart on a 4-wide grid (the first at (1, 1)) and a free box."""
    world = World()
    world.insert(Ground(name="ground"))
    for k in range(robots):
        world.insert(BoeBot(name=_robot(k), pose=Pose((1 - 0.5 * (k // 4), 1 - 0.5 * (k % 4), 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=5.0, free=True, pose=Pose((2.5, 1, 0.1))))
    return world


def full_stack(world: World, robot: str = "bot") -> dict[str, object]:
    """The services and sensors of the full stack on ``robot``, bound to ``world`` (compiled), by name."""
    drive = DriveService(world, robot)
    parts = {
        "drive service": drive,
        "bumper": Bumper(world, robot),
        "encoders 50 Hz": Encoders(world, robot, rate=50),
        "GPS 10 Hz": GPS(world, robot, rate=10),
        "360-ray laser 10 Hz": LaserRangeFinder(world, robot, fov_deg=360, rays=360, rate=10),
    }
    drive.limits = drive.limits.__class__(command_timeout=10.0)
    drive.cmd_vel(0.1, 0.2)
    return parts


def robots_run(robots: int, full: bool) -> Callable[[], tuple[float, float]]:
    """``robots`` Boe-Bots, 5 s in one ``world.step(N)`` with the full stack on each, or raw ``nstep=N``."""

    def run() -> tuple[float, float]:
        world = scene(robots)
        model, data = world.compile()
        if full:
            for k in range(robots):
                full_stack(world, _robot(k))
        else:
            data.ctrl[:] = 0.5
        steps = round(SECONDS / world.options.timestep)
        cpu, wall = time.process_time(), time.perf_counter()
        if full:
            world.step(steps)
        else:
            mujoco.mj_step(model, data, nstep=steps)
        return time.perf_counter() - wall, time.process_time() - cpu

    return run


WALKERS_GOAL = 1.1
GYM = Path(".bench-mjcf/lib/python3.11/site-packages/gymnasium/envs/mujoco/assets")
WALKERS = {"humanoid": GYM / "humanoid.xml", "ant": GYM / "ant.xml"}


def walker_world(path: Path) -> World:
    """The model as ``robot`` (its own free root) on a ground."""
    world = World(base_dir=path.parent)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="robot", file=path.name))
    return world


class Idle:
    """A controller that does nothing at 500 Hz: what ``world.step(N)`` costs around a tick of that rate."""

    def __init__(self, world: World) -> None:
        self.next_time, self.period = world.time, 0.002
        world.controllers.append(self)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Nothing."""


def walker_run(path: Path, service: bool, idle: bool = False) -> Callable[[], tuple[float, float]]:
    """5 s of the walker: ``world.step(N)`` with a ``JointService`` holding its pose (or, ``idle``, with an
    :class:`Idle` controller at the same rate), or raw ``nstep=N``."""

    def run() -> tuple[float, float]:
        world = walker_world(path)
        model, data = world.compile()
        if service:
            JointService(world, "robot")
        elif idle:
            Idle(world)
        steps = round(SECONDS / world.options.timestep)
        cpu, wall = time.process_time(), time.perf_counter()
        if service or idle:
            world.step(steps)
        else:
            mujoco.mj_step(model, data, nstep=steps)
        return time.perf_counter() - wall, time.process_time() - cpu

    return run


def split_seconds(robots: int) -> tuple[float, float, float]:
    """One more full-stack run under ``cProfile`` (process CPU): the seconds in ``mj_step`` (the physics of the
    stack's own motion), in ``mj_multiRay`` and in everything else (Python: controllers and the step loop,
    profiler overhead included)."""
    world = scene(robots)
    world.compile()
    for k in range(robots):
        full_stack(world, _robot(k))
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    world.step(round(SECONDS / world.options.timestep))
    profile.disable()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    total = sum(v[2] for v in stats.values())  # tottime over every function: the run's profiled CPU

    def of(name: str) -> float:
        return float(sum(v[2] for k, v in stats.items() if k[2] == f"<built-in method mujoco._functions.{name}>"))

    physics, rays = of("mj_step"), of("mj_multiRay")
    return physics, rays, float(total) - physics - rays


def walker_split(path: Path) -> tuple[float, float, float, float, float]:
    """One more walker run with its ``JointService`` under ``cProfile`` (process CPU): seconds in ``mj_step``,
    in ``JointService.tick`` (cumulative), in its contact inertia (``joint_inertia.with_contacts``), in its
    feed-forward forces (``joint_loops.Scratch.feed_forward``) and in the numpy LAPACK wrappers the contact
    inertia calls (``numpy.linalg``'s ``solve``, ``eigvalsh``)."""
    world = walker_world(path)
    world.compile()
    JointService(world, "robot")
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    world.step(round(SECONDS / world.options.timestep))
    profile.disable()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]

    def cumulative(file: str, name: str) -> float:
        return float(sum(v[3] for k, v in stats.items() if k[0].endswith(file) and k[2] == name))

    physics = float(sum(v[2] for k, v in stats.items() if k[2] == "<built-in method mujoco._functions.mj_step>"))
    lapack = cumulative("_linalg.py", "solve") + cumulative("_linalg.py", "eigvalsh")
    return (
        physics,
        cumulative("joint_service.py", "tick"),
        cumulative("joint_inertia.py", "with_contacts"),
        cumulative("joint_loops.py", "feed_forward"),
        lapack,
    )


def walker_tick(path: Path) -> dict[str, float]:
    """What one ``JointService`` tick of the walker costs and what it is made of, over the states of a run.

    The walker is held for :data:`SECONDS` by its service (one tick per 2 ms step) and every tick's state
    (``qpos``, ``qvel``) kept; then, state by state (each set into the data first), best of 3 passes of
    process CPU, in microseconds per tick: ``tick``, the service's ``tick``; ``mujoco``, the MuJoCo calls a
    tick makes, in its order: the scratch data posed (``mj_kinematics``, ``mj_comPos``, ``mj_tendon``,
    ``mj_comVel``, ``mj_passive``, ``mj_rne``: :meth:`~simrun.services.joint_loops.Scratch.feed_forward`
    itself, with its one vector subtraction), the contacts' rows (``mj_collision``, ``mj_makeConstraint``),
    the mass matrix (``mj_crb``, ``mj_factorM``) and ``mj_solveM`` of those rows; setting the state alone is
    taken off both. ``calls``: Python and C function calls per tick (cProfile's count over the states).
    ``joints``: the actuators (one per driven joint); ``rows``: mean constraint rows per state. ``raw``: one
    physics step (``mj_step`` in the same states), us.
    """
    world = walker_world(path)
    model, data = world.compile()
    service = JointService(world, "robot")
    states = []
    for _ in range(round(SECONDS / world.options.timestep)):
        states.append((data.qpos.copy(), data.qvel.copy()))
        world.step(1)
    scratch = Scratch(model)
    work = scratch.data
    rows: list[int] = []

    def pose() -> None:
        for qpos, qvel in states:
            data.qpos[:] = qpos
            data.qvel[:] = qvel

    def ticks() -> None:
        for qpos, qvel in states:
            data.qpos[:] = qpos
            data.qvel[:] = qvel
            service.tick(model, data)

    def calls_in_c() -> None:
        for qpos, qvel in states:
            data.qpos[:] = qpos
            data.qvel[:] = qvel
            scratch.feed_forward(data)  # the scratch data posed, as the tick poses it
            mujoco.mj_collision(model, work)
            mujoco.mj_makeConstraint(model, work)
            mujoco.mj_crb(model, work)
            mujoco.mj_factorM(model, work)
            count = int(work.nefc)
            if len(rows) < len(states):
                rows.append(count)
            jac = work.efc_J[: count * model.nv].reshape(count, model.nv)
            mujoco.mj_solveM(model, work, np.empty((count, model.nv)), jac)

    stepped = mujoco.MjData(model)

    def steps() -> None:
        for qpos, qvel in states:
            stepped.qpos[:] = qpos
            stepped.qvel[:] = qvel
            mujoco.mj_step(model, stepped)

    def best(run: Callable[[], None]) -> float:
        found = []
        for _ in range(3):
            cpu = time.process_time()
            run()
            found.append(time.process_time() - cpu)
        return min(found) / len(states) * 1e6

    posing = best(pose)
    tick, in_c, raw = best(ticks) - posing, best(calls_in_c) - posing, best(steps)
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    for qpos, qvel in states:
        data.qpos[:] = qpos
        data.qvel[:] = qvel
        service.tick(model, data)
    profile.disable()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    return {
        "tick": tick,
        "mujoco": in_c,
        "calls": sum(v[1] for v in stats.values()) / len(states),
        "joints": float(model.nu),
        "rows": sum(rows) / len(rows),
        "raw": raw,
    }


def cast_seconds(robots: int) -> float:
    """CPU seconds of the lasers' own ``mj_multiRay`` calls over the 5 s run (10 Hz each), on the compiled model."""
    world = scene(robots)
    model, data = world.compile()
    lasers = [full_stack(world, _robot(k))["360-ray laser 10 Hz"] for k in range(robots)]
    world.step(1)
    calls = []
    for laser in lasers:
        assert isinstance(laser, LaserRangeFinder)
        body = laser.caster.bind(model)
        rotation = data.xmat[body].reshape(3, 3)
        origin = data.xpos[body] + rotation[:, 2] * laser.mount_height(model)
        directions = (laser._local @ rotation.T).ravel()
        geomid, dist = np.zeros(len(laser.angles), np.int32), np.zeros(len(laser.angles))
        calls.append((origin, directions, body, geomid, dist, laser.max_range))

    def cast_all() -> None:
        for origin, directions, body, geomid, dist, cutoff in calls:
            mujoco.mj_multiRay(model, data, origin, directions, None, 1, body, geomid, dist, None, len(dist), cutoff)

    n = 200
    per_tick = min(timeit.repeat(cast_all, timer=time.process_time, number=n, repeat=3)) / n
    return per_tick * round(SECONDS * 10)


def world_run(kind: str, single: bool) -> Callable[[], tuple[float, float]]:
    def run() -> tuple[float, float]:
        world = scene()
        _, data = world.compile()
        if kind == "full":
            full_stack(world)
        else:
            LaserRangeFinder(world, "bot", fov_deg=360, rays=360, rate=10)
            data.ctrl[:] = 0.5  # the same motion as the raw loop
        steps = round(SECONDS / world.options.timestep)
        step = world.step
        cpu, wall = time.process_time(), time.perf_counter()
        if single:
            for _ in range(steps):
                step()
        else:
            step(steps)
        return time.perf_counter() - wall, time.process_time() - cpu

    return run


def raw_run(single: bool) -> Callable[[], tuple[float, float]]:
    def run() -> tuple[float, float]:
        world = scene()
        model, data = world.compile()
        data.ctrl[:] = 0.5
        steps = round(SECONDS / world.options.timestep)
        cpu, wall = time.process_time(), time.perf_counter()
        if single:
            for _ in range(steps):
                mujoco.mj_step(model, data)
        else:
            mujoco.mj_step(model, data, nstep=steps)
        return time.perf_counter() - wall, time.process_time() - cpu

    return run


def tick_costs() -> dict[str, float]:
    """Microseconds per ``tick`` of each controller of the full stack, and of one physics step."""
    world = scene()
    model, data = world.compile()
    costs = {}
    for name, part in full_stack(world).items():
        tick = part.tick  # type: ignore[attr-defined]
        n = 2000
        calls = timeit.repeat(functools.partial(tick, model, data), timer=time.process_time, number=n, repeat=3)
        costs[name] = min(calls) / n * 1e6
    costs["physics step (mj_step)"] = min(
        timeit.repeat(lambda: mujoco.mj_step(model, data), timer=time.process_time, number=2000, repeat=3)
    )
    costs["physics step (mj_step)"] *= 1e6 / 2000
    return costs


def main() -> int:
    args = arguments(__doc__, 5)
    before = load_average()
    contenders = {
        "raw single": raw_run(single=True),
        "full single": world_run("full", single=True),
        "raw batched": raw_run(single=False),
        "full batched": world_run("full", single=False),
        "laser batched": world_run("laser", single=False),
    }
    for n in ROBOTS:
        contenders[f"raw {n} robots"] = robots_run(n, full=False)
        contenders[f"full {n} robots"] = robots_run(n, full=True)
    walkers = [name for name, path in WALKERS.items() if path.exists()]
    for name in walkers:
        contenders[f"raw {name}"] = walker_run(WALKERS[name], service=False)
        contenders[f"service {name}"] = walker_run(WALKERS[name], service=True)
        contenders[f"idle {name}"] = walker_run(WALKERS[name], service=False, idle=True)
    results = interleave(contenders, args.repeat)
    costs = tick_costs()
    casts = {n: cast_seconds(n) for n in ROBOTS}
    splits = {n: split_seconds(n) for n in ROBOTS}
    walker_splits = {name: walker_split(WALKERS[name]) for name in walkers}
    walker_ticks = {name: walker_tick(WALKERS[name]) for name in walkers}
    steps = round(SECONDS / 0.002)
    write_section(args.out, section(results, costs, steps, args.repeat, before), BEGIN, END)
    text = robots_section(results, casts, splits, walker_splits, walker_ticks, steps, args.repeat, before)
    write_section(args.out, text, ROBOTS_BEGIN, ROBOTS_END)
    for name, t in results.items():
        print(f"{name}: {steps / t.cpu_median:.0f} steps/s (CPU median)")
    return 0


def robots_section(
    results: dict[str, Timing],
    casts: dict[int, float],
    splits: dict[int, tuple[float, float, float]],
    walker_splits: dict[str, tuple[float, float, float, float, float]],
    walker_ticks: dict[str, dict[str, float]],
    steps: int,
    repeat: int,
    before: str,
) -> str:
    lines = [
        ROBOTS_BEGIN,
        "## Drive stack over 1, 4 and 16 robots",
        "",
        f"`python bench/drive.py . --repeat {repeat}` (part of `make bench`, the same rounds as the block above): "
        f"N Boe-Bots, each with the drive service (cmd_vel, odometry), a bumper, encoders 50 Hz, GPS 10 Hz and "
        f"a 360-ray laser 10 Hz, {SECONDS:g} simulated seconds ({steps} steps) in one `world.step(N)`, against "
        "`mujoco.mj_step(model, data, nstep=N)` on the same model with the controls held. Process CPU, min / "
        "median of the rounds; ratio of medians. *Cast floor*: the lasers' own `mj_multiRay` calls (one per "
        "laser per tick, the same origins and 360 directions, timed with `timeit` on the compiled model) added "
        "to the raw loop's time, over the raw loop: the ratio no Python could go below while the lasers see "
        "what they see. *Where the stack's time goes*: one more run under `cProfile` (process CPU): seconds in "
        "`mj_step` (the physics of the motion the stack commands: the raw loop holds its controls, so it drives "
        "otherwise) and in `mj_multiRay`; the rest is the full stack's median less both (Python: controllers and "
        f"the step loop). {before} before, {load_average()} after the run; Python bytecode: "
        f"{'not written (PYTHONDONTWRITEBYTECODE)' if sys.flags.dont_write_bytecode else '.pyc present'}.",
        "",
        "| robots | raw CPU min / median s | full stack CPU min / median s | lasers' casts s | full / raw | "
        f"cast floor | goal <= {ROBOTS_GOAL:g}x | mj_step / mj_multiRay / rest s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for n in ROBOTS:
        raw, full = results[f"raw {n} robots"], results[f"full {n} robots"]
        ratio = full.cpu_median / raw.cpu_median
        floor = (raw.cpu_median + casts[n]) / raw.cpu_median
        met = "met" if ratio <= ROBOTS_GOAL else f"short by {ratio / ROBOTS_GOAL:.2f}x"
        lines.append(
            f"| {n} | {raw.cpu_min:.3f} / {raw.cpu_median:.3f} | {full.cpu_min:.3f} / {full.cpu_median:.3f} | "
            f"{casts[n]:.3f} | {ratio:.2f}x | {floor:.2f}x | {met} | "
            f"{splits[n][0]:.3f} / {splits[n][1]:.3f} / {full.cpu_median - splits[n][0] - splits[n][1]:.3f} |"
        )
    big = max(ROBOTS)
    raw_s, full_s = results[f"raw {big} robots"].cpu_median, results[f"full {big} robots"].cpu_median
    physics, rays = splits[big][0], splits[big][1]
    per_tick = (full_s - physics - rays) / big / round(SECONDS * 50) * 1e6
    lines += [
        "",
        f"Why it falls short, at {big} robots (from the columns above, in units of the raw loop's time): full / "
        f"raw {full_s / raw_s:.2f} = the physics of the motion the stack commands {physics / raw_s:.2f} + the "
        f"lasers' `mj_multiRay` {rays / raw_s:.2f} (each of the {big * 360} rays per tick is tested against "
        "every geom in range: MuJoCo's own cost, the same whatever calls it) + the Python of the controllers and "
        f"the step loop {(full_s - physics - rays) / raw_s:.2f} ({per_tick:.0f} us per robot per 50 Hz tick, for "
        "its drive service, bumper and encoders at 50 Hz and GPS and laser at 10 Hz). Every "
        "laser is already one `mj_multiRay` per tick (one origin per call: MuJoCo has no call for rays of many "
        "origins), the controllers' schedule is scanned once per tick, not per step, and the physics between "
        "ticks runs inside one `mj_step(nstep)`.",
    ]
    walkers = list(walker_splits)
    lines += [
        "",
        "gymnasium's walkers (`MjcfRobot` of `gymnasium/envs/mujoco/assets/*.xml`, the world's 2 ms step) with a "
        "`JointService` at 500 Hz holding the initial pose, 5 s in one `world.step(N)`, against "
        "`mj_step(model, data, nstep=N)` on the same compiled model (the same rounds):",
        "",
        "| model | raw CPU min / median s | with JointService CPU min / median s | ratio | "
        f"goal <= {WALKERS_GOAL:g}x | idle 500 Hz controller CPU median s (ratio) | service us per tick |",
        "|---|---|---|---|---|---|---|",
    ]
    ticks = round(SECONDS / 0.002)
    for name in walkers:
        raw, full, idle = results[f"raw {name}"], results[f"service {name}"], results[f"idle {name}"]
        ratio = full.cpu_median / raw.cpu_median
        met = "met" if ratio <= WALKERS_GOAL else f"short by {ratio / WALKERS_GOAL:.2f}x"
        per_tick = (full.cpu_median - idle.cpu_median) / ticks * 1e6
        lines.append(
            f"| {name} | {raw.cpu_min:.3f} / {raw.cpu_median:.3f} | {full.cpu_min:.3f} / {full.cpu_median:.3f} | "
            f"{ratio:.2f}x | {met} | {idle.cpu_median:.3f} ({idle.cpu_median / raw.cpu_median:.2f}x) | "
            f"{per_tick:.0f} |"
        )
    if not walkers:
        lines.append(
            "| (skipped: `.bench-mjcf/` not installed; `python bench/mjcf_robots.py --install` installs it) |||||||"
        )
    lines += [
        "",
        "*Idle*: `world.step(N)` with a controller that does nothing at 500 Hz (the same rounds): the step loop's "
        "own cost around a tick every step, which no service can go below. *Service us per tick*: (service "
        f"median - idle median) / {ticks} ticks.",
    ]
    for name, (physics, tick, contacts, feed, lapack) in walker_splits.items():
        lines.append(
            f"\n{name}, profiled (cProfile, its overhead included): `mj_step` {physics:.3f} s, `JointService.tick` "
            f"{tick:.3f} s, of which the contact inertia `joint_inertia.with_contacts` {contacts:.3f} s (its "
            f"`numpy.linalg` solve and eigvalsh {lapack:.3f} s) and the feed-forward forces "
            f"`joint_loops.Scratch.feed_forward` {feed:.3f} s; the rest is the control laws' array arithmetic "
            "(`joint_loops.Layout.controls`) and the tick's bookkeeping."
        )
    for name, t in walker_ticks.items():
        rest = t["tick"] - t["mujoco"]
        _, tick_s, contacts_s, _, _ = walker_splits[name]
        share = contacts_s / tick_s
        allowed = (WALKERS_GOAL - 1.0) * t["raw"]
        room = (
            "less than MuJoCo's own calls take"
            if t["mujoco"] >= allowed
            else f"{allowed - t['mujoco']:.0f} us beyond MuJoCo's own calls"
        )
        lines.append(
            f"\n{name}, a tick over the run's {ticks} states (each set into the data, then ticked; best of 3 "
            f"passes): {t['tick']:.0f} us, of which MuJoCo's own calls {t['mujoco']:.0f} us (the scratch data "
            f"posed, the contacts' constraint rows, {t['rows']:.0f} per state on average, the mass matrix factored "
            f"and solved for them); the other {rest:.0f} us are {t['calls']:.0f} Python and numpy calls per tick "
            f"(cProfile's count) on arrays of {t['joints']:.0f} actuated joints, {rest / t['calls']:.2f} us each. "
            f"The goal leaves a tick {allowed:.0f} us ({WALKERS_GOAL - 1.0:.1f} x one `mj_step` of these states, "
            f"{t['raw']:.0f} us): {room}. Per joint the laws are a few vector operations: a tick costs numpy's "
            "price per call on arrays this small, and the contact inertia (issue 37: the joints' inertia with "
            f"what their contacts hold) is {share:.0%} of the tick in the profile above."
        )
    lines.append(ROBOTS_END)
    return "\n".join(lines)


def section(results: dict[str, Timing], costs: dict[str, float], steps: int, repeat: int, before: str) -> str:
    def row(label: str, name: str, base: str, goal: float | None) -> str:
        t, b = results[name], results[base]
        ratio = b.cpu_median / t.cpu_median
        met = "" if goal is None else "met" if ratio >= goal else f"short: {ratio:.3f}x of {goal:g}x"
        return (
            f"| {label} | {steps / t.cpu_median:.0f} | {t.cpu_min:.3f} / {t.cpu_median:.3f} | "
            f"{t.wall_min:.3f} / {t.wall_median:.3f} | {ratio:.3f} | {met} |"
        )

    per_step = sum(v for k, v in costs.items() if not k.startswith("physics"))
    lines = [
        BEGIN,
        "## Drive stack: services and sensors vs raw mj_step",
        "",
        f"`python bench/drive.py . --repeat {repeat}` (part of `make bench`): the Boe-Bot scene, {SECONDS:g} "
        f"simulated seconds ({steps} steps) on a freshly compiled copy each time; the five loops interleaved, "
        f"{repeat} rounds; seconds as min / median of process CPU and of wall-clock; ratios of median CPU to "
        f"the raw loop of the same kind. Machine: {platform.machine()}, CPython {platform.python_version()}, "
        f"MuJoCo {mujoco.__version__}; {before} before, {load_average()} after the run.",
        "",
        "| loop | steps/s (CPU) | CPU min / median s | wall min / median s | ratio to raw | goal >= 0.85x |",
        "|---|---|---|---|---|---|",
        row("raw `mujoco.mj_step`, one call per step", "raw single", "raw single", None),
        row(
            "full stack, `world.step()` once per physics step (vs the loop of single `mj_step` calls)",
            "full single",
            "raw single",
            0.85,
        ),
        row("raw `mujoco.mj_step(model, data, nstep=N)`", "raw batched", "raw batched", None),
        row(
            "full stack, `world.step(N)`: drive service (cmd_vel, odometry) + bumper + encoders 50 Hz + GPS 10 Hz "
            "+ 360-ray laser 10 Hz (vs `nstep=N`)",
            "full batched",
            "raw batched",
            0.85,
        ),
        row("`world.step(N)` with the 360-ray laser 10 Hz only (vs `nstep=N`)", "laser batched", "raw batched", None),
        "",
        "Each controller's `tick`, measured with `timeit` in the same run (best of 3 x 2,000 calls, process CPU), "
        "microseconds:",
        "",
        "| controller | us per tick |",
        "|---|---|",
        *(f"| {name} | {value:.2f} |" for name, value in costs.items()),
        "",
        f"The controllers tick at their own rates; the ticks' sum ({per_step:.1f} us, if every controller ticked "
        "at once) is spread over the steps between them, and the steps between ticks run inside `mj_step`. The "
        "drive's motors are MuJoCo actuators (DC-motor gain and back-EMF bias): no Python runs per physics step "
        "except `World.step`'s check of when the next controller is due.",
        END,
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
