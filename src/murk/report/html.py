"""The self-contained ``report.html`` of ``murk compare``: no external file, no network.

Images are embedded as base64 JPEG data URIs and the bar chart is inline SVG, so the file can be mailed or
opened offline. A few lines of script record, once the page has loaded, how many images decoded
(``body[data-images-loaded]`` of ``data-images-total``): the browser test reads them.

Methods and rows that :func:`murk.metrics.flags` flagged (artefacts, structure loss, grey collapse, darkened,
particles not removed) get the ``flagged`` class (red background) and their flags in a ``flags`` column.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Sequence
from html.entities import codepoint2name
from typing import Any

import cv2
import numpy as np

from murk.metrics import table

SUMMARY_COLUMNS = (
    "uiqm",
    "uicm",
    "uism",
    "uiconm",
    "uciqe",
    "structure_gms",
    "artefact_periodic_ratio",
    "artefact_isolated_ratio",
    "particle_residue_ratio",
    "contrast_ratio",
    "luminance_ratio",
)
"""The metrics of the summary and per-image tables, in their order (headings: the metric table's labels and
units; the ``×`` columns are output/input ratios of the restoration measures, 1 = unchanged)."""


def html_heading(text: str) -> str:
    """``text`` escaped for HTML, its non-ASCII characters as named entities (``×`` -> ``&times;``)."""
    return "".join(
        f"&{codepoint2name[ord(c)]};" if ord(c) > 127 and ord(c) in codepoint2name else c for c in html.escape(text)
    )


SUMMARY_METRICS = tuple((k, html_heading(table.get(k).heading)) for k in SUMMARY_COLUMNS)
"""(key, HTML heading) of :data:`SUMMARY_COLUMNS`."""

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#1d2733;background:#fafbfc}
h1{font-size:22px;margin:0 0 4px} h2{font-size:17px;margin:28px 0 8px} .meta{color:#5b6b7c;font-size:13px}
table{border-collapse:collapse;font-size:13px;margin:8px 0;background:#fff}
th,td{border:1px solid #d5dce3;padding:4px 8px;text-align:right} th{background:#eef2f6} td.l,th.l{text-align:left}
tr.best td{font-weight:600} img{max-width:100%;border:1px solid #d5dce3} .note{font-size:12px;color:#5b6b7c}
tr.flagged td{background:#fdecea} td.flags{color:#b3261e;text-align:left}
"""

_SCRIPT = """
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute('data-images-loaded', String(ok));
  document.body.setAttribute('data-images-total', String(imgs.length));
  document.body.setAttribute('data-table-rows', String(document.querySelectorAll('#summary tbody tr').length));
});
"""


def jpeg_data_uri(image_u8: np.ndarray, quality: int = 88) -> str:
    """A ``data:image/jpeg;base64,...`` URI of a uint8 RGB image."""
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image_u8[:, :, ::-1]), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError("image: JPEG encoding failed")
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def bar_chart_svg(labels: Sequence[str], means: Sequence[float], stds: Sequence[float], *, title: str) -> str:
    """A horizontal bar chart (mean with a +- std whisker per method) as inline SVG."""
    n = len(labels)
    row, left, width = 28, 190, 420
    top = max([m + s for m, s in zip(means, stds, strict=True)] + [1e-9])
    bottom = min([0.0] + [m - s for m, s in zip(means, stds, strict=True)])
    span = top - bottom or 1.0

    def x(v: float) -> float:
        return left + (v - bottom) / span * width

    h = 30 + n * row
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + width + 80}" height="{h}" role="img" '
        f'aria-label="{html.escape(title)}"><text x="4" y="16" font-size="13" font-weight="600">'
        f"{html.escape(title)}</text>"
    ]
    for i, (lab, m, s) in enumerate(zip(labels, means, stds, strict=True)):
        y = 26 + i * row
        x0, x1 = x(0.0), x(m)
        parts.append(f'<text x="{left - 6}" y="{y + 15}" font-size="12" text-anchor="end">{html.escape(lab)}</text>')
        parts.append(f'<rect x="{min(x0, x1):.1f}" y="{y + 3}" width="{abs(x1 - x0):.1f}" height="16" fill="#3b7dd8"/>')
        parts.append(f'<line x1="{x(m - s):.1f}" x2="{x(m + s):.1f}" y1="{y + 11}" y2="{y + 11}" stroke="#1d2733"/>')
        parts.append(f'<text x="{x(m + s) + 6:.1f}" y="{y + 15}" font-size="12">{m:.3f}</text>')
    parts.append("</svg>")
    return "".join(parts)


def _fmt(stat: dict[str, float] | None) -> str:
    if not stat or stat.get("n", 0) == 0:
        return "-"
    return f"{stat['mean']:.3f} &plusmn; {stat['std']:.3f}"


def _flag_summary(counts: dict[str, float] | None) -> str:
    """``"2/3 flagged: artefacts 2, darkened 1"`` from :func:`murk.metrics.count_flags` counts (HTML-escaped)."""
    if not counts or not counts.get("flagged"):
        return "" if not counts or not counts.get("n") else "none"
    named = ", ".join(f"{k} {int(v)}" for k, v in counts.items() if k not in ("flagged", "n") and v)
    return html.escape(f"{int(counts['flagged'])}/{int(counts['n'])} flagged: {named}")


def render_report(
    *,
    title: str,
    methods: Sequence[dict[str, Any]],
    summary: dict[str, dict[str, dict[str, float]]],
    images: Sequence[dict[str, Any]],
    notes: Sequence[str] = (),
    meta: str = "",
    columns: Sequence[tuple[str, str]] = SUMMARY_METRICS,
) -> str:
    """The report page (``columns``: the (key, heading) pairs of the tables, :data:`SUMMARY_METRICS` by
    default).

    Args:
        methods: ``{"label", "spec"}`` per method, in display order.
        summary: label -> metric -> ``{"mean", "std", "n"}`` (plus ``ms``: time per image, and optionally
            ``flags``: the counts of :func:`murk.metrics.count_flags`).
        images: per image ``{"name", "grid_u8", "rows": [{"method", metric: value, ..., "flags": "a; b"}]}``.
    """
    labels = [m["label"] for m in methods]
    means = [summary[lab]["uiqm"]["mean"] if summary[lab]["uiqm"]["n"] else 0.0 for lab in labels]
    scored = any(summary[lab]["uiqm"]["n"] for lab in labels)
    best = labels[int(np.argmax(means))] if scored else ""  # no best method when no image was scored
    head = "".join(f"<th>{name} mean &plusmn; std</th>" for _, name in columns)
    rows = []
    for m in methods:
        lab = m["label"]
        s = summary[lab]
        cells = "".join(f"<td>{_fmt(s.get(k))}</td>" for k, _ in columns)
        ms = s.get("ms", {}).get("mean")
        ms_text = "-" if ms is None or not math.isfinite(ms) else f"{ms:.0f}"
        flag_counts = s.get("flags")
        classes = " ".join(
            c for c, on in (("best", lab == best), ("flagged", bool(flag_counts and flag_counts.get("flagged")))) if on
        )
        rows.append(
            f'<tr class="{classes}"><td class="l">{html.escape(lab)}</td>'
            f'<td class="l"><code>{html.escape(m["spec"])}</code></td>{cells}<td>{s["uiqm"]["n"]}</td>'
            f'<td>{ms_text}</td><td class="flags">{_flag_summary(flag_counts)}</td></tr>'
        )
    stds = [summary[lab]["uiqm"]["std"] if summary[lab]["uiqm"]["n"] else 0.0 for lab in labels]
    chart = bar_chart_svg(labels, means, stds, title="Mean UIQM per method (whisker: +- std)")
    sections = []
    for im in images:
        cols = "".join(f"<th>{name}</th>" for _, name in columns)
        trs = "".join(
            f'<tr class="{"flagged" if r.get("flags") else ""}"><td class="l">{html.escape(r["method"])}</td>'
            + "".join(f"<td>{r.get(k, float('nan')):.3f}</td>" for k, _ in columns)
            + f'<td class="flags">{html.escape(r.get("flags", ""))}</td></tr>'
            for r in im["rows"]
        )
        sections.append(
            f'<section><h2>{html.escape(im["name"])}</h2><img alt="{html.escape(im["name"])}" '
            f'src="{jpeg_data_uri(im["grid_u8"])}"><table><thead><tr><th class="l">method</th>{cols}'
            f'<th class="l">flags</th></tr></thead><tbody>{trs}</tbody></table></section>'
        )
    notes_html = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"
        f'<div class="meta">{html.escape(meta)}</div>'
        f'<h2>Summary (the paper\'s Fig. 8)</h2><table id="summary"><thead><tr><th class="l">method</th>'
        f'<th class="l">spec</th>{head}<th>images</th><th>ms / image</th><th class="l">flags</th></tr></thead>'
        f"<tbody>{''.join(rows)}"
        f"</tbody></table>{chart}<ul class='note'>{notes_html}</ul>"
        f"<h2>Per image (the paper's Figs. 7 and 9)</h2>{''.join(sections)}"
        f"<script>{_SCRIPT}</script></body></html>"
    )
