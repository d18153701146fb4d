"""OBJ parse benchmark: meshtool's reader against trimesh.load, in one run, on the same files.

Usage: python bench/parse.py ../shared/corpus [--repeat 3] [--out docs/benchmarks.md]

For each mesh it times (best of --repeat, wall clock, file read included):
  * meshtool parse: ``parse_obj(path.read_bytes())`` (arrays, polygons as written)
  * meshtool mesh: parse + triangulation + cleaning (``build_mesh``), comparable to what trimesh returns
  * trimesh.load(path) with its defaults (merges vertices, triangulates)
  * trimesh.load(path, process=False)
and writes the table, with trimesh / meshtool ratios, into docs/benchmarks.md between the
``<!-- parse:begin -->`` / ``<!-- parse:end -->`` markers (other sections of the file are kept).
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path

import numpy as np
import trimesh
from _report import arguments, best, corpus_meshes, write_section

import meshtool
from meshtool.mesh import build_mesh
from meshtool.obj.parse import parse_obj

MESHES = [
    ("stanford bunny, subdivided (1.11M tri)", "derived/stanford-bunny-subdiv2/stanford-bunny-subdiv2.obj"),
    ("ogre (124k tri)", "src/alecjacobson__common-3d-test-models/data/ogre.obj"),
    ("stanford bunny (69k tri)", "src/alecjacobson__common-3d-test-models/data/stanford-bunny.obj"),
    ("beast, quads + n-gons (64k tri)", "src/alecjacobson__common-3d-test-models/data/beast.obj"),
    ("fuze, uv + normals (small)", "src/mikedh__trimesh/models/fuze.obj"),
]
BEGIN, END = "<!-- parse:begin -->", "<!-- parse:end -->"


def measure(path: Path, repeat: int) -> dict[str, float | int]:
    def ours_parse() -> object:
        return parse_obj(path.read_bytes(), path.name)

    def ours_mesh() -> object:
        return build_mesh(parse_obj(path.read_bytes(), path.name))

    mesh, _ = ours_mesh()  # type: ignore[misc]
    tm = trimesh.load(path, force="mesh")
    return {
        "mb": path.stat().st_size / 1e6,
        "triangles": int(mesh.faces.shape[0]),
        "trimesh_triangles": len(tm.faces),
        "parse": best(ours_parse, repeat),
        "mesh": best(ours_mesh, repeat),
        "trimesh": best(lambda: trimesh.load(path, force="mesh"), repeat),
        "trimesh_raw": best(lambda: trimesh.load(path, force="mesh", process=False), repeat),
    }


def table(rows: list[tuple[str, dict[str, float | int]]], repeat: int) -> str:
    lines = [
        BEGIN,
        "## OBJ parsing: meshtool vs trimesh",
        "",
        f"`python bench/parse.py ../shared/corpus --repeat {repeat}`: best of {repeat} wall-clock runs, file read "
        "included, one process, same files.",
        f"Machine: {platform.machine()}, {platform.python_implementation()} {platform.python_version()}, "
        f"numpy {np.__version__}, trimesh {trimesh.__version__}, meshtool {meshtool.__version__}.",
        "",
        "*parse* = `parse_obj` (arrays, polygons); *mesh* = parse + ear-clipping triangulation + cleaning "
        "(`build_mesh`), the like-for-like peer of `trimesh.load`. Ratios are trimesh time / meshtool time "
        "(higher is better for meshtool). Text-to-number conversion (fastnumbers, numpy) is about half of "
        "meshtool's time.",
        "",
        "| mesh | MB | triangles | meshtool parse s | meshtool mesh s | trimesh.load s | trimesh process=False s "
        "| parse vs trimesh.load | mesh vs trimesh.load | mesh vs process=False |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows:
        lines.append(
            f"| {name} | {r['mb']:.1f} | {r['triangles']} | {r['parse']:.3f} | {r['mesh']:.3f} | {r['trimesh']:.3f} | "
            f"{r['trimesh_raw']:.3f} | {r['trimesh'] / r['parse']:.1f}x | {r['trimesh'] / r['mesh']:.1f}x | "
            f"{r['trimesh_raw'] / r['mesh']:.1f}x |"
        )
    lines.append("")
    lines.append(
        "Triangle counts are meshtool's after dropping degenerate triangles; trimesh's differ where it merges or "
        "drops faces differently."
    )
    lines.append(END)
    return "\n".join(lines)


def main() -> int:
    args = arguments(__doc__, 3)
    rows = []
    for name, path in corpus_meshes(args.corpus, MESHES):
        r = measure(path, args.repeat)
        rows.append((name, r))
        print(f"{name}: mesh {r['mesh']:.3f}s trimesh {r['trimesh']:.3f}s ({r['trimesh'] / r['mesh']:.1f}x)")
    write_section(args.out, table(rows, args.repeat), BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
