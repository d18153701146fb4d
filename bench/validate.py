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
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import trimesh
from _report import arguments, write_section

from meshtool.validate import ValidateOptions, discover, validate

BEGIN, END = "<!-- validate:begin -->", "<!-- validate:end -->"


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


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


def main() -> None:
    args = arguments(__doc__, 1)
    assets = [p for p, _ in discover([args.corpus])]
    objs = [p for p in assets if p.suffix.lower() == ".obj"]
    rows = []
    t_trimesh, _ = timed(lambda: trimesh_all(objs))
    t_mujoco, _ = timed(lambda: mujoco_all(objs))
    findings = None
    for label, executor, jobs, thumbs in (
        ("local, 1 worker", "local", 1, False),
        ("local, 2 workers", "local", 2, False),
        ("Dask LocalCluster, 2 workers", "dask", 2, False),
        ("local, 2 workers, HTML thumbnails", "local", 2, True),
    ):
        with tempfile.TemporaryDirectory() as cache:
            options = ValidateOptions(jobs=jobs, executor=executor, cache_dir=Path(cache), thumbnails=thumbs)
            cold, report = timed(lambda options=options: validate([args.corpus], options))
            warm, again = timed(lambda options=options: validate([args.corpus], options))
        assert again.cache_hits == len(assets) and again.checked == 0
        summary = [(a.path, [f.to_dict() for f in a.findings]) for a in report.assets]
        if findings is None:
            findings = summary
        assert summary == findings, f"{label}: findings differ from the first run"
        rows.append((label, cold, warm))
        print(f"{label}: cold {cold:.2f} s, warm {warm:.3f} s")
    counts = report.counts()
    by_rule: dict[str, int] = {}
    for a in report.assets:
        for f in a.findings:
            by_rule[f.code] = by_rule.get(f.code, 0) + 1
    histogram = ", ".join(f"{rule} {n}" for rule, n in sorted(by_rule.items()))
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
        f" MuJoCo {mujoco.__version__}, trimesh {trimesh.__version__}. `python bench/validate.py ../shared/corpus`.",
        "",
        f"Findings by rule: {histogram}.",
        "",
        "| configuration | cold s | warm s | cold / trimesh load | warm / trimesh load | cold / warm |",
        "|---|---|---|---|---|---|",
    ]
    for label, cold, warm in rows:
        lines.append(
            f"| {label} | {cold:.2f} | {warm:.3f} | {cold / t_trimesh:.1f}x | {warm / t_trimesh:.2f}x"
            f" | {cold / warm:.0f}x |"
        )
    lines += ["", END]
    write_section(args.out, "\n".join(lines), BEGIN, END)


if __name__ == "__main__":
    main()
