"""Findings: what meshtool noticed, repaired or refused, returned to the caller instead of printed.

A finding is ``(code, severity, message, path, line)``. Codes are stable identifiers documented in
``docs/findings.md``; severities are ``info`` (a repair or a note), ``warning`` (something was dropped or
guessed, the output is still usable; ``--strict`` turns these into failure) and ``error`` (only used in
reports; fatal problems raise :class:`meshtool.errors.MeshtoolError` instead).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Severity(StrEnum):
    """How serious a finding is."""

    INFO = "info"
    WARNING = "warning"
    ERROR = "error"


@dataclass(frozen=True, slots=True)
class Finding:
    """One observation about an input.

    Attributes:
        code: Stable kebab-case identifier, e.g. ``texture-missing``.
        severity: See :class:`Severity`.
        message: One sentence saying what was found and what was done about it.
        path: File the finding is about (relative to the asset folder), or ``None``.
        line: 1-based line in ``path``, or ``None``.
    """

    code: str
    severity: Severity
    message: str
    path: str | None = None
    line: int | None = None

    def __post_init__(self) -> None:
        if self.line is not None and self.line < 1:  # formats without lines (COLLADA, glTF) say 0: no line
            object.__setattr__(self, "line", None)

    @property
    def where(self) -> str:
        """``path:line``, ``path`` or an empty string."""
        if self.path is None:
            return ""
        return f"{self.path}:{self.line}" if self.line is not None else self.path

    def one_line(self) -> str:
        """``severity: where: message [code]`` on one line."""
        where = f"{self.where}: " if self.where else ""
        return f"{self.severity.value}: {where}{self.message} [{self.code}]"

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dict with the five fields."""
        return {
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "path": self.path,
            "line": self.line,
        }


def info(code: str, message: str, path: str | None = None, line: int | None = None) -> Finding:
    """Build an ``info`` finding."""
    return Finding(code, Severity.INFO, message, path, line)


def warning(code: str, message: str, path: str | None = None, line: int | None = None) -> Finding:
    """Build a ``warning`` finding."""
    return Finding(code, Severity.WARNING, message, path, line)


def count_of(findings: list[Finding], severity: Severity) -> int:
    """Number of findings of exactly ``severity``."""
    return sum(1 for f in findings if f.severity is severity)
