"""URDF import on the real robots of ../shared/robots: import, compile, and compare with the URDF.

For every URDF in the manifest: ``meshtool urdf``'s library path (import, MJCF built, written and compiled
by the builder), then the written folder is loaded with ``MjModel.from_xml_path`` and compared with the
URDF itself, read by yourdfpy (an independent parser):

- moving joints: names, types (revolute/continuous -> hinge, prismatic -> slide) and limits;
- total mass: the sum of MuJoCo's body masses against the sum of the URDF's ``<inertial>`` masses;
- forward kinematics: every link's position and orientation, MuJoCo against yourdfpy, at random
  configurations inside the limits (mimic joints follow their leader in both).

Usage: python bench/urdf_robots.py [--robots ../shared/robots] [--configs 20] [--markdown docs table]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import yourdfpy

from meshtool.urdf.import_robot import UrdfOptions, import_urdf
from meshtool.urdf.write import write_import

ROOT = Path(__file__).resolve().parent.parent


def measure(robots: Path, entry: dict, configs: int, seed: int) -> dict:  # type: ignore[type-arg]
    urdf = robots / entry["urdf"]
    packages = tuple((name, robots / folder) for name, folder in entry.get("package_dirs", {}).items())
    started = time.perf_counter()
    result = import_urdf(urdf, UrdfOptions(package_dirs=packages))
    with tempfile.TemporaryDirectory() as tmp:
        write_import(result, Path(tmp))
        model = mujoco.MjModel.from_xml_path(str(Path(tmp) / f"{result.name}.xml"))
    seconds = time.perf_counter() - started
    robot = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True)
    moving = [j for j in robot.robot.joints if j.type in ("revolute", "continuous", "prismatic")]
    kinds = {"revolute": mujoco.mjtJoint.mjJNT_HINGE, "continuous": mujoco.mjtJoint.mjJNT_HINGE}
    kinds["prismatic"] = mujoco.mjtJoint.mjJNT_SLIDE
    names_ok = sorted(model.joint(j).name for j in range(model.njnt)) == sorted(j.name for j in moving)
    types_ok = names_ok and all(int(model.joint(j.name).type[0]) == int(kinds[j.type]) for j in moving)
    limits_ok, empty = True, []
    for j in moving:
        jid = model.joint(j.name).id
        if j.type == "continuous" or j.limit is None or j.limit.lower is None:
            limits_ok &= not model.jnt_limited[jid]
        elif j.limit.lower >= j.limit.upper:
            empty.append(j.name)  # [0, 0]: imported unlimited, with a warning
            limits_ok &= not model.jnt_limited[jid]
        else:
            limits_ok &= bool(model.jnt_limited[jid]) and list(model.jnt_range[jid]) == [j.limit.lower, j.limit.upper]
    urdf_mass = sum(float(link.inertial.mass) for link in robot.robot.links if link.inertial and link.inertial.mass)
    mjcf_mass = float(model.body_mass.sum())
    pos_err, rot_err = _fk(model, robot, moving, configs, seed)
    return {
        "id": entry["id"],
        "links": len(robot.robot.links),
        "moving": len(moving),
        "mimic": sum(1 for j in moving if j.mimic is not None),
        "meshes": len(result.mbins),
        "materials": int(model.nmat),
        "joints_ok": bool(types_ok),
        "limits_ok": bool(limits_ok),
        "empty_ranges": empty,
        "urdf_mass": urdf_mass,
        "mjcf_mass": mjcf_mass,
        "mass_diff": abs(urdf_mass - mjcf_mass),
        "fk_pos": pos_err,
        "fk_rot": rot_err,
        "warnings": sum(1 for f in result.findings if f.severity.value == "warning"),
        "seconds": seconds,
    }


def _fk(model: mujoco.MjModel, robot: yourdfpy.URDF, moving: list, configs: int, seed: int) -> tuple[float, float]:  # type: ignore[type-arg]
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    root = robot.base_link
    links = [link.name for link in robot.robot.links if link.name != "world"]
    worst_pos = worst_rot = 0.0
    for _ in range(configs):
        cfg: dict[str, float] = {}
        for j in moving:
            if j.mimic is not None:
                continue
            low, high = (-math.pi, math.pi)
            limited = j.type != "continuous" and j.limit is not None and j.limit.lower is not None
            if limited and j.limit.lower < j.limit.upper:
                low, high = float(j.limit.lower), float(j.limit.upper)
            cfg[j.name] = float(rng.uniform(low, high))
        robot.update_cfg(cfg)
        data.qpos[:] = 0
        for j in moving:
            value = cfg.get(j.name)
            if j.mimic is not None:
                value = float(j.mimic.offset or 0.0) + float(j.mimic.multiplier or 1.0) * cfg[j.mimic.joint]
            data.qpos[model.joint(j.name).qposadr[0]] = value
        mujoco.mj_kinematics(model, data)
        for link in links:
            expected = robot.get_transform(frame_to=link, frame_from=root)
            body = model.body(link).id
            worst_pos = max(worst_pos, float(np.abs(data.xpos[body] - expected[:3, 3]).max()))
            worst_rot = max(worst_rot, float(np.abs(data.xmat[body].reshape(3, 3) - expected[:3, :3]).max()))
    return worst_pos, worst_rot


def markdown(rows: list[dict]) -> str:  # type: ignore[type-arg]
    lines = [
        "| URDF | links | moving joints (mimic) | meshes | materials | joints | limits | mass URDF / MJCF (kg) "
        "| FK max error (m) | FK max rotation error | warnings |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        limits = "equal" if r["limits_ok"] else "DIFFER"
        if r["empty_ranges"]:
            limits += f" ({len(r['empty_ranges'])} empty [0, 0] -> unlimited)"
        lines.append(
            f"| {r['id']} | {r['links']} | {r['moving']} ({r['mimic']}) | {r['meshes']} | {r['materials']} "
            f"| {'equal' if r['joints_ok'] else 'DIFFER'} | {limits} | {r['urdf_mass']:.6g} / {r['mjcf_mass']:.6g} "
            f"| {r['fk_pos']:.1e} | {r['fk_rot']:.1e} | {r['warnings']} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=Path, default=ROOT.parent / "shared" / "robots")
    parser.add_argument("--configs", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="Also write the rows as JSON here.")
    args = parser.parse_args()
    manifest = json.loads((args.robots / "manifest.json").read_text())
    rows = []
    failures = 0
    for entry in manifest["urdfs"]:
        try:
            row = measure(args.robots, entry, args.configs, args.seed)
        except Exception as exc:  # report every robot, whatever fails
            print(f"{entry['id']}: FAILED: {exc}", file=sys.stderr)
            failures += 1
            continue
        ok = row["joints_ok"] and row["limits_ok"] and row["mass_diff"] <= 1e-9 * max(1.0, row["urdf_mass"])
        ok = ok and row["fk_pos"] <= 1e-6
        failures += not ok
        rows.append(row)
        print(f"{row['id']}: {'ok' if ok else 'MISMATCH'} ({row['seconds']:.1f} s)", file=sys.stderr)
    print(markdown(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"\n{len(manifest['urdfs']) - failures} of {len(manifest['urdfs'])} URDFs import, compile and match")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
