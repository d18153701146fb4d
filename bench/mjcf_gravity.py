"""Joint targets under gravity, judged after the robot has settled: bench/mjcf_robots.py's models (issue 37).

Each loadable model is put in as ``bench/mjcf_robots.py`` puts it (its ``scene`` with gravity -9.81 m/s^2,
its ``lift`` and root), its ``JointService`` (the default bandwidth unless ``--bandwidth``) commands that
script's target pose, and the world runs in 0.1 s steps until the robot is at rest: every one of its degrees
of freedom (root included) slower than ``SETTLED`` (0.05 rad/s or m/s) at each of the last ``QUIET`` (5)
samples, 0.5 s; at most ``--seconds`` (10 s). Then each commanded joint is judged as that script judges
"reached" against the simulator's ``qpos``: within 25 % of its step. A joint whose actuator ends at its
control or force limit is counted apart (saturated: the actuator cannot do more, the documented exception,
not the loop). A walker that falls over is judged where it comes to rest, on its limbs; a robot that never
comes to rest within the time is judged at the end and marked ``not settled``. The count at 2 s (the
earlier measure of this script, while walkers were still falling) is printed too.

One line per model with commanded joints, then the totals. A diagnostic (docs/robots.md, "Servos under
load"), not part of the bench's pass rate.

Usage: python bench/mjcf_gravity.py [--only TEXT] [--seconds S] [--bandwidth RAD_PER_S]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import bench.mjcf_robots as bench  # noqa: E402
from simrun.services.joint_service import JointService  # noqa: E402

SETTLED = 0.05  # rad/s or m/s: a degree of freedom slower than this is at rest
QUIET = 5  # consecutive 0.1 s samples at rest: settled
SAMPLE = 0.1  # s between samples
EARLY = 2.0  # s: the time the earlier measure judged at


@dataclass
class Judged:
    """One model's result: commanded joints, off and off-unsaturated at 2 s and after settling."""

    joints: int
    early: tuple[int, int]  # (off, off with the actuator not at its limit) at EARLY
    off: int
    free: int
    settled: float  # s, the time judged at (math.inf: not settled by the end)
    worst: list[str]


def _off(
    model: mujoco.MjModel, data: mujoco.MjData, service: JointService, rows: list[tuple[str, float, float]]
) -> tuple[int, int, list[str]]:
    """(off, off unsaturated, descriptions) of the commanded joints now."""
    off, free, worst = 0, 0, []
    for name, target, step in rows:
        drive = service._drives[name]
        error = abs(float(data.qpos[drive.qpos]) - target)
        if error <= 0.25 * abs(step):
            continue
        ctrl = float(data.ctrl[drive.actuator])
        saturated = math.isfinite(drive.high) and (ctrl >= drive.high - 1e-9 or ctrl <= drive.low + 1e-9)
        force = abs(float(data.actuator_force[drive.actuator]))
        if model.actuator_forcelimited[drive.actuator]:
            saturated |= force >= float(abs(model.actuator_forcerange[drive.actuator]).max()) - 1e-9
        off += 1
        free += not saturated
        worst.append(f"{name}[{drive.kind}] {error / abs(step):.2f}{' saturated' if saturated else ''}")
    return off, free, worst


def judge(path: Path, seconds: float) -> Judged | None:
    """One model under gravity (see the module), or ``None`` without commanded joints."""
    world = bench.scene(path, -9.81, bench.lift(path))
    model, data = world.compile()
    service, joints, targets, steps = bench.run(world, 0.0)
    if not joints:
        return None
    rows = list(zip(joints, targets, steps, strict=True))
    mine = [b for b in range(model.nbody) if model.body(b).name == "robot" or model.body(b).name.startswith("robot/")]
    dofs = np.flatnonzero(np.isin(model.dof_bodyid, mine))
    early = (0, 0)
    quiet, settled = 0, math.inf
    while world.time < seconds - 1e-9:
        world.run(SAMPLE)
        if abs(world.time - EARLY) < SAMPLE / 2:
            early = _off(model, data, service, rows)[:2]
        quiet = quiet + 1 if float(np.abs(data.qvel[dofs]).max(initial=0.0)) < SETTLED else 0
        if quiet >= QUIET and world.time >= EARLY - 1e-9:
            settled = world.time
            break
    off, free, worst = _off(model, data, service, rows)
    return Judged(len(joints), early, off, free, settled, worst[:4])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--only", default="", help="models whose path contains this text")
    parser.add_argument("--seconds", type=float, default=10.0, help="the longest a model runs before it is judged")
    parser.add_argument("--bandwidth", type=float, default=None, help="the service's bandwidth, rad/s")
    args = parser.parse_args()
    if args.bandwidth is not None:
        defaults = list(JointService.__init__.__defaults__ or ())
        defaults[1] = args.bandwidth
        JointService.__init__.__defaults__ = tuple(defaults)
    site = bench.site_packages()
    models = joints = off = free = with_free = early_free = early_models = unsettled = 0
    for kind, path, _ in bench.classify(site):
        if kind != "model" or args.only not in str(path):
            continue
        try:
            mujoco.MjModel.from_xml_path(str(path))
        except ValueError:
            continue
        found = judge(path, args.seconds)
        if found is None:
            continue
        models += 1
        joints += found.joints
        off, free, with_free = off + found.off, free + found.free, with_free + (found.free > 0)
        early_free, early_models = early_free + found.early[1], early_models + (found.early[1] > 0)
        unsettled += not math.isfinite(found.settled)
        when = f"settled at {found.settled:.1f} s" if math.isfinite(found.settled) else "not settled"
        print(
            f"{path.relative_to(site)}: {found.joints} joints, {when}: {found.off} off ({found.free} not "
            f"saturated) {', '.join(found.worst)}; at {EARLY:g} s {found.early[0]} off ({found.early[1]} not saturated)"
        )
    print(
        f"{models} models, {joints} commanded joints; after settling ({unsettled} not settled in {args.seconds:g} s): "
        f"{off} off, {free} of them with the actuator not at its limit, in {with_free} models; at {EARLY:g} s: "
        f"{early_free} not at the limit in {early_models} models"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
