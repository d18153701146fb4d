"""Machine-readable reports: JSON, JUnit XML and GitHub Actions annotation lines.

All three are deterministic: the same findings give the same bytes (no timings, no cache state).
"""

from __future__ import annotations

import json
import math
from typing import Any
from xml.etree import ElementTree as ET

from meshtool import __version__
from meshtool.findings import Finding, Severity
from meshtool.formats import MESH_FORMATS, OUTPUTS
from meshtool.validate.reports.names import printable_report
from meshtool.validate.rules import RULES
from meshtool.validate.runner import ValidationReport
from meshtool.validate.task import AssetResult
from meshtool.work.reportkit import annotation_data, annotation_property

FORMAT = "meshtool-validate-report"
FORMAT_VERSION = 1


def status(asset: AssetResult) -> str:
    """``error``, ``warning``, ``info`` or ``clean``: the worst severity among the asset's findings."""
    levels = {f.severity for f in asset.findings}
    for level in (Severity.ERROR, Severity.WARNING, Severity.INFO):
        if level in levels:
            return level.value
    return "clean"


def format_label(asset: AssetResult) -> str:
    """How reports name the asset's format, from the formats registry.

    A mesh format's label (``OBJ``, ``STL``, ``PLY``, ``glTF``, ``GLB``, ``COLLADA``); ``MBIN`` for a pack (its
    output row's name, as :func:`meshtool.formats.check_suffix` writes it).
    """
    name = asset.format or asset.kind
    mesh = next((row for row in MESH_FORMATS if row.name == name), None)
    if mesh is not None:
        return mesh.label
    output = next((row for row in OUTPUTS if row.name == name), None)
    return output.name.upper() if output is not None else name


def finding_dict(f: Finding) -> dict[str, Any]:
    """A finding with its rule's name, category and hint."""
    rule = RULES[f.code]
    return {
        "rule": f.code,
        "name": rule.name,
        "category": rule.category,
        "severity": f.severity.value,
        "message": f.message,
        "file": f.path,
        "line": f.line,
        "hint": rule.hint,
    }


def to_json(report: ValidationReport, strict: bool = False) -> str:
    """One object: ``summary`` and ``assets`` (one object per asset); see ``docs/validate-report.schema.json``."""
    report = printable_report(report)
    counts = report.counts()
    document = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "tool": {"name": "meshtool", "version": __version__},
        "summary": {
            "assets": len(report.assets),
            "unchanged_skipped": report.unchanged_skipped,
            "errors": counts["error"],
            "warnings": counts["warning"],
            "infos": counts["info"],
            "by_status": {s: sum(status(a) == s for a in report.assets) for s in ("error", "warning", "info", "clean")},
            "strict": strict,
            "passed": not report.failed(strict),
            "config": report.config_file,
        },
        "assets": [
            {
                "path": a.path,
                "kind": a.kind,
                "format": a.format or a.kind,
                "status": status(a),
                "findings": [finding_dict(f) for f in a.findings],
                "notes": a.notes,
                "stats": _finite(a.stats),
            }
            for a in report.assets
        ],
    }
    return json.dumps(document, indent=1, sort_keys=False, ensure_ascii=False, allow_nan=False) + "\n"


def to_junit(report: ValidationReport, strict: bool = False) -> str:
    """JUnit XML: one ``testcase`` per asset; errors (and warnings with ``strict``) are failures, X001 an error."""
    report = printable_report(report)
    fails = {Severity.ERROR, Severity.WARNING} if strict else {Severity.ERROR}
    suite = ET.Element("testsuite", name="meshtool validate")
    failures = errors = 0
    for a in report.assets:
        folder = a.path.rpartition("/")[0].replace("/", ".") or "."
        case = ET.SubElement(suite, "testcase", classname=f"meshtool.validate.{folder}", name=a.path, file=a.path)
        properties = ET.SubElement(case, "properties")  # first in a testcase, as JUnit readers expect it
        ET.SubElement(properties, "property", name="format", value=format_label(a))
        internal = [f for f in a.findings if f.code == "X001"]
        failing = [f for f in a.findings if f.severity in fails and f.code != "X001"]
        rest = [f for f in a.findings if f not in failing and f not in internal]
        if internal:
            errors += 1
            element = ET.SubElement(case, "error", message=internal[0].message, type="X001")
            element.text = "\n".join(_line(f) for f in internal)
        elif failing:
            failures += 1
            first = failing[0]
            element = ET.SubElement(
                case, "failure", message=f"{len(failing)} problem(s), first: {first.message}", type=first.code
            )
            element.text = "\n".join(_line(f) for f in failing)
        if rest or a.notes:
            out = ET.SubElement(case, "system-out")
            out.text = "\n".join([*(_line(f) for f in rest), *a.notes])
    suite.set("tests", str(len(report.assets)))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))
    suite.set("skipped", "0")
    root = ET.Element(
        "testsuites",
        name="meshtool validate",
        tests=suite.get("tests", "0"),
        failures=str(failures),
        errors=str(errors),
    )
    root.append(suite)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def to_github(report: ValidationReport, strict: bool = False) -> str:
    """GitHub Actions workflow commands: ``::error``/``::warning``/``::notice`` per finding, file and line."""
    report = printable_report(report)
    command = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.INFO: "notice"}
    lines = []
    for a in report.assets:
        for f in a.findings:
            kind = "error" if strict and f.severity is Severity.WARNING else command[f.severity]
            props = [f"file={annotation_property(f.path or a.path)}"]
            if f.line is not None:
                props.append(f"line={f.line}")
            props.append(f"title={annotation_property(f'{f.code} {RULES[f.code].name}')}")
            lines.append(f"::{kind} {','.join(props)}::{annotation_data(f'{f.message} (fix: {RULES[f.code].hint})')}")
    return "".join(line + "\n" for line in lines)


def _finite(value: Any) -> Any:
    """``value`` with NaN and infinities replaced by ``None`` (JSON has neither)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in sorted(value.items())}  # sorted: cached and fresh agree
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def _line(f: Finding) -> str:
    where = f"{f.path}:{f.line}" if f.line is not None else (f.path or "")
    return f"{f.severity.value} {f.code} {RULES[f.code].name}: {where}: {f.message} (fix: {RULES[f.code].hint})"
