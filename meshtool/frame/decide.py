"""The source frame of an OBJ: its unit, extra scale and up axis, from the options and from evidence.

``--units`` and ``--up`` given as a unit / ``y`` / ``z`` are obeyed. ``--up auto`` (the default) decides
with :func:`meshtool.frame.upaxis.decide_up`; ``--units auto`` applies what a consumer file (URDF, SDF, MJCF
that uses the mesh) says, and otherwise reads metres. Whatever was decided, and on what evidence, becomes
findings (``up-axis``, ``units-evidence``) that ``asset.json`` records. The consumers are looked up in the
run's index of the mesh's index root (:func:`meshtool.frame.consumers.find_index_root`); consumers using the mesh
in different frames are a ``consumer-frames-differ`` warning (the nearest one's frame is applied), an index
stopped by a limit a ``consumer-index-limit`` warning.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.files.resolve import file_sha256
from meshtool.files.safeopen import printable
from meshtool.findings import Finding, Severity, info, warning
from meshtool.frame.consumers import ConsumerRef, consumers_and_limit, frame_conflict
from meshtool.frame.modelroot import ModelRoot
from meshtool.frame.units import UnitEvidence, apply_scale, evidence_findings, unit_evidence
from meshtool.frame.upaxis import FloatArray, UpDecision, decide_up


@dataclass(slots=True)
class Frame:
    """The decided source frame.

    Attributes:
        units: Unit of the source coordinates.
        scale: Extra uniform scale after the unit.
        up: ``y`` or ``z``.
        up_decision: Why that axis.
        evidence: What files say about the unit, or ``None``.
        consumers: The description files that use the mesh.
        findings: ``up-axis`` and ``units-evidence`` findings.
    """

    units: str
    scale: float
    up: str
    up_decision: UpDecision
    evidence: UnitEvidence | None
    consumers: list[ConsumerRef] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)

    def sources(self, obj_dir: Path) -> list[dict[str, str]]:
        """The consumer files read, as ``asset.json`` source entries (role ``consumer``, path, SHA-256).

        Args:
            obj_dir: The OBJ's folder (consumer paths are relative to it).
        """
        out: list[dict[str, str]] = []
        for file in dict.fromkeys(c.file for c in self.consumers):
            digest = file_sha256(obj_dir / file)
            if digest is not None:
                out.append({"role": "consumer", "path": file, "sha256": digest})
        return out

    def record(self) -> dict[str, Any]:
        """The decision for ``asset.json``'s ``transform``: rules, evidence and consumer files."""
        return {
            "up_rule": self.up_decision.rule,
            "up_evidence": self.up_decision.evidence,
            "units_evidence": self.evidence.describe() if self.evidence else None,
            "consumers": [c.describe() for c in self.consumers],
        }


def decide_frame(
    src: Path,
    positions: FloatArray,
    header_comments: list[str],
    units: str | None,
    scale: float,
    up: str | None,
    root: ModelRoot | None,
    normalised_before: bool = False,
    declared_up: UpDecision | None = None,
) -> Frame:
    """Decide unit, scale and up axis of ``src``.

    Args:
        src: The OBJ file.
        positions: (N, 3) positions in source units and axes.
        header_comments: The OBJ's header comment lines.
        units: ``--units``: a unit, ``auto`` or ``None`` (metres, or what meshtool's header says).
        scale: ``--scale``.
        up: ``--up``: ``y``, ``z``, ``auto`` or ``None`` (auto).
        root: The OBJ's model root (an ``explicit`` one from ``--model-root`` also sets the index root).
        normalised_before: The file was written by meshtool.
        declared_up: The up axis the file declares (COLLADA ``<up_axis>``), used unless ``up`` forces one or
            a description file (URDF, SDFormat) uses the mesh as it is: a robot places its meshes in the
            link's Z-up frame whatever the exporter declared (Assimp and MeshLab write ``Y_UP`` whatever
            they hold), as ``meshtool urdf`` places them (:func:`meshtool.read.placed_up`).

    Returns:
        The frame and its findings.
    """
    name = printable(src.name)  # non-UTF-8 file names print as \xNN
    consumers, limit = ([], None) if normalised_before else consumers_and_limit(src, root)
    evidence = None if normalised_before else unit_evidence(consumers, header_comments)
    findings: list[Finding] = []
    if limit is not None:  # consumers beyond the limit are not seen: the frame may be the wrong one
        findings.append(warning("consumer-index-limit", f"consumer files not all read: {limit}", name))
    conflict = frame_conflict(consumers, name)
    if conflict is not None:
        findings.append(conflict)
    chosen_unit, chosen_scale = units or "m", scale
    if units == "auto":
        chosen_unit = "m"
        if evidence is not None and evidence.source == "consumer":
            if evidence.unit is not None:
                chosen_unit = evidence.unit
            elif evidence.scale is not None:
                chosen_scale = scale * evidence.scale
            else:
                findings.append(
                    warning(
                        "units-evidence",
                        f"--units auto: {evidence.text} scales the axes differently; read as metres",
                        name,
                    )
                )
    applied = evidence_findings(evidence, chosen_unit, chosen_scale, name)
    if evidence is not None and units == "auto" and (chosen_unit != "m" or chosen_scale != scale):
        # --units auto scaled every vertex: a warning (shown; --strict refuses it; --units UNIT accepts it)
        said = f"--units auto: every vertex scaled as {evidence.describe()}"
        applied = [
            warning(f.code, said, f.path, f.line) if f.code == "units-evidence" and f.severity is Severity.INFO else f
            for f in applied
        ]
    findings.extend(applied)
    if up in ("y", "z"):
        decision = UpDecision(up, "forced", f"--up {up}")
    elif declared_up is not None and not consumers:
        decision = declared_up
    else:
        metres = apply_scale(np.asarray(positions, dtype=np.float64), chosen_unit, chosen_scale)
        decision = decide_up(src, metres, header_comments, consumers, root, normalised_before)
    if decision.rule not in ("forced", "meshtool"):
        turned = "rotated +90 degrees about X to Z-up" if decision.up == "y" else "kept as it is"
        # a rotation moves every vertex: a warning (shown, --strict refuses it; --up y accepts it silently)
        told = warning if decision.up == "y" else info
        findings.append(told("up-axis", f"up axis {decision.up} ({turned}): {decision.evidence}", name))
    return Frame(chosen_unit, chosen_scale, decision.up, decision, evidence, consumers, findings)
