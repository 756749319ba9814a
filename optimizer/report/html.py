"""``report.html``: a run folder's front as one self-contained page (no network, no library).

The front in the study's first two objectives (or the first against the trial number) as an SVG
scatter: every evaluated feasible design grey, each Pareto design a circle that, clicked or
hovered, shows its values and links to its leg drawing and its files; the objectives table; the
resolved study. Text a user wrote (study name, values, the study file) is escaped where it lands:
in HTML by :func:`html.escape`, in the page's data by JSON with ``</`` escaped, and shown by the
script through ``textContent`` only.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: The page's name in a run folder.
REPORT_FILE = "report.html"
#: Plot area (SVG user units) and its margins.
_W, _H, _LEFT, _BOTTOM, _TOP, _RIGHT = 640, 420, 70, 50, 20, 20


@dataclass(frozen=True)
class ReportPoint:
    """One Pareto design as the page shows it.

    Attributes:
        trial: its trial number.
        shape: its shape label (``3x2``).
        objectives: objective name -> value (the study's objectives first).
        design: value name -> value.
        files: label -> path relative to the run folder (model file, URDF, MJCF, leg drawing).
    """

    trial: int
    shape: str
    objectives: dict[str, float]
    design: dict[str, float]
    files: dict[str, str]


def report_html(
    name: str,
    objectives: list[str],
    points: list[ReportPoint],
    others: list[tuple[float, float]],
    study_text: str,
    figures: list[str] = (),
) -> str:
    """The page: ``objectives`` are the study's (the first two span the plot), ``others`` the
    other feasible designs' (x, y) in the plot's axes, ``study_text`` the resolved study file,
    ``figures`` the run folder's plots (paths relative to it), shown at the end."""
    two = len(objectives) > 1
    xy = [(p.objectives[objectives[0]], p.objectives[objectives[1]]) if two else (p.trial, p.objectives[objectives[0]])
          for p in points]
    axes = (objectives[0], objectives[1]) if two else ("trial", objectives[0])
    data = {"points": [vars(p) for p in points], "objectives": objectives}
    payload = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    esc = html.escape
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>footopt: {esc(name)}</title>
<style>{_STYLE}</style></head>
<body>
<h1>Study <q>{esc(name)}</q></h1>
<p>{len(points)} Pareto design(s) of {len(points) + len(others)} feasible evaluated; objectives:
{esc(", ".join(objectives))}. Click or hover a point for its design and files.</p>
<div class="row">{_svg(xy, others, axes)}
<div id="details"><p>No design chosen yet.</p></div></div>
<h2>Pareto designs</h2>
{_table(points, objectives)}
{_figures(figures)}<h2>Study settings</h2>
<pre id="study">{esc(study_text)}</pre>
<script type="application/json" id="data">{payload}</script>
<script>{_SCRIPT}</script>
</body></html>
"""


def _figures(figures: list[str]) -> str:
    """The run folder's plots, each an image linking to itself (nothing without plots)."""
    if not figures:
        return ""
    esc = html.escape
    items = "".join(f'<figure><a href="{esc(f, quote=True)}"><img src="{esc(f, quote=True)}" alt="{esc(f)}"></a>'
                    f"<figcaption>{esc(f)}</figcaption></figure>" for f in figures)
    return f'<h2>Figures</h2>\n<div id="figures">{items}</div>\n'


def _scale(values: list[float], lo_px: float, hi_px: float) -> tuple[Any, float, float]:
    lo, hi = min(values), max(values)
    pad = (hi - lo) * 0.08 or abs(hi) * 0.1 or 1.0
    lo, hi = lo - pad, hi + pad
    return (lambda v: lo_px + (v - lo) / (hi - lo) * (hi_px - lo_px)), lo, hi


def _svg(xy: list[tuple[float, float]], others: list[tuple[float, float]], axes: tuple[str, str]) -> str:
    every = xy + others
    sx, x0, x1 = _scale([p[0] for p in every], _LEFT, _W - _RIGHT)
    sy, y0, y1 = _scale([p[1] for p in every], _H - _BOTTOM, _TOP)
    parts = [f'<svg id="front" viewBox="0 0 {_W} {_H}" width="{_W}" height="{_H}" role="img">']
    parts.append(f'<rect x="{_LEFT}" y="{_TOP}" width="{_W - _LEFT - _RIGHT}" height="{_H - _TOP - _BOTTOM}" '
                 'class="frame"/>')
    for k in range(5):
        vx, vy = x0 + (x1 - x0) * k / 4, y0 + (y1 - y0) * k / 4
        parts.append(f'<text x="{sx(vx):.1f}" y="{_H - _BOTTOM + 16}" class="tick">{_tick(vx)}</text>')
        parts.append(f'<text x="{_LEFT - 6}" y="{sy(vy):.1f}" class="tick y">{_tick(vy)}</text>')
    parts.append(f'<text x="{(_LEFT + _W - _RIGHT) / 2}" y="{_H - 8}" class="label">{html.escape(axes[0])}</text>')
    parts.append(f'<text x="14" y="{(_TOP + _H - _BOTTOM) / 2}" class="label" '
                 f'transform="rotate(-90 14 {(_TOP + _H - _BOTTOM) / 2})">{html.escape(axes[1])}</text>')
    for x, y in others:
        parts.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="2.5" class="other"/>')
    for i, (x, y) in enumerate(xy):
        parts.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="7" class="pareto" data-index="{i}" tabindex="0"/>')
    parts.append("</svg>")
    return "\n".join(parts)


def _tick(v: float) -> str:
    return f"{v:.4g}" if math.isfinite(v) else ""


def _table(points: list[ReportPoint], objectives: list[str]) -> str:
    esc = html.escape
    head = "".join(f"<th>{esc(o)}</th>" for o in objectives)
    rows = []
    for i, p in enumerate(points):
        cells = "".join(f"<td>{p.objectives[o]:.6g}</td>" for o in objectives)
        links = " ".join(f'<a href="{esc(path, quote=True)}">{esc(label)}</a>' for label, path in p.files.items())
        rows.append(f'<tr data-index="{i}"><td>{p.trial}</td><td>{esc(p.shape)}</td>{cells}<td>{links}</td></tr>')
    return f'<table id="designs"><tr><th>trial</th><th>shape</th>{head}<th>files</th></tr>\n' + "\n".join(rows) + "</table>"


_STYLE = """
body { font-family: sans-serif; margin: 1.5em; color: #222; }
.row { display: flex; gap: 1.5em; align-items: flex-start; flex-wrap: wrap; }
svg .frame { fill: #fafafa; stroke: #bbb; }
svg .tick { font-size: 11px; text-anchor: middle; fill: #555; }
svg .tick.y { text-anchor: end; dominant-baseline: middle; }
svg .label { font-size: 13px; text-anchor: middle; }
svg .other { fill: #bbb; }
svg .pareto { fill: #3b6ea5; stroke: #111; cursor: pointer; }
svg .pareto.chosen { fill: #e67e22; }
#details { min-width: 18em; max-width: 30em; }
#details img { max-width: 100%; border: 1px solid #ddd; }
#figures img { max-width: 100%; border: 1px solid #ddd; }
table { border-collapse: collapse; } td, th { border: 1px solid #ccc; padding: 2px 6px; font-size: 13px; }
pre { background: #f4f4f4; padding: 0.8em; overflow: auto; }
"""

_SCRIPT = """
"use strict";
const data = JSON.parse(document.getElementById("data").textContent);
const details = document.getElementById("details");
function line(parent, tag, text) { const e = document.createElement(tag); e.textContent = text; parent.appendChild(e); return e; }
function show(i) {
  const p = data.points[i];
  details.replaceChildren();
  line(details, "h3", "trial " + p.trial + " (" + p.shape + ")");
  const list = line(details, "ul", "");
  for (const [k, v] of Object.entries(p.objectives)) line(list, "li", k + " = " + String(v));
  const links = line(details, "p", "");
  for (const [label, path] of Object.entries(p.files)) {
    const a = document.createElement("a"); a.href = path; a.textContent = label; links.appendChild(a);
    links.appendChild(document.createTextNode(" "));
  }
  if (p.files.drawing) { const img = document.createElement("img"); img.src = p.files.drawing; img.alt = "leg"; details.appendChild(img); }
  const values = line(details, "details", ""); line(values, "summary", "design values");
  const table = line(values, "table", "");
  for (const [k, v] of Object.entries(p.design)) { const r = line(table, "tr", ""); line(r, "td", k); line(r, "td", String(v)); }
  document.querySelectorAll("circle.pareto").forEach(c => c.classList.toggle("chosen", Number(c.dataset.index) === i));
}
document.querySelectorAll("circle.pareto, #designs tr[data-index]").forEach(el => {
  const i = Number(el.dataset.index);
  el.addEventListener("click", () => show(i));
  if (el.tagName === "circle") el.addEventListener("mouseenter", () => show(i));
});
"""


def write_report(path: Path, *args: Any) -> Path:
    """Write :func:`report_html` (same arguments after ``path``) to ``path``."""
    path.write_text(report_html(*args), encoding="utf-8")
    return path


__all__ = ["REPORT_FILE", "ReportPoint", "report_html", "write_report"]
