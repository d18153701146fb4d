"""Load benchmark: .mbin against OBJ and GLB through trimesh, MuJoCo's MSH, raw arrays and MuJoCo's OBJ loader.

Usage: python bench/load.py ../shared/corpus [--repeat 5] [--out docs/benchmarks.md]

All formats hold the same normalised mesh (written by meshtool from the corpus file) and are measured in
one run, best of --repeat, file read from the page cache included:
  * OBJ via trimesh.load; GLB via trimesh.load (written by ``meshtool export --glb``)
  * MSH via numpy (read + np.frombuffer of its four arrays)
  * raw: read + np.frombuffer of a file holding exactly the float32 positions and u32 indices
  * .mbin lossless and quantised via meshtool.load (verify=True: all checksums and index ranges checked;
    verify=False: header and bounds only, arrays mapped lazily)
  * MuJoCo: compile a model from the loaded .mbin arrays (MjSpec uservert/userface) against MuJoCo
    compiling the OBJ file itself.
The table is written into docs/benchmarks.md between ``<!-- load:begin -->`` and ``<!-- load:end -->``.
"""

from __future__ import annotations

import platform
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import trimesh
from _report import arguments, best, corpus_meshes, write_section

import meshtool
from meshtool import normalise
from meshtool.normalise import NormaliseOptions
from meshtool.packfile import load, pack, parse
from meshtool.packfile.export import to_glb, to_msh

MESHES = [
    ("fuze, textured (1k tri)", "src/mikedh__trimesh/models/fuze.obj"),
    ("stanford bunny scan (69k tri)", "src/alecjacobson__common-3d-test-models/data/stanford-bunny.obj"),
    ("bunny subdivided (1.11M tri)", "derived/stanford-bunny-subdiv2/stanford-bunny-subdiv2.obj"),
]
BEGIN, END = "<!-- load:begin -->", "<!-- load:end -->"


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


def load_mbin(path: Path, verify: bool) -> None:
    with load(path, verify=verify) as p:
        p.positions.shape  # noqa: B018


def mujoco_from_mbin(path: Path) -> None:
    with load(path) as p:
        spec = mujoco.MjSpec()
        spec.add_mesh(name="m", uservert=p.positions.ravel(), userface=p.indices.astype(np.int32).ravel())
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m", contype=0, conaffinity=0)
        spec.compile()


def mujoco_from_obj(paths: list[Path]) -> None:
    """Compile from an OBJ MuJoCo has not seen yet (its mesh cache is keyed by file name)."""
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(paths.pop()))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m", contype=0, conaffinity=0)
    spec.compile()


def measure(src: Path, work: Path, repeat: int) -> dict[str, float]:
    asset = normalise(src, NormaliseOptions(up="z"))
    obj = work / f"{asset.name}.obj"
    for name, data in asset.files.items():
        (work / name).write_bytes(data)
    lossless, quantized = pack(asset), pack(asset, quantize=True)
    paths = {"mbin": work / "m.mbin", "mbinq": work / "q.mbin", "glb": work / "m.glb", "msh": work / "m.msh"}
    paths["mbin"].write_bytes(lossless)
    paths["mbinq"].write_bytes(quantized)
    packed = parse(lossless)
    paths["glb"].write_bytes(to_glb(packed))
    paths["msh"].write_bytes(to_msh(packed))
    raw = work / "m.raw"
    nv = packed.positions.shape[0]
    raw.write_bytes(np.asarray(packed.positions, "<f4").tobytes() + np.asarray(packed.indices, "<u4").tobytes())
    fresh = []
    for k in range(max(1, repeat // 2)):
        copy = work / f"fresh_{k}.obj"
        copy.write_bytes(obj.read_bytes())
        fresh.append(copy)
    r = {
        "triangles": float(packed.indices.shape[0]),
        "size_obj": obj.stat().st_size,
        "size_glb": paths["glb"].stat().st_size,
        "size_msh": paths["msh"].stat().st_size,
        "size_raw": raw.stat().st_size,
        "size_mbin": len(lossless),
        "size_mbinq": len(quantized),
        "t_obj": best(lambda: trimesh.load(obj, force="mesh"), max(1, repeat // 2)),
        "t_glb": best(lambda: trimesh.load(paths["glb"], force="mesh"), repeat),
        "t_msh": best(lambda: read_msh(paths["msh"]), repeat),
        "t_raw": best(lambda: read_raw(raw, nv), repeat),
        "t_mbin": best(lambda: load_mbin(paths["mbin"], True), repeat),
        "t_mbin_noverify": best(lambda: load_mbin(paths["mbin"], False), repeat),
        "t_mbinq": best(lambda: load_mbin(paths["mbinq"], True), repeat),
        "t_mj_mbin": best(lambda: mujoco_from_mbin(paths["mbin"]), max(1, repeat // 2)),
        "t_mj_obj": best(lambda: mujoco_from_obj(fresh), max(1, repeat // 2)),
    }
    return r


def ms(t: float) -> str:
    return f"{t * 1000:.2f}" if t < 0.1 else f"{t * 1000:.0f}"


def table(rows: list[tuple[str, dict[str, float]]], repeat: int) -> str:
    lines = [
        BEGIN,
        "## Loading: .mbin vs OBJ, GLB, MSH, raw arrays and MuJoCo",
        "",
        f"`python bench/load.py ../shared/corpus --repeat {repeat}`: best of {repeat} wall-clock runs (OBJ and MuJoCo "
        f"rows best of {max(1, repeat // 2)}), same normalised mesh in every format, files in the page cache.",
        f"Machine: {platform.machine()}, CPython {platform.python_version()}, numpy {np.__version__}, "
        f"trimesh {trimesh.__version__}, MuJoCo {mujoco.__version__}, meshtool {meshtool.__version__}.",
        "",
        "Load times in milliseconds:",
        "",
        "| mesh | triangles | OBJ (trimesh) | GLB (trimesh) | MSH (numpy) | raw np.frombuffer | .mbin verify | "
        ".mbin no verify | .mbin quantised | OBJ / .mbin | .mbin / raw |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows:
        lines.append(
            f"| {name} | {int(r['triangles'])} | {ms(r['t_obj'])} | {ms(r['t_glb'])} | {ms(r['t_msh'])} | "
            f"{ms(r['t_raw'])} | {ms(r['t_mbin'])} | {ms(r['t_mbin_noverify'])} | {ms(r['t_mbinq'])} | "
            f"{r['t_obj'] / r['t_mbin']:.0f}x | {r['t_mbin'] / r['t_raw']:.2f}x |"
        )
    lines += [
        "",
        "Sizes in bytes (ratios against GLB):",
        "",
        "| mesh | OBJ | GLB | MSH | raw | .mbin | .mbin quantised | .mbin / GLB | quantised / GLB |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows:
        lines.append(
            f"| {name} | {int(r['size_obj'])} | {int(r['size_glb'])} | {int(r['size_msh'])} | {int(r['size_raw'])} | "
            f"{int(r['size_mbin'])} | {int(r['size_mbinq'])} | {r['size_mbin'] / r['size_glb']:.2f} | "
            f"{r['size_mbinq'] / r['size_glb']:.2f} |"
        )
    lines += [
        "",
        "MuJoCo model compile, milliseconds (mesh processing dominates both; each OBJ compile reads a file MuJoCo "
        "has not cached):",
        "",
        "| mesh | MuJoCo compiling the OBJ | .mbin load + MjSpec uservert/userface compile | ratio |",
        "|---|---|---|---|",
    ]
    for name, r in rows:
        lines.append(f"| {name} | {ms(r['t_mj_obj'])} | {ms(r['t_mj_mbin'])} | {r['t_mj_obj'] / r['t_mj_mbin']:.2f}x |")
    lines += [
        "",
        "Sizes include everything each file holds: the GLB and .mbin carry materials and PNG textures, MSH and raw "
        "only arrays; .mbin also carries its metadata JSON (sources, findings, mass properties).",
        END,
    ]
    return "\n".join(lines)


def main() -> int:
    args = arguments(__doc__, 5)
    rows = []
    for name, src in corpus_meshes(args.corpus, MESHES):
        with tempfile.TemporaryDirectory() as tmp:
            r = measure(src, Path(tmp), args.repeat)
        rows.append((name, r))
        print(f"{name}: obj {r['t_obj']:.4f}s mbin {r['t_mbin']:.5f}s raw {r['t_raw']:.5f}s", flush=True)
    write_section(args.out, table(rows, args.repeat), BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
