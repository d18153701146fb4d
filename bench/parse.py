"""OBJ parse benchmark: meshtool's reader against trimesh and the C++ tinyobjloader, same run, same files.

Usage: python bench/parse.py ../shared/corpus [--repeat 5] [--peer-python .bench-peers/bin/python]
       [--out docs/benchmarks.md]

Contenders, interleaved for --repeat rounds, file read included, process CPU and wall-clock:
  * meshtool parse: ``parse_obj(path.read_bytes())`` (arrays, polygons as written, line-accurate findings);
  * meshtool mesh: parse + triangulation + cleaning (``build_mesh``), what the normaliser uses;
  * trimesh.load(path) with its defaults, and with ``process=False``;
  * tinyobjloader (C++, ``tinyobjloader==2.0.0rc13`` in the peers' environment, ``make bench`` installs it):
    ``ObjReader.ParseFromFile`` with triangulation plus its numpy arrays, timed inside a peer process
    (the process start is not counted).
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import trimesh
from _report import Timing, arguments, corpus_meshes, interleave, load_average, timed, write_section

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
PEER = """
import json, sys, time
import numpy
import tinyobjloader
path = sys.argv[1]
cpu, wall = time.process_time(), time.perf_counter()
reader = tinyobjloader.ObjReader()
config = tinyobjloader.ObjReaderConfig()
config.triangulate = True
if not reader.ParseFromFile(path, config):
    raise SystemExit(reader.Error())
attrib = reader.GetAttrib()
arrays = [attrib.numpy_vertices()] + [shape.mesh.numpy_indices() for shape in reader.GetShapes()]
print(json.dumps([time.perf_counter() - wall, time.process_time() - cpu]))
"""


def peer(python: str, path: Path) -> tuple[float, float]:
    out = subprocess.run([python, "-c", PEER, str(path)], capture_output=True, text=True, check=True).stdout
    wall, cpu = json.loads(out.strip().splitlines()[-1])
    return float(wall), float(cpu)


def measure(path: Path, repeat: int, peer_python: str | None) -> tuple[dict[str, float], dict[str, Timing]]:
    mesh, _ = build_mesh(parse_obj(path.read_bytes(), path.name))
    contenders = {
        "parse": timed(lambda: parse_obj(path.read_bytes(), path.name)),
        "mesh": timed(lambda: build_mesh(parse_obj(path.read_bytes(), path.name))),
        "trimesh": timed(lambda: trimesh.load(path, force="mesh")),
        "trimesh raw": timed(lambda: trimesh.load(path, force="mesh", process=False)),
    }
    if peer_python:
        contenders["tinyobjloader"] = lambda: peer(peer_python, path)
    info = {"mb": path.stat().st_size / 1e6, "triangles": float(mesh.faces.shape[0])}
    return info, interleave(contenders, repeat)


def table(rows: list[tuple[str, dict[str, float], dict[str, Timing]]], repeat: int) -> str:
    has_peer = all("tinyobjloader" in t for _, _, t in rows)
    lines = [
        BEGIN,
        "## OBJ parsing: meshtool vs trimesh and tinyobjloader",
        "",
        f"`make bench` (`python bench/parse.py ../shared/corpus --repeat {repeat} --peer-python "
        f".bench-peers/bin/python`): contenders interleaved, {repeat} rounds, file read included. Seconds as "
        "min / median of process CPU (wall in the second table). Machine: "
        f"{platform.machine()}, CPython {platform.python_version()}, numpy {np.__version__}, trimesh "
        f"{trimesh.__version__}, meshtool {meshtool.__version__}; {load_average()} at the end of the run.",
        "",
        "*parse* = `parse_obj` (arrays, polygons); *mesh* = parse + triangulation + cleaning (`build_mesh`), "
        "the like-for-like peer of `trimesh.load` and of tinyobjloader with `triangulate`. Goals (issue 17): "
        "mesh >= 3x faster than trimesh.load and within 1.5x of tinyobjloader.",
        "",
        "| mesh | MB | triangles | meshtool parse | meshtool mesh | trimesh.load | trimesh process=False | "
        "tinyobjloader | trimesh / mesh | mesh / tinyobjloader |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, info, t in rows:
        tiny = t.get("tinyobjloader")

        def cell(x: Timing) -> str:
            return f"{x.cpu_min:.3f} / {x.cpu_median:.3f}"

        lines.append(
            f"| {name} | {info['mb']:.1f} | {int(info['triangles'])} | {cell(t['parse'])} | {cell(t['mesh'])} | "
            f"{cell(t['trimesh'])} | {cell(t['trimesh raw'])} | {cell(tiny) if tiny else '-'} | "
            f"{t['trimesh'].cpu_median / t['mesh'].cpu_median:.2f}x | "
            f"{(t['mesh'].cpu_median / tiny.cpu_median) if tiny else float('nan'):.2f}x |"
        )
    lines += [
        "",
        "Wall-clock, min / median s:",
        "",
        "| mesh | meshtool parse | meshtool mesh | trimesh.load | trimesh process=False | tinyobjloader |",
        "|---|---|---|---|---|---|",
    ]
    for name, _, t in rows:
        cells = [
            f"{t[k].wall_min:.3f} / {t[k].wall_median:.3f}" if k in t else "-"
            for k in ("parse", "mesh", "trimesh", "trimesh raw", "tinyobjloader")
        ]
        lines.append(f"| {name} | {' | '.join(cells)} |")
    lines += [
        "",
        "Triangle counts are meshtool's after dropping degenerate triangles."
        + ("" if has_peer else " tinyobjloader was not available (run `make bench`)."),
        END,
    ]
    return "\n".join(lines)


def main() -> int:
    args = arguments(__doc__, 5)
    rows = []
    for name, path in corpus_meshes(args.corpus, MESHES):
        info, timings = measure(path, args.repeat, args.peer_python)
        rows.append((name, info, timings))
        m, tm = timings["mesh"], timings["trimesh"]
        print(f"{name}: mesh {m.cpu_median:.3f}s CPU, trimesh {tm.cpu_median:.3f}s", flush=True)
    write_section(args.out, table(rows, args.repeat), BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
