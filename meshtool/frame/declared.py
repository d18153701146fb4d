"""The frame stage's entry: the unit and up axis of a mesh, with what its format declares.

:func:`decide_asset_frame` takes the read stage's record (:class:`~meshtool.stages.SourceAsset`: the geometry
rules read the vertices the output keeps, ``triangles.kept``) and returns the
:class:`~meshtool.stages.FramedAsset`. An OBJ's frame is :func:`meshtool.frame.decide.decide_frame`'s alone;
other formats' declarations (COLLADA ``<unit>``/``<up_axis>``, glTF metres Y-up) are weighed first
(:func:`source_frame`); STL and PLY declare neither and are treated like OBJ (options, consumer files,
geometry), with a unit suggestion for STL.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from meshtool.findings import info
from meshtool.formats import MeshFormat, mesh_format, mesh_format_named
from meshtool.frame.decide import Frame, decide_frame
from meshtool.frame.modelroot import ModelRoot
from meshtool.frame.units import MAX_PLAUSIBLE_M, PLAUSIBLE_OBJECT_M, UNIT_FACTORS, UnitEvidence, unit_scale
from meshtool.frame.upaxis import FloatArray, UpDecision
from meshtool.stages import FramedAsset, SourceAsset, SourceMesh


def decide_asset_frame(source: SourceAsset, *, units: str | None, scale: float, up: str | None) -> FramedAsset:
    """Decide the source unit, extra scale and up axis of a read asset.

    Args:
        source: The read stage's record; the decision reads the (V, 3) positions of the vertices the output
            keeps (``source.triangles.kept``: :func:`meshtool.read.triangles.kept_vertices`), in source units
            and axes.
        units: ``--units`` (a unit, ``auto`` or ``None``).
        scale: ``--scale``.
        up: ``--up`` (``y``, ``z``, ``auto`` or ``None``).

    Returns:
        The record with the decision; its findings are the read asset's, then the decision's.
    """
    kept = source.triangles.kept
    positions = source.mesh.positions
    frame = source_frame(
        source.mesh,
        source.src,
        positions if kept.all() else positions[kept],
        units,
        scale,
        up,
        source.resolver.model_root,
        source.normalised_before,
    )
    return FramedAsset(source, frame, [*source.findings, *frame.findings])


def source_frame(
    obj: SourceMesh,
    src: Path,
    positions: FloatArray,
    units: str | None,
    scale: float,
    up: str | None,
    root: ModelRoot | None,
    normalised_before: bool = False,
) -> Frame:
    """:func:`meshtool.frame.decide.decide_frame` with what the format declares.

    A declared unit (COLLADA, glTF) is used unless ``--units`` names one (``auto`` keeps the declared one:
    consumers such as ROS apply a COLLADA unit before their own scale); a declared up axis is used unless
    ``--up`` is ``y`` or ``z``. Both are recorded (rule ``format``) for ``asset.json``.

    Args:
        obj: The mesh as read.
        src: The file.
        positions: (N, 3) positions in source units.
        units: ``--units``.
        scale: ``--scale``.
        up: ``--up``.
        root: The model root.
        normalised_before: The file was written by meshtool (OBJ only).

    Returns:
        The frame and its findings.
    """
    header = obj.header_comments
    if obj.format == "obj":
        return decide_frame(src, positions, header, units, scale, up, root, normalised_before)
    declared = obj.frame
    user_unit = units if units in UNIT_FACTORS else None
    unit, extra, factor = units, scale, 1.0
    if declared.unit_m is not None and user_unit is None:
        unit, factor = _unit_key(declared.unit_m)
        extra = scale * factor
    forced_up = up if up in ("y", "z") else None
    # glTF's Y-up is its specification's, whoever uses the file; another format's declaration (COLLADA
    # <up_axis>) gives way to a description file that uses the mesh as it is (placed_up: one rule for both)
    spec_up = declared.up if declared.up is not None and _placed_up(src) == declared.up else None
    declared_up = (
        UpDecision(declared.up, "format", declared.up_text) if declared.up is not None and spec_up is None else None
    )
    frame = decide_frame(src, positions, header, unit, extra, forced_up or spec_up or up, root, declared_up=declared_up)
    if declared.unit_m is not None:
        frame.findings = [f for f in frame.findings if f.code != "units-evidence"]
        if user_unit is None:
            frame.evidence = UnitEvidence(
                unit, None if factor == 1.0 else declared.unit_m, "format", declared.unit_text
            )
            frame.findings.append(info("units-format", f"unit from the file: {declared.unit_text}", obj.path))
    if spec_up is not None and forced_up is None:
        frame.up_decision = UpDecision(declared.up or spec_up, "format", declared.up_text)
        turned = "rotated +90 degrees about X to Z-up" if spec_up == "y" else "kept as it is"
        frame.findings.append(info("up-axis", f"up axis {spec_up} ({turned}): {declared.up_text}", obj.path))
    row = mesh_format_named(obj.format)
    if row.suggested_unit is not None:
        _cad_defaults(row, frame, positions, user_unit is None, obj.path)  # --units auto: the same suggestion
    return frame


def _placed_up(src: Path) -> str:
    """As :func:`meshtool.read.placed_up` (the format's rule, :meth:`meshtool.formats.MeshFormat.placed_up`)."""
    row = mesh_format(src)
    return row.placed_up() if row is not None else "z"


def _unit_key(metres: float) -> tuple[str, float]:
    """A unit name for ``metres`` per unit, and the remaining factor (1 when the unit is exact)."""
    for key in UNIT_FACTORS:
        if math.isclose(unit_scale(key), metres, rel_tol=1e-9):
            return key, 1.0
    return "m", metres


def _cad_defaults(row: MeshFormat, frame: Frame, positions: FloatArray, suggest_unit: bool, path: str) -> None:
    """A format from CAD (STL): its fallback up axis (Z) when nothing else tells, millimetres suggested.

    Millimetres are suggested when metres is implausible.
    The suggestion becomes the frame's unit evidence (source ``suggestion``) when no consumer file says
    anything: ``asset.json`` records it and the size warning names ``--units mm``.
    """
    if frame.up_decision.rule == "default":
        frame.up_decision = UpDecision(row.fallback_up, "format", row.fallback_reason)
        frame.up = row.fallback_up
        frame.findings = [f for f in frame.findings if f.code != "up-axis"]
        frame.findings.append(info("up-axis", f"up axis z (kept as it is): {frame.up_decision.evidence}", path))
    finite = positions[np.isfinite(positions).all(axis=1)] if positions.shape[0] else positions
    if not suggest_unit or frame.evidence is not None or finite.shape[0] == 0:
        return
    largest = float(np.max(finite.max(axis=0) - finite.min(axis=0))) * frame.scale
    in_mm = largest * unit_scale("mm")
    if largest > MAX_PLAUSIBLE_M and PLAUSIBLE_OBJECT_M[0] <= in_mm <= PLAUSIBLE_OBJECT_M[1]:
        frame.evidence = UnitEvidence("mm", None, "suggestion", "STL without unit, as CAD exports usually are")
        frame.findings.append(
            info(
                "stl-units",
                f"STL has no unit: read as metres ({largest:.3g} m across); CAD exports are usually millimetres: "
                f"pass --units mm ({in_mm:.3g} m)",
                path,
            )
        )
