"""Report formats of ``meshtool validate``: text, JSON, JUnit XML, GitHub annotations and HTML."""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from meshtool.files.outdir import check_output, is_within
from meshtool.formats import COMPANION_SUFFIXES, REPORT_FORMATS, mesh_suffixes, output_named
from meshtool.validate.reports.html import to_html
from meshtool.validate.reports.machine import to_github, to_json, to_junit
from meshtool.validate.reports.text import to_text
from meshtool.validate.runner import ValidationReport

#: The report formats, in the formats registry's order (:data:`meshtool.formats.REPORT_FORMATS`).
FORMATS = tuple(row.name for row in REPORT_FORMATS)


def render(report: ValidationReport, fmt: str, strict: bool = False, colour: bool = False) -> str:
    """The report in format ``fmt`` (one of :data:`FORMATS`)."""
    if fmt == "text":
        return to_text(report, strict, colour)
    if fmt == "json":
        return to_json(report, strict)
    if fmt == "junit":
        return to_junit(report, strict)
    if fmt == "github":
        return to_github(report, strict)
    if fmt == "html":
        return to_html(report, strict)
    raise ValueError(f"unknown report format {fmt!r}")


#: What each format's report starts with or holds, to recognise an earlier report that ``-o`` may replace.
_MARKERS = (b'"meshtool-validate-report"', b'name="meshtool validate"', b"<title>meshtool validate")
_TEXT_RUN_LINE = re.compile(rb"^checked \d+.*, \d+ from cache", re.MULTILINE)
_VERDICT = re.compile(rb"^(PASSED|FAILED)\b", re.MULTILINE | re.IGNORECASE)


def is_report(head: bytes) -> bool:
    """Whether ``head`` (the first bytes of a file) is a report ``meshtool validate`` wrote, in any format.

    JSON, JUnit and HTML carry meshtool's name; a text report has its verdict line and its ``checked N ...,
    M from cache`` line; a GitHub report is nothing but workflow commands (every line starts with ``::``).
    """
    if any(marker in head for marker in _MARKERS):
        return True
    if _VERDICT.search(head) and _TEXT_RUN_LINE.search(head):
        return True
    lines = [line for line in head.splitlines() if line.strip()]
    return bool(lines) and all(line.startswith(b"::") for line in lines)


#: Suffixes of what validate reads under its PATHS (meshes, packs, materials, textures, robot descriptions).
INPUT_SUFFIXES = (
    *mesh_suffixes(),
    *output_named("mbin").suffixes,
    *COMPANION_SUFFIXES,  # companions of meshes
)


def check_report_output(output: Path, paths: list[Path], force: bool) -> None:
    """Refuse a report path that would destroy something (:func:`meshtool.files.outdir.check_output`).

    A file the run reads (one of ``paths``, or a file with an input suffix inside one of them) is refused
    always; another existing file that is not an earlier report (:func:`is_report`, or empty) unless ``force``.

    Raises:
        OutputError: With the reason and how to fix it.
    """
    inside = any(stat.S_ISDIR(_mode(p) or 0) and is_within(output, p) for p in paths)
    reads = inside and output.suffix.lower() in INPUT_SUFFIXES and _mode(output) is not None
    inputs = [output] if reads else paths
    check_output(
        output, force=force, inputs=inputs, recognise=("an earlier meshtool validate report", _report_or_empty)
    )


def _report_or_empty(head: bytes) -> bool:
    return not head or is_report(head)  # an empty file holds nothing (a clean GitHub report is empty)


def _mode(path: Path) -> int | None:
    """``st_mode`` of ``path`` (links followed), ``None`` for a missing path or a name the system refuses."""
    try:
        return os.stat(path).st_mode
    except OSError:
        return None


__all__ = [
    "FORMATS",
    "INPUT_SUFFIXES",
    "check_report_output",
    "is_report",
    "render",
    "to_github",
    "to_html",
    "to_json",
    "to_junit",
    "to_text",
]
