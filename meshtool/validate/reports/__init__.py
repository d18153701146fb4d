"""Report formats of ``meshtool validate``: text, JSON, JUnit XML, GitHub annotations and HTML."""

from __future__ import annotations

import re

from meshtool.validate.reports.html import to_html
from meshtool.validate.reports.machine import to_github, to_json, to_junit
from meshtool.validate.reports.text import to_text
from meshtool.validate.runner import ValidationReport

FORMATS = ("text", "json", "junit", "github", "html")


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


__all__ = ["FORMATS", "is_report", "render", "to_github", "to_html", "to_json", "to_junit", "to_text"]
