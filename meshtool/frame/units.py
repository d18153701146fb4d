"""Units and axes: converting geometry to metres, Z-up, and noticing implausible sizes.

Conventions (``docs/conventions.md``): SI units, Z up, right-handed. OBJ has no unit and is Y-up by
convention; CAD exports are often Z-up already. Conversion to Z-up from Y-up is a rotation of +90 degrees
about X, ``(x, y, z) -> (x, -z, y)``, done as an exact permutation so repeated runs are bit-identical.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, info, warning
from meshtool.frame.consumers import ConsumerRef

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

_HEADER_UNIT = re.compile(
    r"\b(?:units?|uses|in|unit\s*[:=])\b[^.]*?\b(millimet(?:er|re)s?|mm|centimet(?:er|re)s?|cm|met(?:er|re)s?|"
    r"inch(?:es)?|feet|foot)\b",
    re.IGNORECASE,
)
_HEADER_WORDS = {"mm": "mm", "millimet": "mm", "cm": "cm", "centimet": "cm", "met": "m", "inch": "in", "fe": "ft"}
_HEADER_WORDS["fo"] = "ft"


@dataclass(frozen=True, slots=True)
class UnitEvidence:
    """What a file says about the unit of a mesh.

    Attributes:
        unit: The unit it implies (a key of :data:`UNIT_FACTORS`), or ``None`` for a scale that is no unit.
        scale: The uniform factor when the evidence is a scale that is no unit (``0.1``), else ``None``.
        source: ``consumer`` (a URDF/SDF/MJCF that uses the mesh), ``header`` (an exporter comment),
            ``format`` (the mesh file declares it: COLLADA, glTF) or ``suggestion`` (STL: CAD's usual mm).
        text: One phrase naming the evidence, e.g. ``robot.urdf (URDF, scale 0.001 0.001 0.001)``.
    """

    unit: str | None
    scale: float | None
    source: str
    text: str

    def describe(self) -> str:
        """``mm from robot.urdf (URDF, scale 0.001 0.001 0.001)``."""
        what = self.unit if self.unit else f"a scale of {self.scale:g}" if self.scale else "no uniform scale"
        return f"{what} from {self.text}"


def unit_of_scale(scale: tuple[float, float, float] | None) -> tuple[str | None, float | None]:
    """The unit a consumer's ``scale`` converts from, or the uniform factor when it is no unit.

    Args:
        scale: (x, y, z) scale; ``None`` means 1 1 1. A mirrored axis (``-0.001 0.001 0.001``) still tells
            the unit.

    Returns:
        (unit, None) when the magnitude is a unit's factor, (None, factor) for another uniform positive
        magnitude, (None, None) when the magnitudes differ.
    """
    if scale is None:
        return "m", None
    magnitudes = [abs(v) for v in scale]
    if not all(math.isfinite(m) and m > 0 for m in magnitudes):
        return None, None
    if max(magnitudes) - min(magnitudes) > 1e-9 * max(magnitudes):
        return None, None
    for unit in UNIT_FACTORS:
        if math.isclose(magnitudes[0], unit_scale(unit), rel_tol=1e-6):
            return unit, None
    return None, magnitudes[0]


def header_unit(header_comments: Sequence[str]) -> str | None:
    """The unit an exporter's header comment declares (``# This file uses centimeters as units``)."""
    for line in header_comments:
        match = _HEADER_UNIT.search(line)
        if match:
            word = match.group(1).lower()
            return next(u for prefix, u in _HEADER_WORDS.items() if word.startswith(prefix))
    return None


def unit_evidence(consumers: Sequence[ConsumerRef], header_comments: Sequence[str]) -> UnitEvidence | None:
    """The strongest evidence of a mesh's unit: the nearest consumer file, else an exporter header.

    Args:
        consumers: References to the mesh in description files, nearest first.
        header_comments: The OBJ's header comments.

    Returns:
        The evidence, or ``None``.
    """
    if consumers:
        first = consumers[0]
        unit, factor = unit_of_scale(first.scale)
        others = {unit_of_scale(c.scale) for c in consumers[1:]} - {(unit, factor)}
        note = f"; {len(others)} other file(s) disagree" if others else ""
        return UnitEvidence(unit, factor, "consumer", first.describe() + note)
    unit = header_unit(header_comments)
    if unit is not None:
        line = next(c for c in header_comments if _HEADER_UNIT.search(c))
        return UnitEvidence(unit, None, "header", f"the exporter header {line.strip()[:70]!r}")
    return None


def evidence_findings(evidence: UnitEvidence | None, units: str, scale: float, path: str) -> list[Finding]:
    """A finding comparing the units used with the evidence (``units-evidence``).

    Args:
        evidence: From :func:`unit_evidence`.
        units: The unit applied.
        scale: The extra scale applied.
        path: The source file for the finding.

    Returns:
        An info finding when the output agrees with a consumer file, a warning when it disagrees with one
        (header evidence only ever gives an info: exporters write boilerplate).
    """
    if evidence is None:
        return []
    if agrees_with(evidence, unit_scale(units) * scale):
        return [info("units-evidence", f"units agree with the evidence: {evidence.describe()}", path)]
    if evidence.source == "consumer" and (evidence.unit is not None or evidence.scale is not None):
        fix = f"--units {evidence.unit}" if evidence.unit else f"--scale {evidence.scale:g}"
        return [
            warning(
                "units-evidence",
                f"read as {units} x{scale:g} but the evidence says {evidence.describe()}: pass --units auto or {fix}",
                path,
            )
        ]
    return [info("units-evidence", f"read as {units} x{scale:g}; evidence: {evidence.describe()}", path)]


def agrees_with(evidence: UnitEvidence, metres_per_unit: float) -> bool:
    """Whether the factor applied to the source (metres per source unit, ``--scale`` included) is the evidence's."""
    wanted = unit_scale(evidence.unit) if evidence.unit is not None else evidence.scale
    return wanted is not None and math.isclose(metres_per_unit, wanted, rel_tol=1e-9)


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


def scale_findings(
    extent: FloatArray,
    path: str,
    unit_given: bool,
    evidence: UnitEvidence | None = None,
    applied: float | None = None,
    explicit: str | None = None,
) -> list[Finding]:
    """A ``scale-suspicious`` finding when the largest extent is implausible for a robot-world object.

    A size that something vouches for is no warning but a ``scale-unusual`` info: a consumer file (URDF, SDF,
    MJCF) that uses the mesh at the factor applied (a Gazebo ground plane 10.9 m long in metres), or a unit the
    user named with ``--units``.

    Args:
        extent: (3,) bounding-box size in metres, Z-up.
        path: The source file for the finding.
        unit_given: Whether the unit was chosen rather than the default metres (changes the advice).
        evidence: What files say about the unit (:func:`unit_evidence`); a consumer file's unit is
            suggested instead of a size-based guess and named in the message.
        applied: Metres per source unit applied (unit factor times ``--scale``), compared with the evidence.
        explicit: The unit the user named with ``--units`` (not ``auto``), or ``None``.

    Returns:
        Zero or one finding.
    """
    largest = float(np.max(extent)) if extent.size else 0.0
    if not math.isfinite(largest) or MIN_PLAUSIBLE_M <= largest <= MAX_PLAUSIBLE_M or largest == 0.0:
        return []
    axis = int(np.argmax(extent))
    shape = ("long (along x)", "wide (along y)", "tall")[axis]
    size = f"{largest:.1f} m" if largest >= 10 else f"{largest * 1000:.3g} mm"
    vouched = evidence is not None and evidence.source == "consumer" and applied is not None
    if vouched and evidence is not None and applied is not None and agrees_with(evidence, applied):
        return [info("scale-unusual", f"{size} {shape}: the size {evidence.text} gives it, kept", path)]
    if explicit is not None:
        given = f"{size} {shape} read as {UNIT_WORDS[explicit]} (--units {explicit}): kept"
        return [info("scale-unusual", given, path)]
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
    if evidence is not None and evidence.unit is not None and not unit_given and evidence.source != "format":
        advice = (
            f"{evidence.describe()} ({largest * unit_scale(evidence.unit):.3g} m): pass --units {evidence.unit}"
            + (" or --units auto" if evidence.source == "consumer" else "")
        )
    if unit_given:
        advice = "check --units and --scale"
    return [warning("scale-suspicious", f"{size} {shape}: {advice}", path)]
