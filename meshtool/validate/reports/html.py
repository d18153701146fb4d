"""The HTML report: one self-contained page (inline CSS, images as data URIs), one card per asset.

Each card has exactly one ``<img>``: the thumbnail (visual and collision views side by side) or, when
there is none, an inline SVG saying why. Cards are grouped by status, worst first.
"""

from __future__ import annotations

import base64
from html import escape

from meshtool import __version__
from meshtool.validate.reports.machine import status
from meshtool.validate.reports.names import printable_report
from meshtool.validate.rules import RULES
from meshtool.validate.runner import ValidationReport
from meshtool.validate.task import AssetResult

_CSS = """
body{font:14px/1.4 system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;background:#f4f5f7;color:#1d2330}
header{background:#1d2330;color:#fff;padding:16px 24px}
header h1{margin:0 0 6px;font-size:20px}
.pills span{display:inline-block;margin-right:8px;padding:2px 10px;border-radius:10px;font-weight:600}
main{padding:12px 24px}
h2{font-size:16px;margin:20px 0 8px}
.card{display:flex;gap:16px;background:#fff;border-radius:8px;padding:12px;margin:0 0 10px;
 box-shadow:0 1px 2px rgba(0,0,0,.08);border-left:6px solid #2e9d57}
.card.error{border-left-color:#c62828}.card.warning{border-left-color:#e0a100}.card.info{border-left-color:#1f78b4}
.card img{width:404px;height:150px;flex:none;border-radius:4px;background:#e8eaee}
.body{min-width:0;flex:1}
.path{font-weight:600;font-family:ui-monospace,Menlo,Consolas,monospace;word-break:break-all}
.stats{color:#5a6275;font-size:12px;margin:2px 0 6px}
table{border-collapse:collapse;width:100%}
td{padding:3px 6px;vertical-align:top;border-top:1px solid #eef0f3}
td.sev{font-weight:700;white-space:nowrap}
.sev.error,.pill-error{color:#c62828}.sev.warning,.pill-warning{color:#9a6c00}.sev.info,.pill-info{color:#1f78b4}
.pill-clean{color:#2e9d57}
.pills .pill-error{background:#fde8e8}.pills .pill-warning{background:#fff4d6}
.pills .pill-info{background:#e3f0fa}.pills .pill-clean{background:#e3f5ea}
.rule{font-family:ui-monospace,Menlo,Consolas,monospace;white-space:nowrap}
.where{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:12px;color:#5a6275;word-break:break-all}
.hint{color:#5a6275;font-size:12px}
.notes{color:#5a6275;font-size:12px;margin-top:4px}
.clean-note{color:#2e9d57;font-weight:600}
"""

_TITLES = {"error": "Errors", "warning": "Warnings", "info": "Notes only", "clean": "Clean"}
_PILLS = {"error": "with errors", "warning": "with warnings", "info": "with notes", "clean": "clean"}


def to_html(report: ValidationReport, strict: bool = False, title: str = "meshtool validate") -> str:
    """The report as one HTML document."""
    report = printable_report(report)
    counts = report.counts()
    groups: dict[str, list[AssetResult]] = {k: [] for k in _TITLES}
    for a in report.assets:
        groups[status(a)].append(a)
    verdict = "FAILED" if report.failed(strict) else "passed"
    pills = "".join(f'<span class="pill-{k}">{len(groups[k])} {_PILLS[k]}</span>' for k in _TITLES if groups[k])
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width,initial-scale=1">',
        f"<title>{escape(title)}: {verdict}</title><style>{_CSS}</style></head><body>",
        f"<header><h1>{escape(title)}: {verdict}</h1>",
        f"<div>{len(report.assets)} assets; {counts['error']} errors, {counts['warning']} warnings, "
        f"{counts['info']} notes{' (strict: warnings fail)' if strict else ''}; meshtool {escape(__version__)}"
        f"{'; config ' + escape(report.config_file) if report.config_file else ''}</div>",
        f'<div class="pills" style="margin-top:8px">{pills}</div></header><main>',
    ]
    for key, assets in groups.items():
        if not assets:
            continue
        parts.append(f'<h2 id="{key}">{_TITLES[key]} ({len(assets)})</h2>')
        parts.extend(_card(a, key) for a in assets)
    parts.append("</main></body></html>")
    return "\n".join(parts) + "\n"


def _card(a: AssetResult, key: str) -> str:
    if a.thumbnail:
        src = "data:image/png;base64," + base64.b64encode(a.thumbnail).decode("ascii")
        alt = f"{a.path}: visual (left) and collision (right)"
    else:
        reason = next((n for n in a.notes if "thumbnail" in n or "not checked" in n), "no preview")
        src = _no_preview_image(reason)
        alt = f"{a.path}: {reason}"
    rows = []
    for f in a.findings:
        rule = RULES[f.code]
        where = _local(f.path or a.path, a.path) + (f":{f.line}" if f.line is not None else "")
        rows.append(
            f'<tr><td class="sev {f.severity.value}">{f.severity.value}</td>'
            f'<td class="rule">{f.code} {escape(rule.name)}</td>'
            f'<td>{escape(f.message)}<div class="where">{escape(where)}</div>'
            f'<div class="hint">fix: {escape(rule.hint)}</div></td></tr>'
        )
    findings = f"<table>{''.join(rows)}</table>" if rows else '<div class="clean-note">no findings</div>'
    notes = "".join(f'<div class="notes">{escape(n)}</div>' for n in a.notes)
    return (
        f'<section class="card {key}"><img src="{src}" alt="{escape(alt)}" width="404" height="150">'
        f'<div class="body"><div class="path">{escape(a.path)}</div>'
        f'<div class="stats">{escape(_stats_line(a))}</div>{findings}{notes}</div></section>'
    )


def _local(path: str, asset: str) -> str:
    """``path`` relative to the asset's folder (the card's title names the folder)."""
    folder = asset.rpartition("/")[0]
    return path[len(folder) + 1 :] if folder and path.startswith(folder + "/") else path


def _stats_line(a: AssetResult) -> str:
    s = a.stats
    bits = [a.kind]
    if "triangles" in s:
        bits.append(f"{s['triangles']} triangles")
    extent = s.get("bbox", {}).get("extent") if isinstance(s.get("bbox"), dict) else None
    if extent:
        bits.append(" x ".join(f"{e:.3g}" for e in extent) + " m")
    physics = s.get("physics") or {}
    if "mass_kg" in physics:
        bits.append(f"{physics['mass_kg']:.3g} kg at the default density")
    collision = s.get("collision") or {}
    if collision.get("volume_ratio"):
        bits.append(f"hull/mesh volume {collision['volume_ratio']:.2f}")
    return " · ".join(bits)


def _no_preview_image(reason: str) -> str:
    svg = (
        '<svg xmlns="http://www.w3.org/2000/svg" width="404" height="150">'
        '<rect width="404" height="150" fill="#e8eaee"/>'
        '<text x="202" y="70" font-family="sans-serif" font-size="14" fill="#5a6275" text-anchor="middle">'
        "no preview</text>"
        '<text x="202" y="92" font-family="sans-serif" font-size="11" fill="#5a6275" text-anchor="middle">'
        f"{escape(reason[:70])}</text></svg>"
    )
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")
