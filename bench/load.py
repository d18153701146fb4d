"""Load benchmark: .mbin against raw arrays, OBJ and GLB through trimesh, MuJoCo's MSH and MuJoCo's OBJ loader.

Usage: python bench/load.py ../shared/corpus [--repeat 7] [--out docs/benchmarks.md]

All formats hold the same normalised mesh (written by meshtool from the corpus file), files in the page
cache. The fast readers run interleaved for --repeat rounds (wall-clock and process CPU, min / median):
  * raw: read + np.frombuffer of a file holding exactly the float32 positions and u32 indices (the anchor);
  * raw, same bytes: read + np.frombuffer of the .mbin file itself (what touching every byte costs);
  * .mbin 1.1 lossless with verify=True (checksums, index bounds, finite floats: everything), verify=False,
    and quantised with verify=True; the same lossless file written as format 1.0 (CRC-32) with verify=True;
  * MSH via numpy.
Slow peers (OBJ and GLB through trimesh) run interleaved for max(2, --repeat // 3) rounds; the Into-MuJoCo
contenders (MuJoCo compiling the OBJ, STL, MSH or the .mbin arrays) after one untimed warm-up call each, for
max(5, --repeat) rounds (meshes of at most 100,000 triangles) or max(2, --repeat // 3). Tables go into
docs/benchmarks.md between ``<!-- load:begin -->`` and ``<!-- load:end -->``.
"""

from __future__ import annotations

import dataclasses
import platform
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import trimesh
from _report import Timing, arguments, corpus_meshes, interleave, load_average, timed, write_section

import meshtool
from meshtool import normalise
from meshtool.packfile import format as fmt
from meshtool.packfile import load, pack, parse
from meshtool.packfile.export import to_glb, to_msh
from meshtool.packfile.read import forget_checks
from meshtool.packfile.write import StoredSection, assemble
from meshtool.repair.normalise import NormaliseOptions
from simrun.world.assets import AssetLibrary

MESHES = [
    ("fuze, textured (1k tri)", "src/mikedh__trimesh/models/fuze.obj"),
    ("suzanne, untextured (968 tri)", "src/alecjacobson__common-3d-test-models/data/suzanne.obj"),
    ("stanford bunny scan (69k tri)", "src/alecjacobson__common-3d-test-models/data/stanford-bunny.obj"),
    ("bunny subdivided (1.11M tri)", "derived/stanford-bunny-subdiv2/stanford-bunny-subdiv2.obj"),
]
BEGIN, END = "<!-- load:begin -->", "<!-- load:end -->"
#: What was measured by hand about the .mbin -> MjSpec rows (not by this script; the commit says when).
MJSPEC_NOTE = (
    "Measured by hand (issue 41 item 6, process CPU, at commit ef1bb1f; not re-measured by this script): "
    "MuJoCo compiling the in-memory `.msh` costs what compiling the MSH file costs (suzanne, 5 x 200 builds in "
    "a loop: 0.61-0.70 ms against 0.65-0.80 ms). In a warm loop (`AssetLibrary.mesh` + `add_geom` + `assets`, "
    "content seen before, 7 x 500 calls) the build is 152-154 us per mesh, 196-201 us before issue 41's cuts "
    "(small `.mbin` files read whole instead of mapped, each layout's section plan remembered, `msh_bytes` "
    "joining the cast arrays; compiled model and virtual files byte-identical): the verified load about 50 us, "
    "path resolution and the regular-file check 20 us, `asset_view` 13 us, the spec calls 10 us; run between "
    "other contenders, as in this table, the same code costs 3 to 5 times more (caches cold). Handing MuJoCo "
    "the arrays as `uservert`/`userface`/`usernormal` instead of a `.msh` compiles no faster (1.64 against "
    "1.57 ms per build + compile; the bindings convert element by element) and changes the saved model's bytes "
    "(mesh arrays equal), so the `.msh` path stays."
)
#: Most triangles MuJoCo reads from an STL file.
STL_MAX_FACES = 200_000


def read_msh(path: Path) -> tuple[np.ndarray, ...]:
    data = path.read_bytes()
    nv, nn, nt, nf = np.frombuffer(data, "<i4", 4)
    o = 16
    v = np.frombuffer(data, "<f4", nv * 3, o).reshape(-1, 3)
    o += nv * 12
    n = np.frombuffer(data, "<f4", nn * 3, o)
    o += nn * 12
    t = np.frombuffer(data, "<f4", nt * 2, o)
    o += nt * 8
    f = np.frombuffer(data, "<i4", nf * 3, o).reshape(-1, 3)
    return v, n, t, f


def read_raw(path: Path, nv: int) -> tuple[np.ndarray, np.ndarray]:
    data = path.read_bytes()
    v = np.frombuffer(data, "<f4", nv * 3, 0).reshape(-1, 3)
    f = np.frombuffer(data, "<u4", offset=nv * 12).reshape(-1, 3)
    return v, f


def read_same_bytes(path: Path) -> np.ndarray:
    return np.frombuffer(path.read_bytes(), np.uint8)


def load_mbin(path: Path, verify: bool) -> None:
    with load(path, verify=verify) as p:
        p.positions.shape  # noqa: B018


def as_version_1_0(data: bytes) -> bytes:
    """The same file written as format 1.0 (CRC-32 checksums), sections unchanged."""
    packed = parse(data)
    sections = [
        StoredSection(
            s.kind.encode(),
            fmt.CODES[s.dtype],
            (s.shape[0], s.shape[1] if len(s.shape) == 2 else 0),
            len(s.shape),
            data[s.offset : s.offset + s.length],
            s.encoding,
            s.index,
        )
        for s in packed.sections
    ]
    return assemble(sections, fmt.FLAG_QUANTIZED if packed.quantized else 0, minor=0)


def mujoco_from_mbin(path: Path, compiled: bool = True) -> None:
    """What a world does with an ``.mbin`` (simrun's :class:`~simrun.world.assets.AssetLibrary`): load it, hand its
    arrays to an ``MjSpec`` (in-memory ``.msh``), compile. MuJoCo's mesh cache is emptied first, as for every
    MuJoCo contender (the library names a mesh by its content, which would hit the cache from the last round),
    and so are meshtool's caches of checks made once per content (:func:`forget_checks`): the file is read as
    content not seen before, as MuJoCo reads each fresh file."""
    mujoco.mj_clearCache(mujoco.mj_getCache())
    forget_checks()
    spec = mujoco.MjSpec()
    library = AssetLibrary(spec)
    asset = library.mesh(path, 1.0)
    for mesh, _ in asset.visual:
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh, contype=0, conaffinity=0)
    spec.assets = library.vfs
    if compiled:
        spec.compile()


def mujoco_from_file(paths: list[Path]) -> None:
    """Compile from a mesh file (OBJ, STL, MSH) MuJoCo has not seen yet (its mesh cache is keyed by file name)."""
    mujoco.mj_clearCache(mujoco.mj_getCache())
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(paths.pop()), inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)  # as simrun's
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m", contype=0, conaffinity=0)
    spec.compile()


def measure(src: Path, work: Path, repeat: int) -> tuple[dict[str, float], dict[str, Timing]]:
    asset = normalise(src, NormaliseOptions(up="z"))
    obj = work / f"{asset.name}.obj"
    for name, data in asset.files.items():
        (work / name).write_bytes(data)
    lossless, quantized = pack(asset), pack(asset, quantize=True)
    paths = {
        "mbin": work / "m.mbin",
        "mbinq": work / "q.mbin",
        "mbin10": work / "m10.mbin",
        "glb": work / "m.glb",
        "msh": work / "m.msh",
        "raw": work / "m.raw",
    }
    paths["mbin"].write_bytes(lossless)
    # the mesh alone for the MjSpec contender: the MuJoCo peers read geometry (and uvs), no image
    bare = [dataclasses.replace(m, maps={}) for m in asset.materials]
    (work / "geometry.mbin").write_bytes(pack(dataclasses.replace(asset, textures={}, materials=bare)))
    paths["mbinq"].write_bytes(quantized)
    paths["mbin10"].write_bytes(as_version_1_0(lossless))
    packed = parse(lossless)
    paths["glb"].write_bytes(to_glb(packed))
    paths["msh"].write_bytes(to_msh(packed))
    nv, nf = packed.positions.shape[0], packed.indices.shape[0]
    paths["raw"].write_bytes(
        np.asarray(packed.positions, "<f4").tobytes() + np.asarray(packed.indices, "<u4").tobytes()
    )
    trimesh.Trimesh(np.asarray(packed.positions), np.asarray(packed.indices), process=False).export(work / "m.stl")
    slow_rounds = max(2, repeat // 3)
    rounds = mujoco_rounds(nf, repeat)
    fresh: dict[str, list[Path]] = {"obj": [], "stl": [], "msh": []}
    for kind, source in (("obj", obj), ("stl", work / "m.stl"), ("msh", paths["msh"])):
        for k in range(rounds + 1):  # one more for the warm-up call
            copy = work / f"fresh_{k}.{kind}"
            copy.write_bytes(source.read_bytes())
            fresh[kind].append(copy)
    sizes = {
        "triangles": float(packed.indices.shape[0]),
        **{f"size_{k}": float(p.stat().st_size) for k, p in paths.items()},
        "size_obj": float(obj.stat().st_size),
        "texture": float(sum(s.length for s in packed.sections if s.kind == "TEX ")),
    }
    fast = interleave(
        {
            "raw": timed(lambda: read_raw(paths["raw"], nv), None),
            "same bytes": timed(lambda: read_same_bytes(paths["mbin"]), None),
            "fromfile": timed(lambda: np.fromfile(paths["mbin"], np.uint8), None),
            "verify": timed(lambda: load_mbin(paths["mbin"], True), None),
            "first verify": timed(lambda: (forget_checks(), load_mbin(paths["mbin"], True)), None),
            "no verify": timed(lambda: load_mbin(paths["mbin"], False), None),
            "quantised": timed(lambda: load_mbin(paths["mbinq"], True), None),
            "1.0 verify": timed(lambda: load_mbin(paths["mbin10"], True), None),
            "msh": timed(lambda: read_msh(paths["msh"]), None),
        },
        repeat,
    )
    slow_contenders = {
        "obj trimesh": timed(lambda: trimesh.load(obj, force="mesh")),
        "glb trimesh": timed(lambda: trimesh.load(paths["glb"], force="mesh")),
    }
    mujoco_contenders = {
        "mujoco obj": timed(lambda: mujoco_from_file(fresh["obj"])),
        "mujoco stl": timed(lambda: mujoco_from_file(fresh["stl"])),
        "mujoco msh": timed(lambda: mujoco_from_file(fresh["msh"])),
        "mujoco mbin": timed(lambda: mujoco_from_mbin(work / "geometry.mbin")),
        "mbin spec": timed(lambda: mujoco_from_mbin(work / "geometry.mbin", compiled=False)),
    }
    if nf > STL_MAX_FACES:  # MuJoCo's STL reader refuses more
        del mujoco_contenders["mujoco stl"]
    slow = interleave(slow_contenders, slow_rounds)
    for run in mujoco_contenders.values():  # a warm-up call each: no contender's first call in the process is timed
        run()
    into_mujoco = interleave(mujoco_contenders, rounds)
    return sizes, {**fast, **slow, **into_mujoco}


def mujoco_rounds(triangles: int, repeat: int) -> int:
    """Rounds of the Into-MuJoCo contenders: ``max(5, repeat)`` for a mesh of at most
    :data:`MUJOCO_ROUNDS_TRIANGLES` triangles (a few ms each), else the slow peers' ``max(2, repeat // 3)``."""
    return max(5, repeat) if triangles <= MUJOCO_ROUNDS_TRIANGLES else max(2, repeat // 3)


#: Largest mesh (triangles) whose Into-MuJoCo contenders run ``max(5, --repeat)`` rounds.
MUJOCO_ROUNDS_TRIANGLES = 100_000


def ms(t: float) -> str:
    return f"{t * 1000:.3f}" if t < 0.01 else f"{t * 1000:.2f}" if t < 0.1 else f"{t * 1000:.0f}"


def pair(t: Timing) -> str:
    return f"{ms(t.wall_min)} / {ms(t.wall_median)} | {ms(t.cpu_min)} / {ms(t.cpu_median)}"


def table(rows: list[tuple[str, dict[str, float], dict[str, Timing]]], repeat: int) -> str:
    lines = [
        BEGIN,
        "## Loading: .mbin vs raw arrays, OBJ, GLB, MSH and MuJoCo",
        "",
        f"`python bench/load.py ../shared/corpus --repeat {repeat}` (part of `make bench`): the same normalised "
        f"mesh in every format, files in the page cache; fast readers interleaved for {repeat} rounds, slow "
        f"peers for {max(2, repeat // 3)} (the Into-MuJoCo contenders after a warm-up call each, for "
        f"{max(5, repeat)} rounds up to {MUJOCO_ROUNDS_TRIANGLES:,} triangles); each fast measurement repeats "
        "the read for about 20 ms and divides. "
        "Milliseconds per read as min / median of wall-clock and of process CPU. "
        f"Machine: {platform.machine()}, CPython {platform.python_version()}, numpy {np.__version__}, trimesh "
        f"{trimesh.__version__}, MuJoCo {mujoco.__version__}, meshtool {meshtool.__version__}; {load_average()} "
        "at the end of the run.",
        "",
        "| mesh | reader | wall min / median ms | CPU min / median ms |",
        "|---|---|---|---|",
    ]
    labels = [
        ("raw", "raw np.frombuffer (positions + u32 indices file)"),
        ("same bytes", "raw read of the .mbin's own bytes"),
        ("fromfile", "np.fromfile of the .mbin (the anchor of issue 28)"),
        ("verify", ".mbin 1.1 `load(verify=True)`, content seen before in this process"),
        ("first verify", ".mbin 1.1 `load(verify=True)`, first load of this content (caches emptied)"),
        ("no verify", ".mbin 1.1 `load(verify=False)`"),
        ("quantised", ".mbin 1.1 quantised, `verify=True`"),
        ("1.0 verify", ".mbin 1.0 (CRC-32), `verify=True`"),
        ("msh", "MSH via numpy"),
        ("obj trimesh", "OBJ via trimesh.load"),
        ("glb trimesh", "GLB via trimesh.load"),
        ("mujoco obj", "MuJoCo compiling the OBJ"),
        ("mujoco stl", "MuJoCo compiling the STL"),
        ("mujoco msh", "MuJoCo compiling the MSH"),
        ("mujoco mbin", ".mbin load + MjSpec compile (simrun's AssetLibrary)"),
        ("mbin spec", ".mbin load + MjSpec built, not compiled"),
    ]
    for name, _, t in rows:
        for key, label in labels:
            if key in t:
                lines.append(f"| {name} | {label} | {pair(t[key])} |")
    lines += [
        "",
        "Ratios (medians). Goals of issue 28: a small asset (<= 10k triangles) loads verified in <= 0.1 ms CPU, "
        "a large one in <= 1.5x `np.fromfile` of the same file; issue 17: quantised <= 2x lossless.",
        "",
        "| mesh | verify ms (CPU) | first verify ms (CPU) | verify / np.fromfile (CPU) | goal | verify / raw (CPU) "
        "| verify / same bytes (CPU) | quantised / lossless (CPU) "
        "| 1.0 verify / 1.1 verify (CPU) | OBJ trimesh / .mbin (CPU) | MuJoCo OBJ / .mbin compile (CPU) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, info, t in rows:
        v = t["verify"]
        anchor = v.cpu_median / t["fromfile"].cpu_median
        if info["triangles"] <= 10_000:
            goal = "met" if v.cpu_median <= 1e-4 else f"short by {v.cpu_median / 1e-4:.2f}x (<= 0.1 ms)"
        else:
            goal = "met" if anchor <= 1.5 else f"short by {anchor / 1.5:.2f}x (<= 1.5x)"
        lines.append(
            f"| {name} | {v.cpu_median * 1e3:.3f} | {t['first verify'].cpu_median * 1e3:.3f} | {anchor:.2f}x | "
            f"{goal} | {v.cpu_median / t['raw'].cpu_median:.2f}x | "
            f"{v.cpu_median / t['same bytes'].cpu_median:.2f}x | {t['quantised'].cpu_median / v.cpu_median:.2f}x | "
            f"{t['1.0 verify'].cpu_median / v.cpu_median:.2f}x | {t['obj trimesh'].cpu_median / v.cpu_median:.0f}x | "
            f"{t['mujoco obj'].cpu_median / t['mujoco mbin'].cpu_median:.2f}x |"
        )
    lines += [
        "",
        "Into MuJoCo (issue 41 item 6): `.mbin` load + `MjSpec` compile through simrun's `AssetLibrary` (the arrays "
        "cast once into an in-memory `.msh`, MuJoCo's binary mesh format, no per-element conversion) against "
        "MuJoCo compiling the same mesh from an OBJ, a binary STL (trimesh's export of the same arrays) and an "
        "MSH file it has not seen (fresh names; MuJoCo's mesh cache emptied before every contender, and for the "
        "`.mbin` meshtool's caches of checks made once per content: a first load), each with "
        "the inertia simrun gives a visual mesh (`shell`); the `.mbin` "
        "is the same mesh without its texture, as the others hold none. Median ms "
        "of process CPU; goal: the binary format loads faster than the text one, <= 1x of every MuJoCo path.",
        "",
        "| mesh | triangles | .mbin -> MjSpec ms | OBJ ms | STL ms | MSH ms | / OBJ | / STL | / MSH | goal <= 1x |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, info, t in rows:
        ours = t["mujoco mbin"].cpu_median
        peers = [t[f"mujoco {k}"].cpu_median if f"mujoco {k}" in t else None for k in ("obj", "stl", "msh")]
        worst = max(ours / p for p in peers if p is not None)
        goal = "met" if worst <= 1.0 else f"short by {worst:.2f}x"
        lines.append(
            f"| {name} | {int(info['triangles'])} | {ours * 1e3:.3f} | "
            + " | ".join(f"{p * 1e3:.3f}" if p is not None else "n/a" for p in peers)
            + " | "
            + " | ".join(f"{ours / p:.2f}x" if p is not None else "n/a (> 200,000 faces)" for p in peers)
            + f" | {goal} |"
        )
    lines.append("")
    parts = []
    for name, info, t in rows:
        built, whole = t["mbin spec"].cpu_median, t["mujoco mbin"].cpu_median
        first = (  # the fast table's file is this one where the mesh has no texture to leave out
            ""
            if info["texture"]
            else f" (of it the verified first load {t['first verify'].cpu_median * 1e3:.3f} ms, the fast table's)"
        )
        parts.append(
            f"{name}: the build {built * 1e3:.3f} ms{first}, the compile {(whole - built) * 1e3:.3f} ms against "
            f"{t['mujoco msh'].cpu_median * 1e3:.3f} ms for MuJoCo's whole MSH path (read and compile)"
        )
    lines.append(
        "Where the `.mbin -> MjSpec` time goes (medians of the same rounds; the build: the verified `.mbin` load, "
        "the library's path checks, `asset_view`, the `.msh` bytes, the spec's meshes and material, no compile): "
        + "; ".join(parts)
        + ". Where the compile alone costs what MuJoCo's MSH path costs, the ratio's excess over 1x is the "
        "build's Python."
    )
    lines += ["", MJSPEC_NOTE]
    for name, info, t in rows:
        v, touch, bare = t["verify"].cpu_median, t["fromfile"].cpu_median, t["no verify"].cpu_median
        if info["triangles"] > 10_000 or v <= 1e-4:
            continue
        texture = f", {int(info['texture']):,} of them its PNG texture" if info["texture"] else ""
        why = (
            f"Its file is {int(info['size_mbin']):,} bytes{texture}; `np.fromfile` of it costs {touch * 1e3:.3f} ms "
            f"CPU and a load that checks nothing (`verify=False`: the table, the JSON sections, the array views) "
            f"{bare * 1e3:.3f} ms; a verified load adds a checksum over every byte and the array reductions"
        )
        lines += ["", f"{name}: short of the small-asset goal by {v / 1e-4:.2f}x. {why}."]
    lines += [
        "",
        "Sizes in bytes:",
        "",
        "| mesh | triangles | OBJ | GLB | MSH | raw | .mbin | .mbin quantised | .mbin / GLB | quantised / GLB |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, s, _ in rows:
        lines.append(
            f"| {name} | {int(s['triangles'])} | {int(s['size_obj'])} | {int(s['size_glb'])} | {int(s['size_msh'])} | "
            f"{int(s['size_raw'])} | {int(s['size_mbin'])} | {int(s['size_mbinq'])} | "
            f"{s['size_mbin'] / s['size_glb']:.2f} | {s['size_mbinq'] / s['size_glb']:.2f} |"
        )
    lines += [
        "",
        "A load with verification reads every byte once (XXH3 checksums) and checks the content with reductions "
        "(index maximum, finiteness; box-quantised arrays by their decoded extremes). The checks made in Python "
        "(table, JSON metadata with every number checked finite, submeshes, hulls) run once per content in a "
        "process: they are remembered by the exact bytes they read (`meshtool/packfile/read.py`), so a file "
        "that differs anywhere they look is checked in full; *first verify* empties those caches before every "
        "load. *verify / same bytes* compares against reading the same file. Quantised files keep their "
        "indices plain since format 1.1 (inflating them cost 10x a lossless load) and decode positions in "
        "float32 on exact grids (docs/mbin-spec.md).",
        END,
    ]
    return "\n".join(lines)


def main() -> int:
    args = arguments(__doc__, 7)
    rows = []
    for name, src in corpus_meshes(args.corpus, MESHES):
        with tempfile.TemporaryDirectory() as tmp:
            sizes, timings = measure(src, Path(tmp), args.repeat)
        rows.append((name, sizes, timings))
        v, r = timings["verify"], timings["raw"]
        print(f"{name}: verify {v.cpu_median * 1e3:.3f} ms CPU, raw {r.cpu_median * 1e3:.3f} ms", flush=True)
    write_section(args.out, table(rows, args.repeat), BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
