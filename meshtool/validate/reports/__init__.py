"""Report formats of ``meshtool validate``: text, JSON, JUnit XML, GitHub annotations and HTML."""

from __future__ import annotations

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


__all__ = ["FORMATS", "render", "to_github", "to_html", "to_json", "to_junit", "to_text"]
