"""The human report: assets with findings grouped, worst first, then a summary line."""

from __future__ import annotations

from meshtool.validate.reports.machine import format_label, status
from meshtool.validate.reports.names import printable_report
from meshtool.validate.rules import RULES
from meshtool.validate.runner import ValidationReport

_COLOUR = {"error": "\x1b[31m", "warning": "\x1b[33m", "info": "\x1b[36m", "clean": "\x1b[32m", "bold": "\x1b[1m"}
_RESET = "\x1b[0m"
_ORDER = {"error": 0, "warning": 1, "info": 2, "clean": 3}


def to_text(report: ValidationReport, strict: bool = False, colour: bool = False, verbose: bool = False) -> str:
    """The report as text lines.

    Args:
        report: The run's report.
        strict: Warnings fail the run (said in the summary).
        colour: ANSI colours (for a terminal).
        verbose: Also list clean assets and the notes of every asset.
    """
    report = printable_report(report)

    def paint(text: str, key: str) -> str:
        return f"{_COLOUR[key]}{text}{_RESET}" if colour else text

    lines: list[str] = []
    for a in sorted(report.assets, key=lambda a: (_ORDER[status(a)], a.path)):
        state = status(a)
        if state == "clean" and not verbose:
            continue
        count = {s: sum(f.severity.value == s for f in a.findings) for s in ("error", "warning", "info")}
        tally = ", ".join(f"{n} {s}{'s' if n != 1 else ''}" for s, n in count.items() if n)
        lines.append(f"{paint(a.path, 'bold')} ({format_label(a)})  {paint(tally or 'clean', state)}")
        for f in a.findings:
            rule = RULES[f.code]
            where = f"{f.path}:{f.line}" if f.line is not None else (f.path or a.path)
            lines.append(f"  {paint(f'{f.severity.value:7}', f.severity.value)} {f.code} {rule.name}: {where}")
            lines.append(f"          {f.message}")
            lines.append(f"          fix: {rule.hint}")
        if verbose:
            lines.extend(f"  note: {n}" for n in a.notes)
    if lines:
        lines.append("")
    lines.extend(summary_lines(report, strict, colour))
    return "\n".join(lines) + "\n"


def summary_lines(report: ValidationReport, strict: bool = False, colour: bool = False) -> list[str]:
    """The verdict with the counts, and how the run went (checked, from cache, executor, time)."""
    counts = report.counts()
    clean = sum(status(a) == "clean" for a in report.assets)
    verdict = "FAILED" if report.failed(strict) else "passed"
    if colour:
        verdict = f"{_COLOUR['error' if report.failed(strict) else 'clean']}{verdict}{_RESET}"
    summary = (
        f"{verdict}: {len(report.assets)} assets, {clean} clean; "
        f"{counts['error']} errors, {counts['warning']} warnings, {counts['info']} infos"
        f"{' (strict: warnings fail)' if strict else ''}"
    )
    places = ", ".join(f"{n} in {where}" if " " in where else f"{n} on {where}" for where, n in report.where.items())
    run = f"checked {report.checked}{f' ({places})' if places else ''}, {report.cache_hits} from cache"
    if report.thumbnails_drawn:
        run += f" ({report.thumbnails_drawn} thumbnail{'s' if report.thumbnails_drawn != 1 else ''} drawn for them)"
    if report.unchanged_skipped:
        run += f", {report.unchanged_skipped} unchanged not shown (--changed-only)"
    if report.checked == 0 and report.cache_hits and not report.thumbnails_drawn:  # no executor started nor contacted
        unused = "not contacted" if report.executor == "dask" else "not used"
        run += f"; {report.executor} executor {unused}: everything cached, {report.seconds:.2f} s"
    else:
        run += f"; {report.executor} executor, {report.seconds:.2f} s"
    return [summary, run]
