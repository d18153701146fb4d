"""Benchmark: meshtool validate over the corpus, cold and warm, 1 and 2 workers, local and Dask.

Peers in the same run, for scale: reading every OBJ with trimesh (``trimesh.load``, no checks at all) and
compiling every OBJ as a MuJoCo mesh (``MjSpec`` mesh from the file, what obj2mjcf relies on). Ratios are
validate's time over trimesh's.

A second section (``<!-- validate-growth:begin -->``) is the growth curve of issue 28: ``meshtool validate``
(the command, a fresh process, ``--no-cache``) over folders of 1, 10, 100 and 1,000 assets, with ``-j 1``
and ``-j 2``. The folders are built in a temporary folder from ten self-contained corpus OBJs (no MTL,
1.5 to 110 KB) cycled with distinct names, each copy given a distinct comment line so no two files hold
the same bytes; the corpus itself is only read.

Usage: python bench/validate.py ../shared/corpus [--repeat 2] [--max-assets 1000] [--out docs/benchmarks.md]
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import trimesh
from _report import Timing, arguments, command, interleave, load_average, write_section

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


# ------------------------------------------------------------------------------------ growth curve (issue 28)

GROWTH = (1, 10, 100, 1000)
GROWTH_BEGIN, GROWTH_END = "<!-- validate-growth:begin -->", "<!-- validate-growth:end -->"
#: Ten self-contained corpus OBJs (no mtllib), 1.5 to 110 KB, in the order the folders cycle through them.
GROWTH_ASSETS = (
    "src/alecjacobson__common-3d-test-models/data/suzanne.obj",
    "src/kevinzakka__mujoco_menagerie/bitcraze_crazyflie_2/assets/cf2_collision_0.obj",
    "src/tinyobjloader__tinyobjloader/models/catmark_torus_creases0.obj",
    "src/kevinzakka__mujoco_menagerie/leap_hand/assets/tip.obj",
    "src/google-deepmind__mujoco/mjx/mujoco/mjx/test_data/shadow_hand/assets/th_distal_pst_190.obj",
    "src/mikedh__trimesh/models/not_convex.obj",
    "src/google-deepmind__mujoco/model/flex/asset/cap.obj",
    "src/google-deepmind__mujoco/test/engine/testdata/collision_convex/cone.obj",
    "src/google-deepmind__mujoco/test/user/testdata/torus_quads.obj",
    "src/kevinzakka__mujoco_menagerie/shadow_hand/assets/wrist.obj",
)


def growth_folder(sources: list[bytes], folder: Path, count: int) -> None:
    """``count`` OBJs in ``folder``: the sources in turn, copy k ending with its own comment line."""
    folder.mkdir(parents=True)
    for k in range(count):
        data = sources[k % len(sources)]
        (folder / f"a{k:04d}.obj").write_bytes(data + (b"" if data.endswith(b"\n") else b"\n") + b"# copy %d\n" % k)


def _reporting(run: Callable[[], tuple[float, float]], report: Path) -> Callable[[], tuple[float, float]]:
    """``run`` that must write ``report`` (exit status 1 is also how a crash ends: the report tells them apart)."""

    def checked() -> tuple[float, float]:
        report.unlink(missing_ok=True)
        result = run()
        if not report.exists():
            raise RuntimeError(f"meshtool validate wrote no report {report}: it failed")
        return result

    return checked


def growth(corpus: Path, work: Path, repeat: int, sizes: tuple[int, ...]) -> tuple[str, dict[str, Timing]] | None:
    """Time ``meshtool validate`` at every size, -j 1 and -j 2; the largest size runs ``max(1, repeat // 2)`` rounds."""
    paths = [corpus / rel for rel in GROWTH_ASSETS]
    missing = [p for p in paths if not p.exists()]
    if missing:
        print(f"skip the validate growth curve: {missing[0]} not found", file=sys.stderr)
        return None
    sources = [p.read_bytes() for p in paths]
    meshtool = str(Path(sys.executable).with_name("meshtool"))
    before = load_average()
    results: dict[str, Timing] = {}
    for n in sizes:
        folder = work / f"n{n}"
        growth_folder(sources, folder, n)
        contenders = {}
        for jobs in (1, 2):
            report = work / f"n{n}-j{jobs}.json"
            argv = [meshtool, "validate", str(folder), "-j", str(jobs), "--no-cache", "--json", "-o", str(report)]
            # cwd: the temporary folder, so no project's configuration is found; exit 1 means errors found
            contenders[f"{n} j{jobs}"] = _reporting(command(argv, cwd=work, ok=(0, 1)), report)
        rounds = repeat if n < max(sizes) else max(1, repeat // 2)
        results.update(interleave(contenders, rounds))
        for jobs in (1, 2):
            summary = json.loads((work / f"n{n}-j{jobs}.json").read_text())["summary"]
            assert summary["assets"] == n, f"{summary['assets']} assets reported for {n}"
            t = results[f"{n} j{jobs}"]
            print(f"validate {n} assets -j {jobs}: CPU {t.cpu_median:.2f} s, wall {t.wall_median:.2f} s", flush=True)
        shutil.rmtree(folder)
    return before, results


def growth_table(before: str, r: dict[str, Timing], repeat: int, sizes: tuple[int, ...]) -> str:
    big = max(sizes)
    lines = [
        GROWTH_BEGIN,
        "## Validation: growth from 1 to 1,000 assets",
        "",
        f"`python bench/validate.py ../shared/corpus --repeat {repeat}` (part of `make bench`): `meshtool validate "
        "FOLDER -j J --no-cache --json -o REPORT`, each run a fresh process (start-up included; CPU is user + "
        "system of it and its worker processes), over folders of N OBJs built in a temporary folder from ten "
        "self-contained corpus OBJs (1.5 to 110 KB: Suzanne, menagerie and MuJoCo test meshes) cycled with "
        "distinct names, each copy with its own comment line (no two files alike; N = 1 is Suzanne alone, "
        "every larger N holds each of the ten N / 10 times). Every rule, the MuJoCo drop test included. "
        f"-j 1 and -j 2 interleaved, {repeat} rounds ({max(1, repeat // 2)} at N = {big:,}); seconds as min / "
        f"median. {before} before, {load_average()} after the run: the -j 2 speed-up needs 2 idle CPUs, which "
        "a shared machine does not have.",
        "",
        "| N | -j 1 wall min / median s | -j 1 CPU min / median s | -j 2 wall min / median s | -j 2 CPU min / "
        "median s | CPU ms per asset (-j 1 / -j 2) | CPU ms per asset beyond N = 1 (-j 1 / -j 2) | -j 2 speed-up "
        "(median wall) | goal -j 2 >= 1.7x |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    first = min(sizes)
    for n in sizes:
        one, two = r[f"{n} j1"], r[f"{n} j2"]
        speed = one.wall_median / two.wall_median
        goal = ("met" if speed >= 1.7 else f"short: {speed:.2f}x of 1.7x") if n >= 100 else ""
        if n > first:
            extra = [
                (t.cpu_median - r[f"{first} {j}"].cpu_median) / (n - first) * 1e3 for j, t in (("j1", one), ("j2", two))
            ]
            beyond = f"{extra[0]:.1f} / {extra[1]:.1f}"
        else:
            beyond = "-"
        lines.append(
            f"| {n:,} | {one.wall_min:.2f} / {one.wall_median:.2f} | {one.cpu_min:.2f} / {one.cpu_median:.2f} | "
            f"{two.wall_min:.2f} / {two.wall_median:.2f} | {two.cpu_min:.2f} / {two.cpu_median:.2f} | "
            f"{one.cpu_median / n * 1e3:.1f} / {two.cpu_median / n * 1e3:.1f} | {beyond} | {speed:.2f}x | {goal} |"
        )
    lines += [
        "",
        "*Beyond N = 1*: the CPU a run costs over the one-asset run (the command's start-up, and with -j 2 the "
        "workers'), per extra asset; linear growth shows as a flat column. The goal (issue 28, on an idle 2-core "
        "machine) is judged where the work outweighs starting the workers (N >= 100).",
        GROWTH_END,
    ]
    return "\n".join(lines)


def main() -> None:
    args = arguments(__doc__, 5)
    if not args.corpus.is_dir():  # as every bench script does without the shared data
        print(f"skip: {args.corpus} not found", file=sys.stderr)
        return
    sizes = tuple(n for n in GROWTH if n <= args.max_assets)
    with tempfile.TemporaryDirectory() as tmp:
        curve = growth(args.corpus, Path(tmp), args.repeat, sizes)
    if curve is not None:
        write_section(args.out, growth_table(curve[0], curve[1], args.repeat, sizes), GROWTH_BEGIN, GROWTH_END)
    if args.growth_only:
        return
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
