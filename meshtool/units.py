"""Units and axes: converting geometry to metres, Z-up, and noticing implausible sizes.

Conventions (``docs/conventions.md``): SI units, Z up, right-handed. OBJ has no unit and is Y-up by
convention; CAD exports are often Z-up already. Conversion to Z-up from Y-up is a rotation of +90 degrees
about X, ``(x, y, z) -> (x, -z, y)``, done as an exact permutation so repeated runs are bit-identical.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, warning

Unit = Literal["m", "cm", "mm", "in", "ft"]
UpAxis = Literal["y", "z"]

#: Metres per unit, as (numerator, denominator) so that cm and mm divide exactly by an integer.
UNIT_FACTORS: dict[str, tuple[float, int]] = {
    "m": (1.0, 1),
    "cm": (1.0, 100),
    "mm": (1.0, 1000),
    "in": (0.0254, 1),
    "ft": (0.3048, 1),
}
UNIT_WORDS = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches", "ft": "feet"}

#: Largest and smallest plausible extent of one asset, metres.
MAX_PLAUSIBLE_M = 10.0
MIN_PLAUSIBLE_M = 0.001
#: Units suggested for an oversized mesh, in order of preference, and the size range they should produce.
SUGGESTED_UNITS = ("cm", "mm", "in")
PLAUSIBLE_OBJECT_M = (0.02, 3.0)

FloatArray = npt.NDArray[np.float64]


def unit_scale(unit: str) -> float:
    """Metres per ``unit``."""
    num, den = UNIT_FACTORS[unit]
    return num / den


def apply_scale(points: FloatArray, unit: str, scale: float) -> FloatArray:
    """Convert points to metres: multiply by the unit's factor, then by ``scale``.

    Args:
        points: (N, 3) coordinates in ``unit``.
        unit: One of :data:`UNIT_FACTORS`.
        scale: Extra uniform factor (1.0 for none).

    Returns:
        (N, 3) coordinates in metres (a new array).
    """
    num, den = UNIT_FACTORS[unit]
    out = points * num if num != 1.0 else points.copy()
    if den != 1:
        out = out / den
    if scale != 1.0:
        out = out * scale
    return out


def to_z_up(vectors: FloatArray, up: str) -> FloatArray:
    """Rotate (N, 3) points or directions from ``up`` axis convention to Z-up.

    Args:
        vectors: (N, 3) array.
        up: ``y`` (rotate +90 degrees about X) or ``z`` (unchanged).

    Returns:
        A new (N, 3) array.
    """
    if up == "z":
        return vectors.copy()
    out = np.empty_like(vectors)
    out[:, 0] = vectors[:, 0]
    out[:, 1] = -vectors[:, 2]
    out[:, 2] = vectors[:, 1]
    return out


def rotation_matrix(up: str) -> list[list[float]]:
    """The 3x3 rotation :func:`to_z_up` applies, row-major."""
    if up == "z":
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    return [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]


def scale_findings(extent: FloatArray, path: str, unit_given: bool) -> list[Finding]:
    """A ``scale-suspicious`` finding when the largest extent is implausible for a robot-world object.

    Args:
        extent: (3,) bounding-box size in metres, Z-up.
        path: The source file for the finding.
        unit_given: Whether the user chose the unit (changes the advice).

    Returns:
        Zero or one finding.
    """
    largest = float(np.max(extent)) if extent.size else 0.0
    if not math.isfinite(largest) or MIN_PLAUSIBLE_M <= largest <= MAX_PLAUSIBLE_M or largest == 0.0:
        return []
    axis = int(np.argmax(extent))
    shape = ("long (along x)", "wide (along y)", "tall")[axis]
    size = f"{largest:.1f} m" if largest >= 10 else f"{largest * 1000:.3g} mm"
    if largest > MAX_PLAUSIBLE_M:
        plausible = [
            u for u in SUGGESTED_UNITS if PLAUSIBLE_OBJECT_M[0] <= largest * unit_scale(u) <= PLAUSIBLE_OBJECT_M[1]
        ]
        best = (
            plausible[0]
            if plausible
            else min(SUGGESTED_UNITS, key=lambda u: abs(math.log(largest * unit_scale(u) / 0.5)))
        )
        advice = f"if it was modelled in {UNIT_WORDS[best]}, pass --units {best} ({largest * unit_scale(best):.3g} m)"
    else:
        advice = "check the source units (--units) or pass --scale"
    if unit_given:
        advice = "check --units and --scale"
    return [warning("scale-suspicious", f"{size} {shape}: {advice}", path)]
