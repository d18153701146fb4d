"""The HTML report of ``simrun test``: one self-contained page, a card per failed run with its last frame.

Styled like ``meshtool validate``'s page (:data:`meshtool.work.reportkit.REPORT_CSS`). Each failed or errored run
has a card with a thumbnail of its final state (rendered headless by the worker that ran it; a note says why
when there is none), the expectations that missed, the values it ran with and the command that reproduces
it; passed runs are one table.
"""

from __future__ import annotations

from html import escape

from meshtool.work.reportkit import REPORT_CSS, no_preview_image, png_data_uri
from simrun import __version__
from simrun.scenetest.report_lines import failure_line, verdict_line
from simrun.scenetest.runner import Run, TestReport

_EXTRA_CSS = """
.card.failed{border-left-color:#c62828}.card.error{border-left-color:#6a1b9a}
.card img{width:320px;height:240px}
.fail{color:#c62828;font-weight:700;white-space:nowrap}.ok{color:#2e9d57;white-space:nowrap}
code{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12px}
table.runs td{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12px}
"""


def to_html(report: TestReport) -> str:
    """The report as one HTML document."""
    counts = report.counts()
    verdict = "FAILED" if report.failed() else "passed"
    bad = [r for r in report.runs if r.result.status != "passed"]
    good = [r for r in report.runs if r.result.status == "passed"]
    pills = (
        f'<span class="pill-clean">{counts["passed"]} passed</span>'
        + (f'<span class="pill-error">{counts["failed"]} failed</span>' if counts["failed"] else "")
        + (f'<span class="pill-warning">{counts["error"]} errors</span>' if counts["error"] else "")
    )
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width,initial-scale=1">',
        f"<title>simrun test: {verdict}</title><style>{REPORT_CSS}{_EXTRA_CSS}</style></head><body>",
        f"<header><h1>simrun test: {verdict}</h1>",
        f"<div>{escape(verdict_line(report))}; simrun {escape(__version__)}</div>",
        f'<div class="pills" style="margin-top:8px">{pills}</div></header><main>',
    ]
    if bad:
        parts.append(f'<h2 id="failed">Failed runs ({len(bad)})</h2>')
        parts.extend(_card(r) for r in bad)
    if good:
        parts.append(f'<h2 id="passed">Passed runs ({len(good)})</h2><table class="runs">')
        parts.extend(f'<tr><td class="ok">passed</td><td>{escape(r.label)}</td></tr>' for r in good)
        parts.append("</table>")
    parts.append("</main></body></html>")
    return "\n".join(parts) + "\n"


def _card(run: Run) -> str:
    r = run.result
    if r.thumbnail:
        src = png_data_uri(r.thumbnail)
        alt = f"{run.label}: the last frame"
    else:
        reason = next((n for n in r.notes if "thumbnail" in n), r.error or "no picture was asked for")
        src, alt = no_preview_image(reason, width=320, height=240), f"{run.label}: {reason}"
    rows = []
    if r.error:
        rows.append(f'<tr><td class="fail">error</td><td>{escape(r.error)}</td></tr>')
    for o in r.outcomes:
        css, word = ("ok", "ok") if o.passed else ("fail", "FAIL")
        rows.append(f'<tr><td class="{css}">{word}</td><td>{escape(failure_line(o))}</td></tr>')
    notes = "".join(f'<div class="notes">{escape(n)}</div>' for n in r.notes)
    values = ", ".join(f"{k} = {v!r}" for k, v in run.values.items()) or "no varied values"
    reproduce = f'<div class="notes">reproduce: <code>{escape(run.resim)}</code></div>' if run.resim else ""
    return (
        f'<section class="card {r.status}"><img src="{src}" alt="{escape(alt)}" width="320" height="240">'
        f'<div class="body"><div class="path">{escape(run.label)}</div>'
        f'<div class="stats">seed {run.seed}; {escape(values)}</div><table>{"".join(rows)}</table>'
        f"{notes}{reproduce}</div></section>"
    )
