"""``--up auto``: which axis of an OBJ is up, decided from evidence, strongest first.

1. A file meshtool wrote says so in its header (Z-up).
2. A consumer file (URDF, SDFormat or MJCF anywhere under the mesh's index root: its ROS package, Gazebo
   model, repository or Python package, or ``--model-root``; see :mod:`meshtool.frame.consumers`) references the
   mesh: those formats are Z-up and use mesh coordinates unrotated, so the mesh is Z-up.
3. The OBJ lies in a model root of a Z-up tool (Gazebo ``model.config``/``model.sdf``, a ROS
   ``package.xml`` found up to the repository root, or a URDF; :func:`meshtool.frame.modelroot.find_model_root`)
   even though no file found references it.
4. A name says it: the file or one of its folders is called like ``z_up``/``zup``/``z-up`` (or ``y_up``).
5. An exporter header says it (``Up axis: Z``, ``+Z up``), or names an exporter whose OBJ default is
   Y-up (Blender, Maya, 3ds Max, Wings 3D).
6. The geometry: a mesh that is flat and lies in the XY plane, or a ground-like extent (wide in X and Y,
   at least a metre across, and thin in Z), is Z-up; wide in X and Z and thin in Y is Y-up.
7. Otherwise the OBJ convention: Y-up.

The decision and its evidence become an ``up-axis`` finding (recorded in ``asset.json``).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from meshtool.formats import mesh_format, mesh_format_named
from meshtool.frame.consumers import ConsumerRef
from meshtool.frame.modelroot import ModelRoot

FloatArray = npt.NDArray[np.float64]

_Z_NAME = re.compile(r"(?:^|[^a-z0-9])z[-_ ]?up(?:[^a-z0-9]|$)", re.IGNORECASE)
_Y_NAME = re.compile(r"(?:^|[^a-z0-9])y[-_ ]?up(?:[^a-z0-9]|$)", re.IGNORECASE)
_HEADER_Z = re.compile(r"\bup[-_ ]?axis\W*\+?z\b|(?<![a-z0-9])\+?z[-_ ]?up\b|\bup\s*[:=]\s*\+?z\b", re.IGNORECASE)
_HEADER_Y = re.compile(r"\bup[-_ ]?axis\W*\+?y\b|(?<![a-z0-9])\+?y[-_ ]?up\b|\bup\s*[:=]\s*\+?y\b", re.IGNORECASE)
#: Exporters whose OBJ output is Y-up by default (word in the header comment -> name).
Y_UP_EXPORTERS = {"blender": "Blender", "maya": "Maya", "3ds max": "3ds Max", "wings 3d": "Wings 3D"}
#: Thin axis / smaller of the two others below which a mesh is "flat" in that axis.
FLAT_RATIO = 1e-6
#: Thin axis / smaller of the two others below which a wide mesh is ground-like, and the least width, m.
GROUND_RATIO = 0.05
GROUND_MIN_WIDTH_M = 1.0


@dataclass(frozen=True, slots=True)
class UpDecision:
    """The up axis chosen and why.

    Attributes:
        up: ``y`` or ``z``.
        rule: ``forced``, ``meshtool``, ``consumer``, ``model-root``, ``name``, ``header``, ``exporter``,
            ``flat``, ``ground`` or ``default``.
        evidence: One sentence naming the evidence.
    """

    up: str
    rule: str
    evidence: str


def decide_up(
    src: Path,
    positions: FloatArray,
    header_comments: Sequence[str],
    consumers: Sequence[ConsumerRef],
    root: ModelRoot | None,
    normalised_before: bool = False,
) -> UpDecision:
    """Decide the up axis of an OBJ from evidence (see the module docstring for the order).

    Args:
        src: The OBJ file (its name and folder names are evidence).
        positions: (N, 3) vertex positions in the source's axes, any unit.
        header_comments: The OBJ's header comment lines.
        consumers: References to the OBJ in description files (:func:`meshtool.frame.consumers.find_consumers`).
        root: The OBJ's model root, or ``None``.
        normalised_before: The file was written by meshtool.

    Returns:
        The decision.
    """
    if normalised_before:
        return UpDecision("z", "meshtool", "the file was written by meshtool (metres, Z-up)")
    if consumers:
        first = consumers[0]
        more = f" and {len(consumers) - 1} more reference(s)" if len(consumers) > 1 else ""
        return UpDecision(
            "z", "consumer", f"{first.describe()} uses the mesh as it is{more}; {first.format.upper()} is Z-up"
        )
    if root is not None and root.kind != "explicit":  # --model-root widens the search; it says nothing of axes
        return UpDecision("z", "model-root", f"it lies in a {root.kind} model ({root.marker}), which is Z-up")
    for part in reversed((*src.parent.parts[-3:], src.stem)):
        if _Z_NAME.search(part):
            return UpDecision("z", "name", f"the name {part!r} says Z-up")
        if _Y_NAME.search(part):
            return UpDecision("y", "name", f"the name {part!r} says Y-up")
    header = " ".join(header_comments)
    if _HEADER_Z.search(header):
        return UpDecision("z", "header", f"the header comment says Z-up ({_quote(header_comments, _HEADER_Z)})")
    if _HEADER_Y.search(header):
        return UpDecision("y", "header", f"the header comment says Y-up ({_quote(header_comments, _HEADER_Y)})")
    geometric = _geometry(positions)
    if geometric is not None:
        return geometric
    lowered = header.lower()
    for word, name in Y_UP_EXPORTERS.items():
        if word in lowered:
            return UpDecision("y", "exporter", f"exported by {name}, whose OBJ export is Y-up by default")
    return UpDecision("y", "default", f"no evidence of the frame: {_default_reason(src)}")


def _default_reason(src: Path) -> str:
    """Why Y-up: the format's fallback in the formats registry (OBJ's convention, or a format read like OBJ)."""
    return (mesh_format(src) or mesh_format_named("obj")).fallback_reason


def _geometry(positions: FloatArray) -> UpDecision | None:
    finite = positions[np.isfinite(positions).all(axis=1)] if positions.size else positions
    if finite.shape[0] < 3:
        return None
    extent = finite.max(axis=0) - finite.min(axis=0)
    x, y, z = (float(e) for e in extent)
    if min(x, y) > 0 and z <= FLAT_RATIO * min(x, y):
        return UpDecision("z", "flat", f"the mesh is flat and lies in the XY plane ({_size(extent)})")
    if min(x, y) >= GROUND_MIN_WIDTH_M and z <= GROUND_RATIO * min(x, y):
        return UpDecision("z", "ground", f"ground-like: wide in X and Y, thin in Z ({_size(extent)})")
    if min(x, z) >= GROUND_MIN_WIDTH_M and y <= GROUND_RATIO * min(x, z):
        return UpDecision("y", "ground", f"ground-like: wide in X and Z, thin in Y ({_size(extent)})")
    return None


def _size(extent: FloatArray) -> str:
    return "extent " + " x ".join(f"{float(e):.4g}" for e in extent)


def _quote(lines: Sequence[str], pattern: re.Pattern[str]) -> str:
    line = next((c for c in lines if pattern.search(c)), "")
    return repr(line.strip()[:60])
