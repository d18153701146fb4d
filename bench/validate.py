"""Benchmark: meshtool validate over the corpus, cold and warm, 1 and 2 workers, local and Dask.

Peers in the same run, for scale: reading every OBJ with trimesh (``trimesh.load``, no checks at all) and
compiling every OBJ as a MuJoCo mesh (``MjSpec`` mesh from the file, what obj2mjcf relies on). Ratios are
validate's time over trimesh's.

Usage: python bench/validate.py ../shared/corpus [--out docs/benchmarks.md]
"""

from __future__ import annotations

import contextlib
import os
import platform
import resource
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import trimesh
from _report import Timing, arguments, load_average, write_section

from meshtool.validate import ValidateOptions, discover, validate

BEGIN, END = "<!-- validate:begin -->", "<!-- validate:end -->"


def timed(fn):
    """(wall s, CPU s of this process and its reaped children, result) of ``fn()``."""
    cpu = _cpu()
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, _cpu() - cpu, result


def _cpu() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def trimesh_all(objs: list[Path]) -> None:
    for path in objs:
        with contextlib.suppress(Exception):  # trimesh refuses some corpus files; the time still counts
            trimesh.load(path, force="mesh", process=False)


def mujoco_all(objs: list[Path]) -> None:
    for path in objs:
        spec = mujoco.MjSpec()
        spec.add_mesh(name="m", file=str(path.resolve()))
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
        with contextlib.suppress(ValueError):  # MuJoCo refuses some corpus files; the time still counts
            spec.compile()


CONFIGURATIONS = (
    ("local, 1 worker", "local", 1, False),
    ("local, 2 workers", "local", 2, False),
    ("Dask LocalCluster, 2 workers", "dask", 2, False),
    ("local, 2 workers, HTML thumbnails", "local", 2, True),
)


def main() -> None:
    args = arguments(__doc__, 5)
    assets = [p for p, _ in discover([args.corpus])]
    objs = [p for p in assets if p.suffix.lower() == ".obj"]
    before = load_average()
    t_trimesh, _, _ = timed(lambda: trimesh_all(objs))
    t_mujoco, _, _ = timed(lambda: mujoco_all(objs))
    findings = None
    cold: dict[str, Timing] = {label: Timing() for label, *_ in CONFIGURATIONS}
    warm: dict[str, Timing] = {label: Timing() for label, *_ in CONFIGURATIONS}
    for _ in range(args.repeat):  # the configurations take turns in every round
        for label, executor, jobs, thumbs in CONFIGURATIONS:
            with tempfile.TemporaryDirectory() as cache:
                options = ValidateOptions(jobs=jobs, executor=executor, cache_dir=Path(cache), thumbnails=thumbs)
                wall, cpu, report = timed(lambda options=options: validate([args.corpus], options))
                cold[label].add(wall, cpu)
                wall, cpu, again = timed(lambda options=options: validate([args.corpus], options))
                warm[label].add(wall, cpu)
            assert again.cache_hits == len(assets) and again.checked == 0
            summary = [(a.path, [f.to_dict() for f in a.findings]) for a in report.assets]
            if findings is None:
                findings = summary
            assert summary == findings, f"{label}: findings differ from the first run"
            print(f"{label}: cold {cold[label].wall[-1]:.2f} s, warm {warm[label].wall[-1]:.3f} s", flush=True)
    counts = report.counts()
    by_rule: dict[str, int] = {}
    for a in report.assets:
        for f in a.findings:
            by_rule[f.code] = by_rule.get(f.code, 0) + 1
    histogram = ", ".join(f"{rule} {n}" for rule, n in sorted(by_rule.items()))
    one = cold["local, 1 worker"].wall_median
    lines = [
        BEGIN,
        "## Validation: `meshtool validate` over the corpus",
        "",
        f"{len(assets)} assets ({len(objs)} OBJ) of `../shared/corpus`, every rule including the MuJoCo drop test;"
        f" {counts['error']} errors and {counts['warning']} warnings, identical in every configuration below."
        " *Cold*: empty cache; *warm*: the same command again (every result from the cache, which still hashes"
        " each asset and every file it depends on). Peers, same run: reading every OBJ with trimesh"
        f" ({t_trimesh:.2f} s, no checks) and compiling every OBJ as a MuJoCo mesh ({t_mujoco:.2f} s).",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()},"
        f" MuJoCo {mujoco.__version__}, trimesh {trimesh.__version__}. `python bench/validate.py ../shared/corpus"
        f" --repeat {args.repeat}` (part of `make bench`): the configurations interleaved, {args.repeat} rounds;"
        f" seconds as min / median; CPU is this process and its worker processes (Dask's workers are threads of"
        f" another process: not counted). {before} before, {load_average()} after: the speed-up of 2 workers"
        " needs 2 idle CPUs.",
        "",
        f"Findings by rule: {histogram}.",
        "",
        "| configuration | cold wall s | cold CPU s | warm wall s | cold wall / trimesh load | speed-up vs 1 worker"
        " (median wall) | goal |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, *_ in CONFIGURATIONS:
        c, w = cold[label], warm[label]
        speed = one / c.wall_median
        goal = ""
        if label == "local, 2 workers":
            goal = ">= 1.7x: met" if speed >= 1.7 else f">= 1.7x: short ({speed:.2f}x)"
        lines.append(
            f"| {label} | {c.wall_min:.2f} / {c.wall_median:.2f} | {c.cpu_min:.2f} / {c.cpu_median:.2f} | "
            f"{w.wall_min:.3f} / {w.wall_median:.3f} | {c.wall_median / t_trimesh:.1f}x | {speed:.2f}x | {goal} |"
        )
    lines += [
        "",
        "Workers take the largest assets first (`meshtool/validate/runner.py`, `largest_first`), so no worker is "
        "left alone with a large mesh at the end.",
        END,
    ]
    write_section(args.out, "\n".join(lines), BEGIN, END)


if __name__ == "__main__":
    main()
