"""Building blocks shared by the reports of ``meshtool validate`` and ``simrun test``.

One definition of each, imported by both packages (simrun reuses meshtool's look and escaping):

- :data:`REPORT_CSS`: the stylesheet of the self-contained HTML pages (header, pills, cards, finding tables);
- :func:`no_preview_image`: the data URI of the grey placeholder a card shows when it has no thumbnail;
- :func:`png_data_uri`: the data URI of a PNG thumbnail;
- :func:`annotation_data` and :func:`annotation_property`: escaping of a GitHub Actions workflow command's
  message and of its ``file=``/``title=`` properties.

Standard library only, so importing it costs nothing.
"""

from __future__ import annotations

import base64
from html import escape

REPORT_CSS = """
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
"""The stylesheet of the HTML reports (``meshtool validate``'s page; ``simrun test`` adds a few rules)."""


def png_data_uri(png: bytes) -> str:
    """``data:image/png;base64,...`` for the PNG bytes ``png`` (a card's thumbnail)."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def no_preview_image(reason: str, width: int = 404, height: int = 150) -> str:
    """The data URI of a ``width`` x ``height`` grey SVG saying "no preview" and why (``reason``, cut to 70).

    The default size is the validate card's thumbnail (visual and collision views side by side).
    """
    x, y = width // 2, height // 2
    svg = (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}">'
        f'<rect width="{width}" height="{height}" fill="#e8eaee"/>'
        f'<text x="{x}" y="{y - 5}" font-family="sans-serif" font-size="14" fill="#5a6275" text-anchor="middle">'
        "no preview</text>"
        f'<text x="{x}" y="{y + 17}" font-family="sans-serif" font-size="11" fill="#5a6275" text-anchor="middle">'
        f"{escape(reason[:70])}</text></svg>"
    )
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def annotation_data(text: str) -> str:
    """``text`` escaped as the message of a GitHub Actions workflow command (after ``::``)."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def annotation_property(text: str) -> str:
    """``text`` escaped as a workflow command's property value (``file=``, ``title=``): also ``:`` and ``,``."""
    return annotation_data(text).replace(":", "%3A").replace(",", "%2C")


__all__ = ["REPORT_CSS", "annotation_data", "annotation_property", "no_preview_image", "png_data_uri"]
