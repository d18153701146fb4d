"""Reports of ``simrun test``: text, JSON, JUnit XML and GitHub annotations (HTML: :mod:`.report_html`).

Every format is deterministic: the runs are in plan order (scene, variation, seed) and nothing that
depends on the machine or the executor is written (no timings, no worker names; the one exception is a
failed ``realtime`` expectation, which states the factor it measured). The session's timing goes to the
summary line on stderr (:func:`session_line`).
"""

from __future__ import annotations

import json
import math
from typing import Any
from xml.etree import ElementTree as ET

from meshtool.work.reportkit import annotation_data, annotation_property
from simrun import __version__
from simrun.errors import UsageError
from simrun.scenetest.expect import Outcome
from simrun.scenetest.report_html import to_html
from simrun.scenetest.report_lines import failure_line, verdict_line
from simrun.scenetest.runner import Run, TestReport

FORMATS = ("text", "json", "junit", "github", "html")
FORMAT = "simrun-test-report"
FORMAT_VERSION = 1
#: Runs listed by name in one GitHub annotation (the rest are counted).
ANNOTATION_RUNS = 5


def render(report: TestReport, fmt: str) -> str:
    """The report in format ``fmt`` (one of :data:`FORMATS`)."""
    renderers = {"text": to_text, "json": to_json, "junit": to_junit, "github": to_github, "html": to_html}
    if fmt not in renderers:
        raise UsageError(f"unknown report format {fmt!r}", hint=f"choose one of {', '.join(renderers)}")
    return renderers[fmt](report)


def session_line(report: TestReport) -> str:
    """How the session went: executor, where runs ran, wall-clock time and runs per second (varies)."""
    places = ", ".join(f"{n} in {w}" if " " in w else f"{n} on {w}" for w, n in sorted(report.where.items()))
    rate = len(report.runs) / report.seconds if report.seconds > 0 else math.inf
    return f"{report.executor} executor ({places or 'nothing run'}), {report.seconds:.2f} s, {rate:.2f} runs/s"


def to_text(report: TestReport, verbose: bool = False) -> str:
    """Failed and errored runs with what missed, then the verdict (``verbose``: every run)."""
    lines: list[str] = []
    for case in report.cases:
        if case.implicit:
            lines.append(f"{case.display}: no [[expect]]: smoke test (passes while the simulation stays finite)")
    for run in report.runs:
        result = run.result
        if result.status == "passed" and not verbose:
            continue
        lines.append(f"{result.status.upper():7} {run.label}")
        if result.error:
            lines.append(f"        {result.error}")
        for o in result.outcomes:
            if not o.passed or verbose:
                lines.append(f"        {'ok  ' if o.passed else 'FAIL'} {failure_line(o)}")
        lines.extend(f"        note: {n}" for n in result.notes)
        if run.resim:
            lines.append(f"        reproduce: {run.resim}")
    if lines:
        lines.append("")
    lines.append(verdict_line(report))
    return "\n".join(lines) + "\n"


def run_dict(run: Run) -> dict[str, Any]:
    """One run as JSON-ready data."""
    r = run.result
    return {
        "scene": run.case.display,
        "seed": run.seed,
        "variation": run.variation,
        "values": run.values,
        "status": r.status,
        "error": r.error,
        "expectations": [
            {
                "id": o.id,
                "kind": o.kind,
                "message": o.message,
                "file": o.file,
                "line": o.line,
                "passed": o.passed,
                "detail": o.detail,
                "time": o.time,
                "miss": o.miss if o.miss is None or math.isfinite(o.miss) else None,
            }
            for o in r.outcomes
        ],
        "notes": r.notes,
        "recording": run.recording,
        "reproduce": run.resim,
    }


def to_json(report: TestReport) -> str:
    """One object: ``summary``, ``scenes`` and ``runs`` (one object per run)."""
    counts = report.counts()
    document = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "tool": {"name": "simrun", "version": __version__},
        "summary": {
            "scenes": len(report.cases),
            "runs": len(report.runs),
            **counts,
            "passed_all": not report.failed(),
            "seeds": report.seeds,
            "vary": [{"key": a.key, "kind": a.kind, "values": list(a.values)} for a in report.axes],
        },
        "scenes": [
            {
                "scene": c.display,
                "duration_s": c.duration,
                "smoke_test": c.implicit,
                "expectations": [e.id for e in c.expectations],
            }
            for c in report.cases
        ],
        "runs": [run_dict(r) for r in report.runs],
    }
    return json.dumps(document, indent=1, ensure_ascii=False, allow_nan=False) + "\n"


def to_junit(report: TestReport) -> str:
    """JUnit XML: a ``testsuite`` per scene, a ``testcase`` per run with its seed and values as properties."""
    root = ET.Element("testsuites", name="simrun test")
    totals = {"tests": 0, "failures": 0, "errors": 0}
    for case in report.cases:
        runs = [r for r in report.runs if r.case is case]
        suite = ET.SubElement(root, "testsuite", name=case.display)
        failures = errors = 0
        stem = case.display.rsplit(".", 1)[0].lstrip("./").replace("/", ".")
        classname = f"simrun.test.{stem}"
        for run in runs:
            r = run.result
            element = ET.SubElement(suite, "testcase", classname=classname, name=run.label, file=case.display)
            line = _first_line(run) or case.line_of("test")
            if line is not None:
                element.set("line", str(line))
            props = ET.SubElement(element, "properties")
            ET.SubElement(props, "property", name="seed", value=str(run.seed))
            for key, value in run.values.items():
                ET.SubElement(props, "property", name=key, value=repr(float(value)))
            if r.status == "error":
                errors += 1
                err = ET.SubElement(element, "error", message=r.error or "", type="internal" if r.internal else "run")
                err.text = r.error or ""
            elif r.status == "failed":
                failures += 1
                failing = [o for o in r.outcomes if not o.passed]
                first = failing[0]
                fail = ET.SubElement(
                    element,
                    "failure",
                    message=f"{len(failing)} of {len(r.outcomes)} expectation(s) failed, "
                    f"first: {first.id}: {first.detail}",
                    type=first.id,
                )
                fail.text = "\n".join(failure_line(o) for o in failing)
            out = [f"{'ok' if o.passed else 'FAIL'} {failure_line(o)}" for o in r.outcomes if o.passed]
            out += [f"note: {n}" for n in r.notes]
            if run.resim:
                out.append(f"reproduce: {run.resim}")
            if out:
                ET.SubElement(element, "system-out").text = "\n".join(out)
        suite.set("tests", str(len(runs)))
        suite.set("failures", str(failures))
        suite.set("errors", str(errors))
        suite.set("skipped", "0")
        totals["tests"] += len(runs)
        totals["failures"] += failures
        totals["errors"] += errors
    for key, value in totals.items():
        root.set(key, str(value))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _first_line(run: Run) -> int | None:
    """The line of the run's first failing expectation in the scene file (for JUnit's ``line``)."""
    for o in run.result.outcomes:
        if not o.passed and o.file == run.case.display:
            return o.line
    return None


def to_github(report: TestReport) -> str:
    """GitHub Actions ``::error`` lines: one per failing expectation (on its file and line) and per run error.

    An expectation that failed in many runs is one annotation naming the first :data:`ANNOTATION_RUNS` runs.
    """
    groups: dict[tuple[str, int | None, str], list[tuple[Run, Outcome]]] = {}
    errors: dict[tuple[str, str], list[Run]] = {}
    for run in report.runs:
        if run.result.status == "error":
            errors.setdefault((run.case.display, run.result.error or ""), []).append(run)
        for o in run.result.outcomes:
            if not o.passed:
                groups.setdefault((o.file, o.line, o.id), []).append((run, o))
    lines = []
    for (file, line, ident), hits in groups.items():
        total = sum(1 for r in report.runs if r.case is hits[0][0].case)
        shown = "; ".join(f"{run.label}: {o.detail}" for run, o in hits[:ANNOTATION_RUNS])
        more = f"; and {len(hits) - ANNOTATION_RUNS} more" if len(hits) > ANNOTATION_RUNS else ""
        message = f"{hits[0][1].message}: failed in {len(hits)} of {total} run(s): {shown}{more}"
        props = [f"file={annotation_property(file)}"] + ([f"line={line}"] if line else [])
        props.append(f"title={annotation_property(f'simrun test: expect {ident}')}")
        lines.append(f"::error {','.join(props)}::{annotation_data(message)}")
    for (file, error), runs in errors.items():
        shown = ", ".join(r.label for r in runs[:ANNOTATION_RUNS])
        more = f" and {len(runs) - ANNOTATION_RUNS} more" if len(runs) > ANNOTATION_RUNS else ""
        message = f"{error} (in {len(runs)} run(s): {shown}{more})"
        props = [f"file={annotation_property(file)}", f"title={annotation_property('simrun test: run error')}"]
        lines.append(f"::error {','.join(props)}::{annotation_data(message)}")
    lines.append(f"::notice title={annotation_property('simrun test')}::{annotation_data(verdict_line(report))}")
    return "".join(line + "\n" for line in lines)


__all__ = [
    "ANNOTATION_RUNS",
    "FORMAT",
    "FORMATS",
    "FORMAT_VERSION",
    "failure_line",
    "render",
    "run_dict",
    "session_line",
    "to_github",
    "to_html",
    "to_json",
    "to_junit",
    "to_text",
    "verdict_line",
]
