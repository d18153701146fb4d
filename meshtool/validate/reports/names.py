r"""Printable names for reports: every report format writes valid UTF-8.

File names on disk need not be UTF-8; Python hands their stray bytes over as surrogate escapes, which no
UTF-8 file or terminal can hold. Reports show those bytes as ``\xNN`` (:func:`meshtool.files.safeopen.printable`),
the way every other meshtool message does.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from meshtool.files.safeopen import printable
from meshtool.findings import Finding
from meshtool.validate.runner import ValidationReport
from meshtool.validate.task import AssetResult


def printable_report(report: ValidationReport) -> ValidationReport:
    r"""A copy of ``report`` whose names, messages and notes hold no surrogate escapes (bytes as ``\xNN``)."""
    return replace(
        report,
        assets=[_asset(a) for a in report.assets],
        config_file=printable(report.config_file) if report.config_file is not None else None,
    )


def _asset(a: AssetResult) -> AssetResult:
    return replace(
        a,
        path=printable(a.path),
        findings=[_finding(f) for f in a.findings],
        notes=[printable(n) for n in a.notes],
        stats=_clean(a.stats),
    )


def _finding(f: Finding) -> Finding:
    return replace(f, message=printable(f.message), path=printable(f.path) if f.path is not None else None)


def _clean(value: Any) -> Any:
    if isinstance(value, str):
        return printable(value)
    if isinstance(value, dict):
        return {printable(k) if isinstance(k, str) else k: _clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    return value
