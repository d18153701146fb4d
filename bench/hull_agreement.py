"""The numpy convex hull against qhull (scipy) on every corpus OBJ it is used for.

Usage: python bench/hull_agreement.py ../shared/corpus [--out docs/benchmarks.md]

For each corpus OBJ (at most 12 MB) whose distinct vertices number at most
``meshtool.hulls.compute.NUMPY_HULL_POINTS`` (larger ones go to qhull), on the normalised positions:
  * exact: ``quickhull.hull3(points)`` against ``scipy.spatial.ConvexHull(points)``: same volume (relative
    difference), our vertex set containing qhull's (ours may keep a point lying on a face qhull merged);
  * budget 64 (the default): ``hull3(points, 64)`` against farthest-point insertion over qhull's vertices
    (``meshtool.hulls.compute._farthest_insertion``, the qhull path's own reduction): same vertex set or not, volumes;
  * CPU of both, this process (scipy imported beforehand, so its import is not counted).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from _report import arguments, load_average, write_section
from scipy.spatial import ConvexHull

from meshtool.errors import MeshtoolError
from meshtool.hulls.compute import NUMPY_HULL_POINTS, _farthest_insertion
from meshtool.hulls.quickhull import hull3
from meshtool.repair.normalise import NormaliseOptions, prepare

BEGIN, END = "<!-- hull-agreement:begin -->", "<!-- hull-agreement:end -->"


def volume(points: np.ndarray, faces: np.ndarray) -> float:
    tri = points[faces] - points.mean(axis=0)
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)


def main() -> int:
    args = arguments(__doc__, 1)
    before = load_average()
    files = sorted(p for p in Path(args.corpus).rglob("*.obj") if p.stat().st_size <= 12e6)
    stats = {"meshes": 0, "exact same volume": 0, "exact contains qhull's": 0, "exact declined": 0}
    stats |= {"budget same set": 0, "budget same volume": 0, "budget larger": 0, "budget smaller": 0}
    worst_exact, worst_budget = 0.0, 0.0
    ours_s = theirs_s = 0.0
    for path in files:
        try:
            asset = prepare(path, NormaliseOptions(strict=False))
        except MeshtoolError:
            continue
        points = np.unique(asset.mesh.positions, axis=0)
        if not 4 <= len(points) <= NUMPY_HULL_POINTS:
            continue
        try:
            reference = ConvexHull(points)
        except Exception:  # flat or degenerate: the pipeline thickens these first
            continue
        stats["meshes"] += 1
        cpu = time.process_time()
        exact, budget = hull3(points), hull3(points, 64)
        ours_s += time.process_time() - cpu
        cpu = time.process_time()
        expected = _farthest_insertion(points[np.sort(ConvexHull(points).vertices)], 64)
        theirs_s += time.process_time() - cpu
        if exact is None or budget is None:
            stats["exact declined"] += 1
            continue
        difference = abs(volume(points[exact.vertices], exact.faces) / reference.volume - 1)
        worst_exact = max(worst_exact, difference)
        stats["exact same volume"] += difference <= 1e-9
        ours = set(map(tuple, points[exact.vertices].tolist()))
        stats["exact contains qhull's"] += set(map(tuple, points[reference.vertices].tolist())) <= ours
        chosen = sorted(map(tuple, points[budget.vertices].tolist()))
        stats["budget same set"] += chosen == sorted(map(tuple, expected.tolist()))
        theirs = ConvexHull(expected).volume
        ratio = volume(points[budget.vertices], budget.faces) / theirs - 1
        worst_budget = max(worst_budget, abs(ratio))
        key = "budget same volume" if abs(ratio) <= 1e-9 else "budget larger" if ratio > 0 else "budget smaller"
        stats[key] += 1
    n, contains = stats["meshes"], stats["exact contains qhull's"]
    lines = [
        BEGIN,
        "## The numpy convex hull against qhull",
        "",
        f"`python bench/hull_agreement.py ../shared/corpus`: every corpus OBJ of at most 12 MB whose distinct "
        f"vertices number at most {NUMPY_HULL_POINTS} (the ones `obj2bin`'s single hull makes in numpy, "
        f"`meshtool/hulls/quickhull.py`; larger ones go to qhull): {n} meshes. {before} before, "
        f"{load_average()} after.",
        "",
        "| check | meshes |",
        "|---|---|",
        f"| exact hull: volume equal to qhull's (relative difference <= 1e-9) | {stats['exact same volume']} of {n} |",
        f"| exact hull: every qhull vertex is ours | {contains} of {n} |",
        f"| declined (qhull used instead) | {stats['exact declined']} of {n} |",
        f"| 64-vertex hull: the same vertices as farthest insertion over qhull's vertices | "
        f"{stats['budget same set']} of {n} |",
        f"| 64-vertex hull: same volume / larger / smaller | {stats['budget same volume']} / "
        f"{stats['budget larger']} / {stats['budget smaller']} |",
        "",
        f"Largest relative volume difference: exact {worst_exact:.1e}, 64 vertices {worst_budget:.1e} (where "
        f"near-equal candidates are picked in another order). CPU for all meshes, scipy already imported: numpy "
        f"hulls (exact and 64) {ours_s:.2f} s, qhull + insertion {theirs_s:.2f} s; a process that needs none of "
        "scipy saves its import (about 0.3 s CPU) besides.",
        END,
    ]
    write_section(args.out, "\n".join(lines), BEGIN, END)
    print("\n".join(lines[8:14]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
