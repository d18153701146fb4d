"""World-building benchmark: 50 textured .mbin meshes through simrun vs the same world as MJCF + OBJ files.

Usage: python bench/world.py ../shared/corpus [--repeat 5] [--out docs/benchmarks.md]

The asset is the corpus's textured fuze (1,000 triangles, a 1024 x 1024 texture), normalised and packed,
then copied to 50 distinct files per format. Contenders run interleaved, --repeat rounds, each round on
fresh file copies so that no cold contender profits from a cache (MuJoCo caches meshes by file name):

* MuJoCo: ``MjModel.from_xml_path`` of an MJCF naming 50 OBJ meshes and 50 PNG textures (the baseline);
* simrun cold: ``World`` with 50 ``MeshEntity`` (arrays and PNG bytes into the spec from memory; identical
  images are decoded once) built and compiled, no model cache;
* simrun second load: the same world built again from the same files with the compiled-model cache
  (simrun/world/model_cache.py) filled by the first load: the model comes from its MJB entry.

A second pair uses 50 *different* textures (one pixel changed per copy), where every image must be decoded
on a cold load by both. Wall-clock and process CPU time (all threads) are reported as min / median.

A second section (``<!-- world-growth:begin -->``) is the growth curve of issue 28: 10, 100, 1,000 and
10,000 static entities of the corpus's Suzanne (untextured, one convex hull), each one body with a visual
mesh geom and a collision hull geom, built and compiled by simrun from ``.mbin`` files and by MuJoCo from an
equivalent MJCF (the same visual and hull meshes as OBJ files, the same geoms, groups and inertia modes);
once with every entity naming one shared mesh file, once with a distinct file per entity (each scaled by
its own tiny factor, so no two files hold the same bytes). Every build reads fresh files and starts with
meshtool's per-content check caches emptied. The per-entity CPU column shows whether growth is linear.
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import io
import os
import platform
import pstats
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from _report import Timing, arguments, interleave, load_average, write_section
from PIL import Image

from meshtool import NormaliseOptions, normalise, normalise_to
from meshtool.export.obj_write import format_obj
from meshtool.hulls.compute import HullOptions, compute_hulls
from meshtool.packfile import pack
from meshtool.packfile.read import forget_checks
from meshtool.pipeline import ConvertOptions, convert
from simrun import MeshEntity, Pose, World
from simrun.world import batch
from simrun.world.model_cache import RACY_NS, ModelCache, model_bytes

COUNT = 50
BEGIN, END = "<!-- world:begin -->", "<!-- world:end -->"
CACHE_BEGIN, CACHE_END = "<!-- model-cache:begin -->", "<!-- model-cache:end -->"
FUZE = "src/mikedh__trimesh/models/fuze.obj"


def prepare(src: Path, work: Path) -> tuple[Path, Path]:
    """One normalised OBJ folder and one .mbin of the asset."""
    folder, _ = normalise_to(src, work / "obj", NormaliseOptions())
    mbin = work / "asset.mbin"
    convert(src, mbin, ConvertOptions(NormaliseOptions()))
    return folder, mbin


def distinct_assets(src: Path, work: Path) -> tuple[list[bytes], list[bytes]]:
    """50 .mbin files' bytes and 50 PNGs, each texture one pixel different from the others."""
    asset = normalise(src, NormaliseOptions())
    hulls = compute_hulls(asset.mesh, HullOptions())
    (name, png) = next(iter(asset.textures.items()))
    image = np.array(Image.open(io.BytesIO(png)))
    mbins, pngs = [], []
    for k in range(COUNT):
        pixels = image.copy()
        pixels[0, k] = (pixels[0, k].astype(np.int32) + 1 + k) % 256
        out = io.BytesIO()
        Image.fromarray(pixels).save(out, format="PNG")
        pngs.append(out.getvalue())
        asset.textures[name] = pngs[-1]
        mbins.append(pack(asset, hulls=hulls.hulls))
    return mbins, pngs


def simrun_world(files: list[bytes], run: Path, cache: ModelCache | None) -> World:
    world = World(base_dir=run)
    world.model_cache = cache
    for k in range(COUNT):
        world.insert(MeshEntity(name=f"m{k}", asset=f"a{k}.mbin", pose=Pose((0.3 * (k % 10), 0.3 * (k // 10), 0.2))))
    world.compile()
    return world


def write_mbins(files: list[bytes], run: Path) -> None:
    run.mkdir(parents=True, exist_ok=True)
    for k, data in enumerate(files):
        (run / f"a{k}.mbin").write_bytes(data)


def write_mjcf(obj: bytes, pngs: list[bytes], run: Path) -> Path:
    run.mkdir(parents=True, exist_ok=True)
    assets, bodies = [], []
    for k in range(COUNT):
        (run / f"m{k}.obj").write_bytes(obj)
        (run / f"t{k}.png").write_bytes(pngs[k])
        assets.append(
            f'<mesh name="m{k}" file="m{k}.obj"/><texture name="t{k}" type="2d" file="t{k}.png"/>'
            f'<material name="mat{k}" texture="t{k}"/>'
        )
        bodies.append(
            f'<body pos="{0.3 * (k % 10)} {0.3 * (k // 10)} 0.2"><geom type="mesh" mesh="m{k}" material="mat{k}"/>'
            "</body>"
        )
    xml = run / "world.xml"
    xml.write_text(f"<mujoco><asset>{''.join(assets)}</asset><worldbody>{''.join(bodies)}</worldbody></mujoco>")
    return xml


def forget_mujoco_meshes() -> None:
    """Empty MuJoCo's mesh cache (keyed by file name; simrun names its in-memory meshes by their content)."""
    mujoco.mj_clearCache(mujoco.mj_getCache())


class Rounds:
    """Contenders that prepare fresh files outside the timed part; each returns (wall, CPU)."""

    def __init__(self, work: Path, mbins: list[bytes], obj: bytes, pngs: list[bytes], tag: str) -> None:
        self.work, self.mbins, self.obj, self.pngs, self.tag = work, mbins, obj, pngs, tag
        self.round = 0
        self.cache = ModelCache(work / f"cache-{tag}")
        self.hashing = ModelCache(work / f"cache-{tag}", hash_inputs=True)
        self.warm = work / f"warm-{tag}"
        write_mbins(mbins, self.warm)
        # a user's assets were not written in the last RACY_NS (files changed that recently are hashed at every
        # lookup, with or without hash_inputs): wait that long before the first load fills the model cache
        time.sleep(RACY_NS / 1e9 + 0.1)
        simrun_world(mbins, self.warm, self.cache)  # fills the model cache
        (entry,) = self.cache.folder.glob("*.mjb")
        self.entry_bytes = entry.stat().st_size
        self.mjb = work / f"entry-{tag}.mjb"  # the entry's model alone, for MuJoCo's own MJB load
        self.mjb.write_bytes(model_bytes(simrun_world(mbins, self.warm, None).model))

    def _timed(self, fn: object) -> tuple[float, float]:
        forget_mujoco_meshes()
        cpu, wall = time.process_time(), time.perf_counter()
        fn()  # type: ignore[operator]
        return time.perf_counter() - wall, time.process_time() - cpu

    def mjcf(self) -> tuple[float, float]:
        self.round += 1
        xml = write_mjcf(self.obj, self.pngs, self.work / f"{self.tag}-m{self.round}")
        return self._timed(lambda: mujoco.MjModel.from_xml_path(str(xml)))

    def cold(self) -> tuple[float, float]:
        run = self.work / f"{self.tag}-s{self.round}"
        write_mbins(self.mbins, run)
        return self._timed(lambda: simrun_world(self.mbins, run, None))

    def second(self) -> tuple[float, float]:
        before = self.cache.hits
        result = self._timed(lambda: simrun_world(self.mbins, self.warm, self.cache))
        assert self.cache.hits == before + 1, "the second load did not come from the model cache"
        return result

    def hashed(self) -> tuple[float, float]:
        before = self.hashing.hits
        result = self._timed(lambda: simrun_world(self.mbins, self.warm, self.hashing))
        assert self.hashing.hits == before + 1, "the second load did not come from the model cache"
        return result

    def miss(self) -> tuple[float, float]:
        cache = ModelCache(self.work / f"miss-{self.tag}-{self.round}")  # empty: look up, compile, store
        result = self._timed(lambda: simrun_world(self.mbins, self.warm, cache))
        assert (cache.hits, cache.misses) == (0, 1) and any(cache.folder.glob("*.mjb")), "the miss stored nothing"
        shutil.rmtree(cache.folder)
        return result

    def mjb_alone(self) -> tuple[float, float]:
        return self._timed(lambda: mujoco.MjModel.from_binary_path(str(self.mjb)))


# ------------------------------------------------------------------------------------ growth curve (issue 28)

GROWTH = (10, 100, 1000, 5000, 10000)
SUZANNE = "src/alecjacobson__common-3d-test-models/data/suzanne.obj"
#: The profiled builds of :func:`growth_split`, by ``"shared N"`` / ``"distinct N"`` (filled by :func:`growth`).
SPLITS: dict[str, dict[str, float]] = {}
GROWTH_BEGIN, GROWTH_END = "<!-- world-growth:begin -->", "<!-- world-growth:end -->"


def growth_variants(src: Path, count: int, folder: Path) -> None:
    """Write ``count`` versions of the asset into ``folder``: version k scaled by 1 + k * 1e-6 (distinct bytes,
    the same shape) as ``a{k}.mbin`` and as the OBJs of its visual mesh ``v{k}.obj`` and its hull ``h{k}.obj``."""
    asset = normalise(src, NormaliseOptions())
    hulls = compute_hulls(asset.mesh, HullOptions()).hulls
    names = [m.name for m in asset.materials]
    folder.mkdir(parents=True)
    for k in range(count):
        factor = 1.0 + k * 1e-6
        mesh = dataclasses.replace(asset.mesh, positions=asset.mesh.positions * factor)
        (only,) = [dataclasses.replace(h, vertices=h.vertices * factor) for h in hulls]  # one convex hull
        (folder / f"a{k}.mbin").write_bytes(pack(dataclasses.replace(asset, mesh=mesh), hulls=[only]))
        (folder / f"v{k}.obj").write_text(format_obj(mesh, names, None, "growth benchmark"))
        (folder / f"h{k}.obj").write_text(
            "".join(
                [f"v {x!r} {y!r} {z!r}\n" for x, y, z in only.vertices.tolist()]
                + [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in only.faces.tolist()]
            )
        )


def _place(k: int) -> tuple[float, float, float]:
    return (0.5 * (k % 100), 0.5 * (k // 100), 0.5)


def growth_world(run: Path, count: int, shared: bool) -> World:
    world = World(base_dir=run)
    world.model_cache = None
    for k in range(count):
        asset = "a0.mbin" if shared else f"a{k}.mbin"
        world.insert(MeshEntity(name=f"e{k}", asset=asset, pose=Pose(_place(k))))
    return world


def growth_simrun(run: Path, count: int, shared: bool) -> mujoco.MjModel:
    """The world's spec built and compiled: the work of ``MjModel.from_xml_path`` (``World.compile`` also
    makes the ``MjData`` and runs ``mj_forward``, which the MJCF contender does not)."""
    return growth_world(run, count, shared).build_spec().compile()


def growth_ready(work: Path, variants: Path, count: int) -> str:
    """Whether ``World.compile`` (spec, model, data, ``mj_forward``) succeeds at ``count`` shared entities."""
    run = work / "ready"
    run.mkdir()
    os.link(variants / "a0.mbin", run / "a0.mbin")
    try:
        growth_world(run, count, True).compile()
    except mujoco.FatalError as exc:
        return f"fails: `{str(exc).splitlines()[0]}`"
    finally:
        shutil.rmtree(run)
    return "succeeds"


def growth_mjcf(run: Path, count: int, shared: bool) -> Path:
    meshes = 1 if shared else count
    assets = [
        f'<mesh name="v{k}" file="v{k}.obj" inertia="shell"/><mesh name="h{k}" file="h{k}.obj" inertia="convex"/>'
        for k in range(meshes)
    ]
    bodies = []
    for k in range(count):
        m = 0 if shared else k
        x, y, z = _place(k)
        bodies.append(
            f'<body name="e{k}" pos="{x} {y} {z}"><geom type="mesh" mesh="v{m}" group="2" contype="0" '
            f'conaffinity="0" density="0"/><geom type="mesh" mesh="h{m}" group="3"/></body>'
        )
    xml = run / "world.xml"
    xml.write_text(f"<mujoco><asset>{''.join(assets)}</asset><worldbody>{''.join(bodies)}</worldbody></mujoco>")
    return xml


class Growth:
    """The growth contenders; each call builds in a fresh folder (files written outside the timed part)."""

    def __init__(self, work: Path, variants: Path) -> None:
        self.work, self.variants, self.serial = work, variants, 0

    def _folder(self, count: int, shared: bool, mjcf: bool) -> Path:
        """A new folder of hard links to the variants: new paths, so neither MuJoCo nor simrun has seen them."""
        self.serial += 1
        run = self.work / f"g{self.serial}"
        run.mkdir()
        for k in range(1 if shared else count):
            for name in (f"v{k}.obj", f"h{k}.obj") if mjcf else (f"a{k}.mbin",):
                os.link(self.variants / name, run / name)
        return run

    def contender(self, count: int, shared: bool, mjcf: bool) -> Callable[[], tuple[float, float]]:
        def run() -> tuple[float, float]:
            folder = self._folder(count, shared, mjcf)
            forget_checks()
            forget_mujoco_meshes()
            cpu, wall = time.process_time(), time.perf_counter()
            if mjcf:
                model = mujoco.MjModel.from_xml_path(str(growth_mjcf(folder, count, shared)))
                nbody = model.nbody
            else:
                nbody = growth_simrun(folder, count, shared).nbody
            result = time.perf_counter() - wall, time.process_time() - cpu
            assert nbody == count + 1, f"{nbody} bodies for {count} entities"
            shutil.rmtree(folder)
            return result

        return run


def growth_split(bench: Growth, count: int, shared: bool) -> dict[str, float]:
    """One more simrun build of ``count`` entities under ``cProfile`` (process CPU), its seconds split into
    MuJoCo's spec bindings (``add_body``, ``add_geom``, ``add_mesh``), MuJoCo's compile, meshtool's
    ``.mbin`` reading, the batches' ``attach`` and the final ``copy`` (simrun/world/batch.py) and the rest
    (simrun's Python; the profiler's own overhead falls on it)."""
    folder = bench._folder(count, shared, False)
    forget_checks()
    forget_mujoco_meshes()
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    growth_simrun(folder, count, shared)
    profile.disable()
    shutil.rmtree(folder)
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    split = {"bindings": 0.0, "attach": 0.0, "compile": 0.0, "meshtool": 0.0, "rest": 0.0}
    for (filename, _, name), row in stats.items():
        own = float(row[2])  # tottime: each second counted once
        if name == "<built-in method mujoco._specs.compile>":
            split["compile"] += own
        elif name in ("<built-in method mujoco._specs.attach>", "<built-in method mujoco._specs.copy>"):
            split["attach"] += own
        elif "mujoco._specs" in name or (filename == "~" and "mujoco" in name):
            split["bindings"] += own
        elif "/meshtool/" in filename:
            split["meshtool"] += own
        else:
            split["rest"] += own
    return split


def growth(corpus: Path, work: Path, repeat: int, sizes: tuple[int, ...]) -> tuple[str, dict[str, Timing], str] | None:
    """Time every N of ``sizes``; the rounds of the largest N are ``max(2, repeat // 2)``."""
    src = corpus / SUZANNE
    if not src.exists():
        print(f"skip the growth curve: {src} not found", file=sys.stderr)
        return None
    before = load_average()
    growth_variants(src, max(sizes), work / "variants")
    bench = Growth(work, work / "variants")
    results: dict[str, Timing] = {}
    for n in sizes:
        rounds = repeat if n < max(sizes) else max(2, repeat // 2)
        contenders = {
            f"{kind} {n} {who}": bench.contender(n, kind == "shared", who == "mjcf")
            for kind in ("shared", "distinct")
            for who in ("mjcf", "simrun")
        }
        results.update(interleave(contenders, rounds))
        for key in contenders:
            t = results[key]
            print(f"{key}: CPU {t.cpu_median:.4f} s, {t.cpu_median / n * 1e6:.1f} us per entity", flush=True)
    ready = growth_ready(work, work / "variants", max(sizes))
    for n in sorted({min(1000, max(sizes)), max(sizes)}):
        for kind in ("shared", "distinct"):
            SPLITS[f"{kind} {n}"] = growth_split(bench, n, kind == "shared")
    return before, results, ready


def spec_adds(count: int) -> float:
    """CPU seconds per body + geom of ``count`` added to a bare ``MjSpec`` through MuJoCo's Python bindings."""
    spec = mujoco.MjSpec()
    cpu = time.process_time()
    for k in range(count):
        body = spec.worldbody.add_body(name=f"b{k}", pos=[0.0, 0.0, 1.0])
        body.add_geom(name=f"g{k}", size=[0.1, 0.0, 0.0])
    return (time.process_time() - cpu) / count


def growth_table(before: str, r: dict[str, Timing], ready: str, repeat: int, sizes: tuple[int, ...]) -> str:
    big = max(sizes)
    probe = sorted({min(1000, big), big})
    adds = {n: spec_adds(n) for n in probe}
    grows = ", ".join(f"{adds[n] * 1e6:.1f} us at N = {n:,}" for n in probe)
    verdict = ""
    if adds[big] > 1.5 * adds[probe[0]]:
        verdict = (
            ": the cost of one addition grows with the spec (MuJoCo's C++ walks the whole tree at every "
            "`mjs_addBody` / `mjs_addGeom`: `ResetTreeLists`, `MakeTreeLists`, the signature), and MuJoCo's MJCF "
            "parser adds its elements the same way, which is why MuJoCo's own per-entity column grows. simrun "
            f"builds worlds of more than {batch.BATCH} entities in child specs of {batch.BATCH} entities, "
            "attached to the world's spec with their elements unnamed and named again after, then copied once "
            "(`simrun/world/batch.py`; the same model byte for byte: `tests/test_world_batch.py`), so no "
            "addition walks more than one batch"
        )
    lines = [
        GROWTH_BEGIN,
        "## World building: growth from 10 to 10,000 entities",
        "",
        f"`python bench/world.py ../shared/corpus --repeat {repeat}` (part of `make bench`): N static entities of "
        "the corpus's Suzanne (968 triangles, untextured, one convex hull), each a body with a visual mesh geom "
        "(group 2, no contacts, no mass) and a collision hull geom (group 3). simrun builds a `World` of "
        "`MeshEntity` from `.mbin` files into its spec and compiles it (`World.build_spec().compile()`, no model "
        "cache); MuJoCo compiles an equivalent MJCF (`MjModel.from_xml_path`: the same visual mesh and hull as "
        "OBJ files, the same geoms, groups and inertia modes). *Shared*: every entity names one file; "
        "*distinct*: one file per entity, each scaled by its own factor 1 + k x 1e-6 (no two files alike). "
        "Every build reads files written for it alone (MuJoCo "
        "caches meshes by file name) and starts with meshtool's per-content check caches emptied. Interleaved, "
        f"{repeat} rounds ({max(2, repeat // 2)} at N = {big:,}); seconds of process CPU as min / median, wall "
        f"median beside it. {before} before, {load_average()} after the run (shared machine: CPU time is the "
        "measure). Goal (issues 28, 41): simrun's build <= MuJoCo's at every N, shared and distinct; Python "
        f"bytecode: {'not written (PYTHONDONTWRITEBYTECODE)' if sys.flags.dont_write_bytecode else '.pyc present'}.",
        "",
        "| meshes | N | MuJoCo CPU min / median s | simrun CPU min / median s | MuJoCo wall median s | simrun wall "
        "median s | MuJoCo us per entity | simrun us per entity | simrun / MuJoCo | goal <= 1x |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for kind in ("shared", "distinct"):
        for n in sizes:
            m, s = r[f"{kind} {n} mjcf"], r[f"{kind} {n} simrun"]
            ratio = s.cpu_median / m.cpu_median
            goal = "met" if ratio <= 1.0 else f"short by {ratio:.2f}x"
            lines.append(
                f"| {kind} | {n:,} | {m.cpu_min:.4f} / {m.cpu_median:.4f} | {s.cpu_min:.4f} / {s.cpu_median:.4f} | "
                f"{m.wall_median:.4f} | {s.wall_median:.4f} | {m.cpu_median / n * 1e6:.1f} | "
                f"{s.cpu_median / n * 1e6:.1f} | {ratio:.2f}x | {goal} |"
            )
    lines += [
        "",
        "Linear growth shows as a flat *us per entity* column down each group; the fixed cost of a build "
        "(the spec, the compile's own set-up) dominates the small N. simrun builds through MuJoCo's `MjSpec` "
        "Python bindings, MuJoCo's MJCF parser in C++; in the bindings (MuJoCo "
        f"{mujoco.__version__}) one `add_body` + `add_geom` on a bare spec costs {grows} (measured in the same "
        f"run){verdict}. `World.compile()` at N = {big:,} (shared; it also makes the `MjData` and runs "
        f"`mj_forward`, with the arena simrun sizes for the broadphase: `simrun.world.world.arena_bytes`) {ready}.",
        "",
        "Where simrun's build goes: one more build under `cProfile` (process CPU; the profiler's overhead falls on "
        "the Python rows), seconds by what ran them: MuJoCo's spec bindings (`add_body`, `add_geom`, `add_mesh`; "
        "setting an element's attributes counts in its caller's row), the batches' `MjSpec.attach` and the final "
        "`MjSpec.copy`, MuJoCo's compile, meshtool's `.mbin` reading (parse, checks, checksums), and the "
        "rest (simrun's Python: entities, poses, paths, asset tables, the in-memory `.msh` files).",
        "",
        "| build | bindings s | attach + copy s | compile s | meshtool s | rest s |",
        "|---|---|---|---|---|---|",
        *(
            f"| {key.split()[0]} {int(key.split()[1]):,} | {v['bindings']:.4f} | {v['attach']:.4f} | "
            f"{v['compile']:.4f} | {v['meshtool']:.4f} | {v['rest']:.4f} |"
            for key, v in SPLITS.items()
        ),
        "",
        *_distinct_note(big),
        GROWTH_END,
    ]
    return "\n".join(lines)


def _distinct_note(big: int) -> list[str]:
    """What the profile says of the distinct-file worlds (one ``.mbin`` per entity), where they fall short."""
    v = SPLITS.get(f"distinct {big}")
    if v is None:
        return []
    total = sum(v.values())
    return [
        f"Distinct files at N = {big:,}: of the profiled build's {total:.1f} s, MuJoCo's compile takes "
        f"{v['compile']:.1f} s (each file's meshes: MuJoCo's own work, as in the MJCF build), meshtool's `.mbin` "
        f"reading {v['meshtool']:.1f} s and simrun's Python {v['rest']:.1f} s, most of it the per-file asset path "
        "(`simrun/world/assets.py`: the pack's view, the in-memory `.msh` files; hull volumes are computed only "
        "for an entity given a mass, a layout's checks run once for files that differ only in content); the tree, "
        f"{v['bindings']:.1f} s in the bindings and {v['attach']:.1f} s in attach + copy (an attachment checks "
        "every name of the world's spec, which holds two named meshes per file), is "
        f"{100 * (v['bindings'] + v['attach']) / total:.1f} % of it.",
    ]


def main() -> int:
    args = arguments(__doc__, 5)
    src = args.corpus / FUZE
    if not src.exists():
        print(f"skip: {src} not found", file=sys.stderr)
        return 0
    if args.growth_only:  # the growth curve alone (the 50-mesh worlds and the cache rows skipped)
        return growth_main(args)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        folder, mbin = prepare(src, work)
        obj = next(folder.glob("*.obj"))
        png = next(folder.glob("*.png")).read_bytes()
        same = Rounds(work, [mbin.read_bytes()] * COUNT, obj.read_bytes(), [png] * COUNT, "same")
        mbins, pngs = distinct_assets(src, work)
        different = Rounds(work, mbins, obj.read_bytes(), pngs, "distinct")
        results = interleave(
            {
                "mjcf": same.mjcf,
                "cold": same.cold,
                "second": same.second,
                "hashed": same.hashed,
                "miss": same.miss,
                "mjb": same.mjb_alone,
                "mjcf distinct": different.mjcf,
                "cold distinct": different.cold,
                "second distinct": different.second,
                "hashed distinct": different.hashed,
                "miss distinct": different.miss,
                "mjb distinct": different.mjb_alone,
            },
            args.repeat,
        )
        entries = {"": same.entry_bytes, " distinct": different.entry_bytes}
    write_section(args.out, table(results, args.repeat), BEGIN, END)
    write_section(args.out, cache_table(results, entries, args.repeat), CACHE_BEGIN, CACHE_END)
    for name, t in results.items():
        print(f"{name}: wall {t.wall_min:.4f}/{t.wall_median:.4f} s, cpu {t.cpu_min:.4f}/{t.cpu_median:.4f} s")
    return growth_main(args)


def growth_main(args: argparse.Namespace) -> int:
    """The growth curve up to ``--max-entities`` (0: none), its block written into ``--out``."""
    sizes = tuple(n for n in GROWTH if n <= args.max_entities)
    if not sizes:  # --max-entities 0: the 50-mesh worlds only
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        curve = growth(args.corpus, Path(tmp), args.repeat, sizes)
    if curve is not None:
        write_section(args.out, growth_table(*curve, args.repeat, sizes), GROWTH_BEGIN, GROWTH_END)
    return 0


def table(r: dict[str, Timing], repeat: int) -> str:
    def row(label: str, key: str, base: str, goal: float | None = None) -> str:
        t, b = r[key], r[base]
        speed = b.cpu_median / t.cpu_median
        verdict = "" if goal is None else "met" if speed >= goal else f"short: {speed:.1f}x of {goal:g}x"
        return (
            f"| {label} | {t.wall_min:.4f} / {t.wall_median:.4f} | {t.cpu_min:.4f} / {t.cpu_median:.4f} | "
            f"{b.wall_median / t.wall_median:.1f}x | {speed:.1f}x | {verdict} |"
        )

    return "\n".join(
        [
            BEGIN,
            "## World building: 50 textured meshes",
            "",
            f"`python bench/world.py ../shared/corpus --repeat {repeat}` (part of `make bench`): contenders "
            f"interleaved, {repeat} rounds, fresh file copies for every cold load and MuJoCo's cache (meshes, "
            "decoded textures) emptied before every contender. Seconds "
            "as min / median of wall-clock and of process CPU (all threads); speed-ups are MuJoCo's median over "
            f"the row's median. Machine: {platform.machine()}, CPython {platform.python_version()}, MuJoCo "
            f"{mujoco.__version__}, numpy {np.__version__}; {load_average()} at the end of the run.",
            "",
            "| world (50 fuze meshes, 1,000 triangles, 1024 x 1024 texture each) | wall min / median s | "
            "CPU min / median s | speed-up (wall) | speed-up (CPU) | goal (CPU) |",
            "|---|---|---|---|---|---|",
            row("MuJoCo: MJCF with 50 OBJ meshes + 50 PNG textures (the same image)", "mjcf", "mjcf"),
            row("simrun cold: 50 MeshEntity from .mbin, no model cache", "cold", "mjcf", 5.0),
            row("simrun second load: the same scene again, compiled-model cache", "second", "mjcf", 50.0),
            row("MuJoCo: MJCF, 50 different textures", "mjcf distinct", "mjcf distinct"),
            row("simrun cold, 50 different textures", "cold distinct", "mjcf distinct", 5.0),
            row("simrun second load, 50 different textures", "second distinct", "mjcf distinct", 50.0),
            "",
            "Goals (issues 17 and 28): cold >= 5x MuJoCo for textured meshes, second load >= 50x; judged on "
            "median CPU. simrun hands MuJoCo each distinct image "
            "once (the 50 copies of one texture are decoded once; MuJoCo's MJCF loader decodes every file); with "
            "50 different images both decode all of them, about "
            f"{(r['cold distinct'].cpu_median - r['cold'].cpu_median) / (COUNT - 1) * 1e3:.0f} ms CPU each here "
            "(the cold difference over 49 images), which bounds the cold ratio. Before issue 41 the cold rounds "
            "after the first found those images in MuJoCo's cache (simrun's in-memory texture names repeat from "
            "build to build), which this table's earlier cold numbers included. The second load reads the model "
            "MuJoCo compiled the first time (MJB), after checking every input's fingerprint (a changed one: its "
            "XXH3 hash); the next section sets it against the cold load. `tests/test_model_cache.py` checks that a "
            "cached model is byte for byte the compiled one, simulates identically, and that any change of a file, "
            "an entity or an option recompiles.",
            END,
        ]
    )


def cache_table(r: dict[str, Timing], sizes: dict[str, int], repeat: int) -> str:
    """The compiled-model cache against the same world cold (issue 41 item 2: a second load >= 5x faster)."""
    bytecode = "off (PYTHONDONTWRITEBYTECODE set)" if sys.dont_write_bytecode else "on (.pyc present)"
    lines = [
        CACHE_BEGIN,
        "## Compiled-model cache: second load, miss and cold",
        "",
        f"`python bench/world.py ../shared/corpus --repeat {repeat}` (part of `make bench`), the worlds of the table "
        "above: 50 fuze `MeshEntity` with one shared texture, and with 50 different textures. *Cold*: built and "
        "compiled, no model cache (the anchor). *Second load*: the same scene again with the cache the first "
        "load filled (`World.compile` through `ModelCache.load`: the inputs' fingerprints checked, the entry "
        "mapped, its XXH3-128 checked, the MJB handed to MuJoCo's `mj_loadModelBuffer`, then `MjData` and "
        "`mj_forward`). *Inputs hashed*: the same with `ModelCache(hash_inputs=True)` (every input's XXH3-128 at "
        "every lookup). *Miss*: an empty cache folder (lookup, compile, entry written). *MuJoCo MJB load*: "
        "`MjModel.from_binary_path` of the same model saved as a plain MJB file (MuJoCo alone, no world). "
        "MuJoCo's mesh cache emptied before every contender. Interleaved, "
        f"{repeat} rounds; seconds of process CPU as min / median. Bytecode: {bytecode}. {load_average()} at the "
        "end. Goal (issue 41): second load >= 5x faster than cold (CPU medians).",
        "",
        "| world | entry MB | contender | CPU min / median s | cold / contender | goal |",
        "|---|---|---|---|---|---|",
    ]
    labels = [
        ("cold", "cold, no cache", False),
        ("second", "second load", True),
        ("hashed", "second load, inputs hashed", True),
        ("miss", "miss (compile + store)", False),
        ("mjb", "MuJoCo MJB load alone", False),
    ]
    for tag, world in (("", "one texture"), (" distinct", "50 different textures")):
        cold = r[f"cold{tag}"].cpu_median
        for key, label, judged in labels:
            t = r[f"{key}{tag}"]
            speed = cold / t.cpu_median
            goal = ("met" if speed >= 5.0 else f"short by {5.0 / speed:.2f}x") if judged else ""
            lines.append(
                f"| {world} | {sizes[tag] / 1e6:.1f} | {label} | {t.cpu_min:.4f} / {t.cpu_median:.4f} | "
                f"{speed:.1f}x | {goal} |"
            )
    second, mjb, miss = (r[f"{k} distinct"].cpu_median for k in ("second", "mjb", "miss"))
    lines += [
        "",
        f"Where a second load's time goes (50 different textures: a {sizes[' distinct'] / 1e6:.0f} MB model, 157 MB "
        f"of it texture pixels): MuJoCo making the model from the mapped entry (`mj_loadModelBuffer`: the model's "
        "buffer allocated and zeroed, one copy in), the inputs' fingerprints (one `lstat` each), one XXH3-128 "
        f"pass over the entry, `MjData` and `mj_forward`; it costs {second / mjb:.2f}x MuJoCo's own "
        "`from_binary_path` of the same MJB file, which reads the file into a buffer of its own first. A miss "
        f"costs {miss / r['cold distinct'].cpu_median:.2f}x the cold load: the compile, then the entry written "
        "(the MJB copied out with `mj_saveModel`, its XXH3-128, the envelope's SHA-256, the atomic write). "
        "MuJoCo's cache (meshes and decoded textures by file name) is emptied before every contender: before "
        "issue 41 the cold rounds after the first reused the textures MuJoCo had decoded in earlier rounds "
        "(simrun's in-memory texture names repeat), so the cold times above were flattered.",
        CACHE_END,
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
