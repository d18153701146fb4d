"""The HTML report: one self-contained page (inline CSS, images as data URIs), one card per asset.

Each card has exactly one ``<img>``: the thumbnail (visual and collision views side by side) or, when
there is none, an inline SVG saying why. Cards are grouped by status, worst first.
"""

from __future__ import annotations

from html import escape

from meshtool import __version__
from meshtool.validate.reports.machine import format_label, status
from meshtool.validate.reports.names import printable_report
from meshtool.validate.rules import RULES
from meshtool.validate.runner import ValidationReport
from meshtool.validate.task import AssetResult
from meshtool.work.reportkit import REPORT_CSS, no_preview_image, png_data_uri

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
        f"<title>{escape(title)}: {verdict}</title><style>{REPORT_CSS}</style></head><body>",
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
        src = png_data_uri(a.thumbnail)
        alt = f"{a.path}: visual (left) and collision (right)"
    else:
        reason = a.thumbnail_note or next((n for n in a.notes if "not checked" in n), "no preview")
        src = no_preview_image(reason)
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
    notes = "".join(f'<div class="notes">{escape(n)}</div>' for n in [*a.notes, *filter(None, [a.thumbnail_note])])
    card = f'<section class="card {key}" data-format="{escape(a.format or a.kind)}">'
    return (
        f'{card}<img src="{src}" alt="{escape(alt)}" width="404" height="150">'
        f'<div class="body"><div class="path">{escape(a.path)}</div>'
        f'<div class="stats">{escape(_stats_line(a))}</div>{findings}{notes}</div></section>'
    )


def _local(path: str, asset: str) -> str:
    """``path`` relative to the asset's folder (the card's title names the folder)."""
    folder = asset.rpartition("/")[0]
    return path[len(folder) + 1 :] if folder and path.startswith(folder + "/") else path


def _stats_line(a: AssetResult) -> str:
    s = a.stats
    bits = [format_label(a)]
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
