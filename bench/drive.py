"""Drive-stack overhead: the Boe-Bot scene with services and sensors vs raw mj_step on the same model.

Usage: python bench/drive.py [--repeat 3] [--out docs/benchmarks.md]   (no corpus needed; pass any path)

One run, same compiled model, 5 simulated seconds each, best of --repeat:
  * raw: ``mujoco.mj_step`` in a loop, controls held constant;
  * full: ``World.step`` with the DriveService (cmd_vel), a bumper, encoders at 50 Hz, odometry (part of the
    service, 50 Hz), GPS at 10 Hz, and a 360-ray laser at 10 Hz;
  * laser only: ``World.step`` with just the 360-ray laser at 10 Hz;
  * single steps: the same full stack driven by ``world.step()`` once per physics step (what a user's own
    loop does), against a Python loop of single ``mujoco.mj_step`` calls.
"""

from __future__ import annotations

import platform
import sys
import time

import mujoco
from _report import arguments, load_average, write_section

from simrun import Box, Ground, Pose, World
from simrun.drive import BoeBot
from simrun.drive_service import DriveService
from simrun.sensors import GPS, Bumper, Encoders, LaserRangeFinder

BEGIN, END = "<!-- drive:begin -->", "<!-- drive:end -->"
SECONDS = 5.0


def scene() -> World:
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((1, 1, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=5.0, free=True, pose=Pose((2.5, 1, 0.1))))
    return world


def timed_world(kind: str, single: bool = False) -> float:
    world = scene()
    _, data = world.compile()
    if kind == "full":
        drive = DriveService(world, "bot")
        Bumper(world, "bot")
        Encoders(world, "bot", rate=50)
        GPS(world, "bot", rate=10)
        LaserRangeFinder(world, "bot", fov_deg=360, rays=360, rate=10)
        drive.limits = drive.limits.__class__(command_timeout=10.0)
        drive.cmd_vel(0.1, 0.2)
    else:
        LaserRangeFinder(world, "bot", fov_deg=360, rays=360, rate=10)
    if kind != "full":
        data.ctrl[:] = 0.5  # the same motion as the raw loop
    steps = round(SECONDS / world.options.timestep)
    step = world.step
    start = time.perf_counter()
    if single:
        for _ in range(steps):
            step()
    else:
        step(steps)
    return time.perf_counter() - start


def timed_raw() -> float:
    world = scene()
    model, data = world.compile()
    data.ctrl[:] = 0.5
    steps = round(SECONDS / world.options.timestep)
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return time.perf_counter() - start


def main() -> int:
    args = arguments(__doc__, 3)
    # the loops take turns in every round (best of the rounds), so a busy machine slows them alike
    rounds = [
        (timed_raw(), timed_world("full"), timed_world("laser"), timed_world("full", single=True))
        for _ in range(args.repeat)
    ]
    raw, full, laser, single = (min(column) for column in zip(*rounds, strict=True))
    steps = round(SECONDS / 0.002)
    print(
        f"raw {steps / raw:.0f} steps/s, full {steps / full:.0f} ({raw / full:.3f}x), laser only {raw / laser:.3f}x, "
        f"full in single steps {steps / single:.0f} ({raw / single:.3f}x)"
    )
    section = "\n".join(
        [
            BEGIN,
            "## Drive stack: services and sensors vs raw mj_step",
            "",
            f"`python bench/drive.py . --repeat {args.repeat}`: the Boe-Bot scene, {SECONDS:g} simulated seconds "
            f"({steps} steps), best of {args.repeat}, one run. Machine: {platform.machine()}, CPython "
            f"{platform.python_version()}, MuJoCo {mujoco.__version__}.",
            "",
            "| loop | steps/s | ratio to raw mj_step |",
            "|---|---|---|",
            f"| raw `mujoco.mj_step` | {steps / raw:.0f} | 1.00 |",
            f"| World.step + drive service (cmd_vel, odometry) + bumper + encoders 50 Hz + GPS 10 Hz + 360-ray "
            f"laser 10 Hz | {steps / full:.0f} | {raw / full:.3f} |",
            f"| World.step + 360-ray laser 10 Hz only | {steps / laser:.0f} | {raw / laser:.3f} |",
            f"| the full stack, `world.step()` called once per physics step (vs the same loop of single "
            f"`mj_step` calls) | {steps / single:.0f} | {raw / single:.3f} |",
            "",
            "Targets: full stack >= 0.8x raw, also in single steps, the laser alone costing <= 5 %. The drive's "
            "motors are MuJoCo actuators (DC-motor gain and back-EMF bias), so no Python runs per physics step: "
            "controllers tick at their own rates and the steps between ticks run inside `mj_step`. In a loop of "
            "single steps, a step between ticks is one `mj_step` call behind a few comparisons: the world remembers "
            "when the next controller is due (`World.step`, `World.reschedule`). What remains is the controllers' "
            "own work: per tick, the 360-ray scan about 25 us (18 us of it MuJoCo's `mj_multiRay`), the drive "
            "service 2.3 us, the bumper 1.5 us, the encoders 1.2 us; about 1.1 us per physics step in all, plus "
            "0.2 us for the single-step check, against about 7 us for the physics of this scene (measured with "
            "`timeit` on each `tick`). The laser's ray casting alone is 5 % of the physics: a single-step loop has "
            "little room above 0.8x while it scans 360 rays at 10 Hz.",
            f"Load average at the time: {load_average()}.",
            END,
        ]
    )
    write_section(args.out, section, BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
