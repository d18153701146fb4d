"""Joint targets under gravity: bench/mjcf_robots.py's models and targets, with gravity, for 2 s (issue 37).

Each loadable model is put in as ``bench/mjcf_robots.py`` puts it (its ``scene`` with gravity -9.81 m/s^2,
its ``lift`` and root), its ``JointService`` (the default bandwidth unless ``--bandwidth``) commands that
script's target pose, and after ``--seconds`` (2) each commanded joint is judged as that script judges
"reached" (within 25 % of its step); a joint whose actuator ends at its control or force limit is counted
apart (saturated: a weak motor, not the loop). One line per model with commanded joints, then the totals.
This is a diagnostic (docs/robots.md, "Servos under load"), not a pass rate: a walker that falls over and
lands on its limbs is measured as it lies.

Usage: python bench/mjcf_gravity.py [--only TEXT] [--seconds S] [--bandwidth RAD_PER_S]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import mujoco

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import bench.mjcf_robots as bench  # noqa: E402
from simrun.services.joint_service import JointService  # noqa: E402


def judge(path: Path, seconds: float) -> tuple[int, int, int, list[str]] | None:
    """(commanded, off, off and not saturated, worst) of one model, or ``None`` without commanded joints."""
    world = bench.scene(path, -9.81, bench.lift(path))
    model, data = world.compile()
    service, joints, targets, steps = bench.run(world, seconds)
    if not joints:
        return None
    off, free, worst = 0, 0, []
    for name, target, step in zip(joints, targets, steps, strict=True):
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
    return len(joints), off, free, worst[:4]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--only", default="", help="models whose path contains this text")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--bandwidth", type=float, default=None, help="the service's bandwidth, rad/s")
    args = parser.parse_args()
    if args.bandwidth is not None:
        defaults = list(JointService.__init__.__defaults__ or ())
        defaults[1] = args.bandwidth
        JointService.__init__.__defaults__ = tuple(defaults)
    site = bench.site_packages()
    totals = [0, 0, 0, 0, 0]  # models, joints, off, off unsaturated, models with such
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
        joints, off, free, worst = found
        totals = [totals[0] + 1, totals[1] + joints, totals[2] + off, totals[3] + free, totals[4] + (free > 0)]
        print(f"{path.relative_to(site)}: {joints} joints, {off} off ({free} not saturated) {', '.join(worst)}")
    print(
        f"{totals[0]} models, {totals[1]} commanded joints: {totals[2]} off, {totals[3]} of them with the "
        f"actuator not at its limit, in {totals[4]} models"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
