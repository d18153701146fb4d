"""One-line summaries shared by every ``simrun test`` report format (text, JUnit, GitHub, HTML).

A module of its own so that :mod:`.reports` (which renders HTML through :mod:`.report_html`) and
:mod:`.report_html` both import it, and neither imports the other back.
"""

from __future__ import annotations

from simrun.scenetest.expect import Outcome
from simrun.scenetest.runner import TestReport


def verdict_line(report: TestReport) -> str:
    """``passed: N runs ...`` or ``FAILED: ...`` with the counts."""
    counts = report.counts()
    scenes = len(report.cases)
    word = "FAILED" if report.failed() else "passed"
    return (
        f"{word}: {len(report.runs)} run(s) of {scenes} scene(s) x {len(report.seeds)} seed(s); "
        f"{counts['passed']} passed, {counts['failed']} failed, {counts['error']} error(s)"
    )


def failure_line(o: Outcome) -> str:
    """``FILE:LINE: expect 'ID' (kind): message: detail``."""
    where = f"{o.file}:{o.line}" if o.line else o.file
    return f"{where}: expect {o.id!r} ({o.kind}): {o.message}: {o.detail}"


__all__ = ["failure_line", "verdict_line"]
