"""A log–log scatter plot as inline SVG, for the verdict: drawn by the browser as the page parses, no script needed.

The verdict's plot must be there the moment the page opens; plotly.js
(4.8 MB of JavaScript) takes seconds to evaluate on a busy machine, so the
verdict draws its Pareto plot as plain SVG built here, and plotly.js is
only unpacked when a section with plotly plots is opened. Every string that
reaches the SVG is escaped (text content and attributes alike).
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import Sequence

from markupsafe import Markup

from reports.palette import GREY


@dataclass(frozen=True)
class Series:
    """One variant's points: name (legend), colour, group (legend heading), and (x, y, hover text) triples.

    muted : drawn grey and under the others until the page asks for every colour (its own colour is kept
    in the CSS variable ``--own``: a rule ``.all-colour g.series.muted {fill: var(--own)}`` brings it back).
    """

    name: str
    colour: str
    group: str
    points: Sequence[tuple[float, float, str]]
    muted: bool = False


def _escape(text: str) -> str:
    return html.escape(str(text), quote=True)


def _decades(low: float, high: float) -> tuple[int, int]:
    a, b = math.floor(math.log10(low)), math.ceil(math.log10(high))
    return (a, b) if b > a else (a, a + 1)


def _tick_label(exponent: int) -> str:
    return f'10<tspan dy="-0.5em" font-size="0.75em">{exponent}</tspan>'


def loglog_svg(series: Sequence[Series], front: Sequence[tuple[float, float]], *, x_title: str, y_title: str,
               target: float | None = None, target_label: str = "", width: int = 720, height: int = 420,
               element_id: str = "", label: str = "") -> Markup:
    """An SVG log–log plot: ``series`` as dots (one ``<g>`` per series, ``data-series`` = its index; muted ones
    grey and drawn first, under the others), ``front`` as a black staircase (step after each point), an
    optional dotted horizontal line at ``target``. ``label``: what a screen reader says the plot shows
    (its ``aria-label``; default: the axes' titles)."""
    xs = [p[0] for s in series for p in s.points if p[0] > 0]
    ys = [p[1] for s in series for p in s.points if p[1] > 0]
    if target is not None and target > 0:
        ys.append(target)
    if not xs or not ys:
        return Markup("")
    x0, x1 = _decades(min(xs), max(xs))
    y0, y1 = _decades(min(ys), max(ys))
    left, right, top, bottom = 70, 15, 12, 48
    plot_w, plot_h = width - left - right, height - top - bottom

    def px(x: float) -> float:
        return left + (math.log10(x) - x0) / (x1 - x0) * plot_w

    def py(y: float) -> float:
        return top + (y1 - math.log10(y)) / (y1 - y0) * plot_h

    parts = [f'<svg class="loglog" id="{_escape(element_id)}" viewBox="0 0 {width} {height}" '
             f'preserveAspectRatio="xMidYMid meet" role="img" '
             f'aria-label="{_escape(label or f"{y_title} against {x_title}, log–log")}" '
             f'font-family="system-ui, sans-serif" font-size="12">',
             f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="#fbfbfb" stroke="#ccc"/>']
    y_step = max(1, math.ceil((y1 - y0) / 10))
    for k in range(x0, x1 + 1):
        x = px(10.0 ** k)
        parts.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{top + plot_h}" stroke="#e4e4e4"/>')
        parts.append(f'<text x="{x:.1f}" y="{top + plot_h + 16}" text-anchor="middle">{_tick_label(k)}</text>')
    for k in range(y0, y1 + 1):
        y = py(10.0 ** k)
        parts.append(f'<line x1="{left}" y1="{y:.1f}" x2="{left + plot_w}" y2="{y:.1f}" stroke="#e4e4e4"/>')
        if (k - y0) % y_step == 0:
            parts.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">{_tick_label(k)}</text>')
    parts.append(f'<text x="{left + plot_w / 2:.1f}" y="{height - 6}" text-anchor="middle">{_escape(x_title)}</text>')
    parts.append(f'<text transform="translate(14 {top + plot_h / 2:.1f}) rotate(-90)" text-anchor="middle">'
                 f'{_escape(y_title)}</text>')
    if target is not None and target > 0:
        y = py(target)
        parts.append(f'<line x1="{left}" y1="{y:.1f}" x2="{left + plot_w}" y2="{y:.1f}" stroke="#888" '
                     f'stroke-dasharray="3 3"/>')
        parts.append(f'<text x="{left + plot_w - 4}" y="{y - 4:.1f}" text-anchor="end" fill="#777" font-size="10">'
                     f'{_escape(target_label)}</text>')
    for index, s in sorted(enumerate(series), key=lambda item: not item[1].muted):  # muted first: underneath
        dots = "".join(
            f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="{3 if s.muted else 4}"><title>{_escape(text)}</title></circle>'
            for x, y, text in s.points if x > 0 and y > 0
        )
        if s.muted:
            parts.append(f'<g class="series muted" data-series="{index}" fill="{GREY}" fill-opacity="0.7" '
                         f'style="--own: {_escape(s.colour)}">{dots}</g>')
        else:
            parts.append(f'<g class="series" data-series="{index}" fill="{_escape(s.colour)}" fill-opacity="0.8">'
                         f'{dots}</g>')
    if front:
        path = [f"M{px(front[0][0]):.1f},{py(front[0][1]):.1f}"]
        for (xb, yb) in front[1:]:
            path.append(f"H{px(xb):.1f}V{py(yb):.1f}")
        parts.append(f'<path class="front" d="{"".join(path)}" fill="none" stroke="#222" stroke-width="2"/>')
    parts.append("</svg>")
    return Markup("".join(parts))
