"""Collision rules (C001..C004): hull budgets and how well the hulls fit the mesh.

For an OBJ source the hulls checked are the ones ``obj2bin`` makes by default (one convex hull within the
vertex budget); for an ``.mbin`` they are the hulls stored in the pack.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding
from meshtool.hulls.compute import Hull, hull_fit
from meshtool.validate.config import Limits
from meshtool.validate.rules import hit

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def collision_findings(
    positions: FloatArray, faces: IntArray, hulls: list[Hull], path: str, limits: Limits
) -> tuple[list[Finding], dict[str, object]]:
    """C001..C003 for a mesh and its collision hulls.

    Args:
        positions: (n, 3) mesh vertices, metres.
        faces: (m, 3) triangles.
        hulls: The collision hulls (none: nothing to check).
        path: The file named in the findings.
        limits: Budgets and thresholds.

    Returns:
        The findings and the fit report of :func:`meshtool.hulls.compute.hull_fit`.
    """
    out: list[Finding] = []
    if not hulls:
        return out, {"hulls": 0}
    if len(hulls) > limits.max_hulls:
        out.append(hit("C001", f"{len(hulls)} hulls, budget {limits.max_hulls}", path))
    largest = max(len(h.vertices) for h in hulls)
    if largest > limits.max_hull_vertices:
        over = sum(len(h.vertices) > limits.max_hull_vertices for h in hulls)
        out.append(hit("C002", f"{over} hull(s) over {limits.max_hull_vertices} vertices (largest {largest})", path))
    report = hull_fit(positions, faces, hulls)
    ratio = report.get("volume_ratio")
    volume = report.get("mesh_volume_m3")
    box = float(np.prod(np.ptp(positions, axis=0))) if len(positions) else 0.0
    thin = isinstance(volume, float) and (volume < limits.min_volume_m3 or volume < limits.min_volume_fraction * box)
    if isinstance(ratio, float) and ratio > limits.max_hull_volume_ratio and not thin:  # thin: G010's business
        out.append(
            hit(
                "C003",
                f"the hulls hold {ratio:.2f}x the mesh's volume (limit {limits.max_hull_volume_ratio:g}x): "
                "contacts happen in empty space",
                path,
            )
        )
    gap = report.get("surface_to_hulls_max_m")
    diagonal = float(np.linalg.norm(np.ptp(positions, axis=0))) if len(positions) else 0.0
    if isinstance(gap, float) and diagonal > 0 and gap > limits.max_hull_gap * diagonal:
        out.append(
            hit(
                "C003",
                f"parts of the surface lie {gap:.3g} m outside every hull "
                f"({gap / diagonal:.1%} of the size; limit {limits.max_hull_gap:.0%})",
                path,
            )
        )
    return out, report
