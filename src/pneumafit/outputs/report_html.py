"""HTML building blocks of the validation report: one self-contained page.

Everything the page needs is inside it: inline CSS, figures as base64 PNG
data URIs, one small inline script that checks in the browser that every
figure decoded (it logs a console error for one that did not, which the
report's browser test looks for). No network resource is referenced.
"""

from __future__ import annotations

import base64
import html
import io
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pneumafit.campaign.units import display_unit

__all__ = [
    "CHANNEL_DISPLAY",
    "Section",
    "channel_value",
    "embed_figure",
    "embed_png",
    "embed_png_file",
    "esc",
    "fmt",
    "note",
    "page",
    "table",
]

#: Display unit of each channel: (factor from SI, unit), from the one table
#: (:data:`pneumafit.campaign.units.DISPLAY_UNITS`).
CHANNEL_DISPLAY: dict[str, tuple[float, str]] = {
    name: display_unit(name)
    for name in ("p_P", "p_N", "pressure", "y", "position", "y_ref", "T_P", "T_N",
                 "temperature", "qm_P", "qm_N", "flow", "u_P", "u_N")
}  # fmt: skip


@dataclass
class Section:
    """One section of the report.

    Attributes
    ----------
    anchor : str
        HTML id (for the table of contents).
    title : str
        Heading.
    status : {"ok", "partial", "not run", "error"}
        ``not run``: its input files are missing (``body`` says which);
        ``error``: an input could not be read or rendered (``body`` says why).
    body : str
        HTML content.
    source : str
        The files the section was built from (or would be).
    """

    anchor: str
    title: str
    status: str
    body: str
    source: str = ""


def esc(text: Any) -> str:
    """HTML-escaped ``str(text)``."""
    return html.escape(str(text), quote=True)


def fmt(value: Any, unit: str = "", digits: int = 4) -> str:
    """A number with ``digits`` significant digits and its unit; '-' for none.

    Non-numbers are returned escaped as they are.
    """
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        if not math.isfinite(value):
            text = str(value)
        elif value != 0 and (abs(value) >= 1e6 or abs(value) < 1e-3):
            text = f"{value:.{digits - 1}e}"
        else:
            text = f"{value:.{digits}g}"
            if "e" in text:  # 1e4 <= |value| < 1e6 with few digits: no exponent
                text = f"{value:.0f}"
    else:
        return esc(value)
    return f"{text}&nbsp;{esc(unit)}" if unit else text


def channel_value(channel: str, value: Any, digits: int = 4) -> str:
    """An SI value of a channel in its display unit (:data:`CHANNEL_DISPLAY`)."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return fmt(value)
    factor, unit = CHANNEL_DISPLAY.get(channel, (1.0, "SI"))
    return fmt(float(value) * factor, unit, digits)


def table(
    header: Sequence[str],
    rows: Iterable[Sequence[Any]],
    *,
    caption: str = "",
    raw: bool = True,
) -> str:
    """An HTML table. Cells are HTML already when ``raw`` (use :func:`fmt`)."""
    out = ['<div class="tw"><table>']
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead>")
    out.append("<tbody>")
    n = 0
    for row in rows:
        cells = [str(c) if raw else esc(c) for c in row]
        out.append("<tr>" + "".join(f"<td{_numeric(c)}>{c}</td>" for c in cells) + "</tr>")
        n += 1
    if n == 0:
        out.append(f'<tr><td colspan="{len(header)}"><em>(no rows)</em></td></tr>')
    out.append("</tbody></table></div>")
    return "\n".join(out)


_NUMBER = re.compile(r"^\[?[-+]?(\d|\.\d)[\d.,e+\-]*(&nbsp;|\]|$)")


def _numeric(cell: str) -> str:
    """' class="n"' for a cell that starts with a number (right-aligned)."""
    return ' class="n"' if _NUMBER.match(cell) else ""


def note(text: str, kind: str = "note") -> str:
    """A boxed remark (``kind``: note, warn, notrun, error); ``text`` is HTML."""
    return f'<div class="{esc(kind)}">{text}</div>'


def embed_png(data: bytes, alt: str, caption: str = "") -> str:
    """A PNG (bytes) as an ``<img>`` with a data URI, in a figure."""
    b64 = base64.b64encode(data).decode("ascii")
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return (
        f'<figure><img class="fig" alt="{esc(alt)}" '
        f'src="data:image/png;base64,{b64}">{cap}</figure>'
    )


def embed_figure(fig: Any, alt: str, caption: str = "", dpi: int = 80) -> str:
    """A matplotlib figure as an embedded PNG; the figure is closed."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight")
    finally:
        plt.close(fig)
    return embed_png(buffer.getvalue(), alt, caption)


def embed_png_file(path: Path, caption: str = "") -> str:
    """A PNG file as an embedded figure (its name as the caption by default)."""
    return embed_png(path.read_bytes(), path.name, caption or path.name)


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;
 margin:0;color:#1c1c1c;background:#fff;line-height:1.4}
main{max-width:1200px;margin:0 auto;padding:1em 2em 4em}
header.top{background:#1f3b57;color:#fff;padding:1.2em 2em}
header.top h1{margin:0;font-size:1.6em}
header.top p{margin:.3em 0 0;opacity:.85}
h2{border-bottom:2px solid #1f3b57;padding-bottom:.2em;margin-top:2.2em}
h3{margin-top:1.6em;color:#1f3b57}
h4{margin-bottom:.3em}
table{border-collapse:collapse;margin:.6em 0 1em;font-size:.88em}
caption{text-align:left;font-weight:600;padding:.2em 0;white-space:nowrap}
div.tw{overflow-x:auto;max-width:100%}
th,td{border:1px solid #ccd3da;padding:.25em .55em;text-align:left;vertical-align:top}
td.n{text-align:right;white-space:nowrap}
th{background:#eef2f6}
tbody tr:nth-child(even){background:#f8fafb}
figure{margin:.8em 0}
img.fig{max-width:100%;height:auto;border:1px solid #e1e5ea}
figcaption{font-size:.85em;color:#555}
.note,.warn,.notrun,.error{padding:.5em .8em;margin:.6em 0;border-left:4px solid}
.note{background:#f1f6fb;border-color:#6b93bd}
.warn{background:#fff8e6;border-color:#e0a800}
.notrun{background:#f3f3f3;border-color:#888;font-style:italic}
.error{background:#fdecea;border-color:#c62828}
.status{font-size:.75em;padding:.1em .5em;border-radius:.6em;margin-left:.6em;
 vertical-align:middle;font-weight:normal}
.s-ok{background:#d9f2df;color:#1b5e20}.s-partial{background:#fff3c4;color:#7a5b00}
.s-notrun{background:#e6e6e6;color:#444}.s-error{background:#fbd3d0;color:#8e1b10}
nav.toc{background:#f6f8fa;border:1px solid #dde3e9;padding:.6em 1.2em;margin:1em 0}
nav.toc ol{margin:.3em 0}
code,pre{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;font-size:.88em}
pre{background:#f6f8fa;padding:.6em;overflow-x:auto;white-space:pre-wrap}
p.source{font-size:.8em;color:#666}
details{margin:.5em 0}
summary{cursor:pointer;color:#1f3b57}
footer{margin-top:3em;font-size:.8em;color:#666}
"""

# Checks in the browser that every embedded figure decoded; a figure that did
# not is reported as a console error (the browser test looks for them).
_SCRIPT = """
window.addEventListener("load", function () {
  var images = document.querySelectorAll("img.fig");
  var bad = 0;
  for (var i = 0; i < images.length; i++) {
    if (!images[i].complete || images[i].naturalWidth === 0) {
      bad += 1;
      console.error("report: figure did not decode: " + images[i].alt);
    }
  }
  document.body.setAttribute("data-figures", String(images.length));
  document.body.setAttribute("data-figures-bad", String(bad));
});
"""


def _status_badge(status: str) -> str:
    cls = {"ok": "s-ok", "partial": "s-partial", "not run": "s-notrun"}.get(status, "s-error")
    return f'<span class="status {cls}">{esc(status)}</span>'


def page(title: str, subtitle: str, sections: Sequence[Section], footer: str) -> str:
    """The whole HTML document: header, table of contents, sections, footer."""
    toc = "".join(
        f'<li><a href="#{esc(s.anchor)}">{esc(s.title)}</a>{_status_badge(s.status)}</li>'
        for s in sections
    )
    body = []
    for s in sections:
        source = f'<p class="source">Source: {s.source}</p>' if s.source else ""
        body.append(
            f'<section id="{esc(s.anchor)}" data-status="{esc(s.status)}">'
            f"<h2>{esc(s.title)}{_status_badge(s.status)}</h2>{source}\n{s.body}\n</section>"
        )
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        '<link rel="icon" href="data:,">'
        f"<title>{esc(title)}</title><style>{_CSS}</style>"
        f"<script>{_SCRIPT}</script></head>\n<body>"
        f'<header class="top"><h1>{esc(title)}</h1><p>{subtitle}</p></header>\n<main>'
        f'<nav class="toc"><strong>Contents</strong><ol>{toc}</ol></nav>\n'
        + "\n".join(body)
        + f'\n<footer id="report-end">{footer}</footer></main></body></html>\n'
    )
