"""Every mesh format through meshtool's readers: outcome per real file, and parse speed against trimesh.

Usage: python bench/formats_check.py ../shared/robots [--corpus ../shared/corpus] [--derived 10] [--json OUT] [--docs]

1. **Outcome**: every STL, COLLADA, PLY, glTF/GLB and OBJ file under the robots folder is normalised in memory
   (:func:`meshtool.repair.normalise.prepare`, default options) and checked against an independent parser
   (``trimesh.load``, ``process=False``, scene graph applied): the same triangle count and the same bounding
   box of the geometry in the file's own units and axes (meshtool's reader output, before the frame change).
   COLLADA materials and textures kept are counted.
2. **Speed**: each file is parsed by meshtool's reader (bytes in memory -> the mesh model) and by
   ``trimesh.load`` (bytes in memory -> ``Trimesh``/``Scene``), best of three, per format. The shared data
   holds no glTF or PLY, so ``--derived N`` also converts the N largest corpus OBJs with trimesh into GLB,
   binary PLY and binary STL in a scratch folder and times those (labelled *derived*).

Prints the Markdown sections; ``--docs`` writes them into docs/corpus.md and docs/benchmarks.md (between
``<!-- formats:begin/end -->`` markers), ``--json`` the raw rows. A crash
(an exception that is not a ``MeshtoolError``) fails the script.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import sys
import tempfile
import time
import warnings
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from _report import write_section

from meshtool.errors import MeshtoolError
from meshtool.files.resolve import Resolver
from meshtool.read import FORMATS, format_of, read_mesh
from meshtool.repair.mesh import build_mesh
from meshtool.repair.normalise import prepare

TRIMESH_TYPE = {"obj": "obj", "stl": "stl", "ply": "ply", "gltf": "gltf", "glb": "glb", "collada": "dae"}


def mesh_files(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() in FORMATS)


def ours(path: Path) -> tuple[Any, float]:
    data = path.read_bytes()
    resolver = Resolver(path.parent, [path.parent.parent])
    start = time.perf_counter()
    mesh = read_mesh(path, data, path.name, resolver)
    return mesh, time.perf_counter() - start


def theirs(path: Path, process: bool = False) -> tuple[Any, float]:
    data = path.read_bytes()
    resolver = trimesh.resolvers.FilePathResolver(str(path))
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = trimesh.load(
            io.BytesIO(data), file_type=TRIMESH_TYPE[format_of(path)], resolver=resolver, process=process
        )
    return loaded, time.perf_counter() - start


def trimesh_geometry(loaded: Any) -> tuple[int, np.ndarray | None]:
    """Triangles and bounding box (2, 3) of what trimesh loaded, scene graph applied."""
    if isinstance(loaded, trimesh.Scene):
        meshes = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
    elif isinstance(loaded, trimesh.Trimesh):
        meshes = [loaded]
    else:
        meshes = []
    meshes = [m for m in meshes if len(m.faces)]
    if not meshes:
        return 0, None
    points = np.concatenate([m.vertices[m.faces.reshape(-1)] for m in meshes])
    return int(sum(len(m.faces) for m in meshes)), np.stack([points.min(axis=0), points.max(axis=0)])


def outcome(path: Path) -> dict[str, Any]:
    fmt = format_of(path)
    row: dict[str, Any] = {"file": str(path), "format": fmt}
    try:
        asset = prepare(path)
    except MeshtoolError as exc:
        row.update(status="error", error=exc.one_line())
        return row
    row.update(
        status="ok",
        triangles=asset.stats["triangles"],
        materials=len(asset.materials),
        textures=len(asset.textures),
        codes=sorted({f.code for f in asset.findings}),
        warnings=sum(f.severity.value == "warning" for f in asset.findings),
    )
    mesh, _ = ours(path)
    built, _ = build_mesh(mesh)
    count, box = trimesh_geometry(theirs(path)[0])
    p = built.positions[built.faces.reshape(-1)] if built.faces.size else np.zeros((0, 3))
    ours_box = np.stack([p.min(axis=0), p.max(axis=0)]) if p.size else None
    row["read_triangles"] = int(mesh.face_sizes.size) if fmt != "obj" else int((mesh.face_sizes - 2).sum())
    row["trimesh_triangles"] = count
    scale = float(np.abs(box).max()) if box is not None else 1.0
    row["bbox_agrees"] = bool(
        box is not None and ours_box is not None and np.allclose(box, ours_box, atol=1e-6 * scale)
    )
    row["triangles_agree"] = row["read_triangles"] == count or built.faces.shape[0] + built.degenerate == count
    return row


def timing(path: Path, repeat: int = 3) -> dict[str, float]:
    best_ours = min(ours(path)[1] for _ in range(repeat))
    best_theirs = min(theirs(path)[1] for _ in range(repeat))
    merged = min(theirs(path, process=True)[1] for _ in range(repeat))
    return {"bytes": path.stat().st_size, "meshtool_s": best_ours, "trimesh_s": best_theirs, "trimesh_merge_s": merged}


def derived(corpus: Path, count: int, folder: Path) -> list[Path]:
    """The ``count`` largest corpus OBJs written by trimesh as GLB, binary PLY and binary STL."""
    objs = sorted(corpus.rglob("*.obj"), key=lambda p: p.stat().st_size, reverse=True)[:count]
    out = []
    for k, obj in enumerate(objs):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh = trimesh.load(obj, force="mesh", process=False)
        for suffix in ("glb", "ply", "stl"):
            target = folder / f"m{k:02d}.{suffix}"
            target.write_bytes(mesh.export(file_type=suffix))  # type: ignore[no-untyped-call, call-arg]
            out.append(target)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robots", type=Path)
    parser.add_argument("--corpus", type=Path, default=None)
    parser.add_argument("--derived", type=int, default=10)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--docs", action="store_true", help="write the sections into docs/corpus.md and docs/benchmarks.md"
    )
    args = parser.parse_args()

    files = mesh_files(args.robots)
    rows = [outcome(p) for p in files]
    by_format: dict[str, Counter[str]] = defaultdict(Counter)
    for r in rows:
        c = by_format[r["format"]]
        c["files"] += 1
        c[r["status"]] += 1
        if r["status"] == "ok":
            c["triangles"] += r["triangles"]
            c["agree"] += int(r["bbox_agrees"] and r["triangles_agree"])
            c["with_materials"] += int(r["materials"] > 0)
            c["textures"] += r["textures"]
            c["warnings"] += r["warnings"]
    out = [
        "<!-- formats:begin -->",
        "## Other mesh formats: the robots' STL, COLLADA and OBJ meshes",
        "",
        f"`python bench/formats_check.py {args.robots} --docs` (issue 20): every mesh file under the robots folder "
        "normalised with default options; *same as trimesh*: the triangle count and the bounding box of meshtool's "
        "reader output (source units and axes) equal what `trimesh.load` (an independent parser, scene graph "
        "applied) reads from the same file. `../shared/corpus` holds only OBJ (the tables above). The shared "
        "data holds no glTF or PLY files; their readers are "
        "checked on the fixtures (`fixtures/formats/`) and on corpus meshes converted by trimesh (speed, "
        "docs/benchmarks.md).",
        "",
        "| format | files | normalised | errors | triangles | same as trimesh | with own materials "
        "| textures | warnings |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for fmt, c in sorted(by_format.items()):
        out.append(
            f"| {fmt} | {c['files']} | {c['ok']} | {c['error']} | {c['triangles']:,} | {c['agree']} of {c['ok']} | "
            f"{c['with_materials']} | {c['textures']} | {c['warnings']} |"
        )
    codes = Counter(code for r in rows if r["status"] == "ok" for code in r["codes"])
    out += ["", "Finding codes (number of files): " + ", ".join(f"`{k}` {v}" for k, v in sorted(codes.items())) + "."]
    differs = [r for r in rows if r["status"] != "ok" or not (r["bbox_agrees"] and r["triangles_agree"])]
    out += [
        f"- differs: `{Path(r['file']).name}`: {r.get('error') or 'geometry differs from trimesh'}" for r in differs
    ]
    out.append("<!-- formats:end -->")
    corpus_section = "\n".join(out)
    print(corpus_section)

    times: dict[str, list[dict[str, float]]] = defaultdict(list)
    for p in files:
        times[format_of(p)].append(timing(p))
    with tempfile.TemporaryDirectory(prefix="formats-check-") as tmp:
        if args.corpus is not None and args.derived > 0:
            for p in derived(args.corpus, args.derived, Path(tmp)):
                times[f"{format_of(p)} (derived)"].append(timing(p))
    bench = [
        "<!-- formats:begin -->",
        "## Mesh formats: meshtool's readers vs trimesh",
        "",
        f"`python bench/formats_check.py {args.robots} --corpus {args.corpus} --derived {args.derived} --docs`: "
        "best of 3 per file, bytes already in memory (file reading excluded), summed per format. "
        f"Machine: {platform.machine()}, CPython {platform.python_version()}, numpy {np.__version__}, trimesh "
        f"{trimesh.__version__}; load average {os.getloadavg()[0]:.1f} at the end of the run (shared machine: "
        "absolute times are inflated, ratios less so).",
        "",
        "*meshtool reader*: bytes -> the mesh model (STL: corners merged into shared vertices, facet normals "
        "checked; COLLADA: pycollada's parse, then welding; glTF and PLY keep their indexed vertices). trimesh "
        "`process=False` returns the arrays as stored (STL: three unshared corners per facet), the peer for "
        "glTF/PLY; `process=True` merges vertices as meshtool does for STL. "
        "*derived*: the 10 largest corpus OBJs written by trimesh as GLB, binary PLY and binary STL.",
        "",
        "| format | files | MB | meshtool reader s | trimesh process=False s | trimesh process=True s "
        "| meshtool MB/s | trimesh MB/s (False / True) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for fmt, entries in sorted(times.items()):
        mb = sum(e["bytes"] for e in entries) / 1e6
        a = sum(e["meshtool_s"] for e in entries)
        b = sum(e["trimesh_s"] for e in entries)
        merged = sum(e["trimesh_merge_s"] for e in entries)
        bench.append(
            f"| {fmt} | {len(entries)} | {mb:.1f} | {a:.3f} | {b:.3f} | {merged:.3f} | {mb / a:.1f} "
            f"| {mb / b:.1f} / {mb / merged:.1f} |"
        )
    bench.append("<!-- formats:end -->")
    bench_section = "\n".join(bench)
    print(bench_section)
    if args.docs:
        write_section(Path("docs/corpus.md"), corpus_section, "<!-- formats:begin -->", "<!-- formats:end -->")
        write_section(Path("docs/benchmarks.md"), bench_section, "<!-- formats:begin -->", "<!-- formats:end -->")
    if args.json:
        args.json.write_text(json.dumps({"outcome": rows, "timing": times}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
