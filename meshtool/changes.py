"""Which findings changed or dropped data: what the CLI shows by default and what ``--strict`` refuses.

Every warning counts, and a change to the geometry that meshtool decided on is one: an up-axis rotation
(``up-axis`` when ``--up auto`` turned the mesh), a unit scale ``--units auto`` applied (``units-evidence``),
a padded part (``part-padded``). Of the info findings, those that record a change to the data count too
(triangles, statements, materials or attributes dropped; values reinterpreted or filled in); notes that only
explain how something was found or read (a repaired reference, the model root, an up axis kept, the
encoding) do not, and neither do the collision-hull notes (``hull-thickened``, ``hull-reduced``:
the hulls are made within the budgets asked for, the asset's data is untouched). ``docs/findings.md``
marks each code.
"""

from __future__ import annotations

from collections.abc import Iterable

from meshtool.findings import Finding, Severity

#: Info codes that record changed or dropped data.
DATA_CHANGING_INFO = frozenset(
    {
        "degenerate-faces",
        "lines-skipped",
        "points-skipped",
        "freeform-skipped",
        "vertex-w-ignored",
        "texcoords-filled",
        "normals-partial",
        "mtl-tr-converted",
        "mtl-statement-unsupported",
        "materials-unused",
        "export-map-dropped",
    }
)


#: Info codes that change nothing but are told by default, once per command, as a ``note:`` line: what a
#: consumer of the output silently ignores (MuJoCo's renderer and normal maps).
TOLD_NOTES = frozenset({"mujoco-ignores-map"})


def changes_data(finding: Finding) -> bool:
    """Whether ``finding`` changed or dropped data (every warning and error does)."""
    return finding.severity is not Severity.INFO or finding.code in DATA_CHANGING_INFO


def split_findings(findings: Iterable[Finding]) -> tuple[list[Finding], list[Finding]]:
    """(findings that changed or dropped data, the other notes), each in input order."""
    shown: list[Finding] = []
    notes: list[Finding] = []
    for f in findings:
        (shown if changes_data(f) else notes).append(f)
    return shown, notes
