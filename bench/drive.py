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
"""

from __future__ import annotations

import platform
import sys
import time
import timeit
from collections.abc import Callable

import mujoco
from _report import Timing, arguments, interleave, load_average, write_section

from simrun import Box, Ground, Pose, World
from simrun.robots.catalogue import BoeBot
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.robot_state import GPS, Bumper, Encoders
from simrun.services.drive_service import DriveService

BEGIN, END = "<!-- drive:begin -->", "<!-- drive:end -->"
SECONDS = 5.0


def scene() -> World:
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((1, 1, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=5.0, free=True, pose=Pose((2.5, 1, 0.1))))
    return world


def full_stack(world: World) -> dict[str, object]:
    """The services and sensors of the full stack, bound to ``world`` (compiled), by name."""
    drive = DriveService(world, "bot")
    parts = {
        "drive service": drive,
        "bumper": Bumper(world, "bot"),
        "encoders 50 Hz": Encoders(world, "bot", rate=50),
        "GPS 10 Hz": GPS(world, "bot", rate=10),
        "360-ray laser 10 Hz": LaserRangeFinder(world, "bot", fov_deg=360, rays=360, rate=10),
    }
    drive.limits = drive.limits.__class__(command_timeout=10.0)
    drive.cmd_vel(0.1, 0.2)
    return parts


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
        costs[name] = min(timeit.repeat(lambda tick=tick: tick(model, data), number=n, repeat=3)) / n * 1e6
    costs["physics step (mj_step)"] = min(timeit.repeat(lambda: mujoco.mj_step(model, data), number=2000, repeat=3))
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
    results = interleave(contenders, args.repeat)
    costs = tick_costs()
    steps = round(SECONDS / 0.002)
    write_section(args.out, section(results, costs, steps, args.repeat, before), BEGIN, END)
    for name, t in results.items():
        print(f"{name}: {steps / t.cpu_median:.0f} steps/s (CPU median)")
    return 0


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
        "Each controller's `tick`, measured with `timeit` in the same run (best of 3 x 2,000 calls), microseconds:",
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
