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
    symbol: str = "circle"  # the family's marker shape (reports.palette.FAMILY_SYMBOLS)
    dash: str = "solid"  # the line through its points (a plotly dash name): a work-precision line

#: SVG stroke-dasharray of each plotly dash name.
DASH_ARRAYS = {"solid": "", "dash": "6 4", "dot": "2 3", "dashdot": "6 3 2 3", "longdash": "10 4"}
#: What a screen reader says of each line style.
DASH_WORDS = {"solid": "solid", "dash": "dashed", "dot": "dotted", "dashdot": "dash-dotted", "longdash": "long-dashed"}


def marker(symbol: str, x: float, y: float, r: float, inner: str = "") -> str:
    """One marker of shape ``symbol`` (a plotly name) centred at (x, y), radius about ``r`` px, ``inner`` inside it."""
    if symbol == "circle":
        return f'<circle cx="{x:.0f}" cy="{y:.0f}" r="{r}">{inner}</circle>'
    shapes = {
        "square": [(-0.85, -0.85), (0.85, -0.85), (0.85, 0.85), (-0.85, 0.85)],
        "diamond": [(0, -1.2), (1.2, 0), (0, 1.2), (-1.2, 0)],
        "triangle-up": [(0, -1.2), (1.1, 0.9), (-1.1, 0.9)],
        "triangle-down": [(0, 1.2), (1.1, -0.9), (-1.1, -0.9)],
        "cross": [(-0.35, -1.1), (0.35, -1.1), (0.35, -0.35), (1.1, -0.35), (1.1, 0.35), (0.35, 0.35), (0.35, 1.1),
                  (-0.35, 1.1), (-0.35, 0.35), (-1.1, 0.35), (-1.1, -0.35), (-0.35, -0.35)],
        "x": [(-0.8, -1.05), (0, -0.25), (0.8, -1.05), (1.05, -0.8), (0.25, 0), (1.05, 0.8), (0.8, 1.05), (0, 0.25),
              (-0.8, 1.05), (-1.05, 0.8), (-0.25, 0), (-1.05, -0.8)],
    }
    corners = shapes.get(symbol)
    if corners is None:
        return f'<circle cx="{x:.0f}" cy="{y:.0f}" r="{r}">{inner}</circle>'
    points = " ".join(f"{x + r * dx:.0f},{y + r * dy:.0f}" for dx, dy in corners)
    return f'<polygon points="{points}">{inner}</polygon>'


def _escape(text: str) -> str:
    return html.escape(str(text), quote=True)


def _decades(low: float, high: float) -> tuple[int, int]:
    a, b = math.floor(math.log10(low)), math.ceil(math.log10(high))
    return (a, b) if b > a else (a, a + 1)


def _tick_label(exponent: int) -> str:
    return f'10<tspan dy="-0.5em" font-size="0.75em">{exponent}</tspan>'


def key_svg(symbol: str, dash: str, colour: str, muted: bool = False) -> Markup:
    """A legend key drawn as the plot draws its series: a short line in its dash with its marker shape on it, in
    ``colour`` (``currentColor``, so a muted key turns grey by CSS and back with "all variants in colour")."""
    dasharray = DASH_ARRAYS.get(dash, "")
    said = f"key: {DASH_WORDS.get(dash, dash)} line, {symbol} markers"
    return Markup(f'<svg class="key{" muted" if muted else ""}" width="26" height="12" viewBox="0 0 26 12" '
                  f'role="img" aria-label="{_escape(said)}" fill="currentColor" stroke="currentColor" style="color: {_escape(colour)}; '
                  f'--own: {_escape(colour)}"><line x1="1" y1="6" x2="25" y2="6" stroke-width="1.5"'
                  + (f' stroke-dasharray="{dasharray}"' if dasharray else "") + f'/>{marker(symbol, 13, 6, 3.6)}</svg>')


def loglog_svg(series: Sequence[Series], front: Sequence[tuple[float, float]], *, x_title: str, y_title: str,
               target: float | None = None, target_label: str = "", width: int = 720, height: int = 420,
               element_id: str = "", label: str = "", picks: Sequence[tuple[float, float, str]] = (),
               y_extent: Sequence[float] = ()) -> Markup:
    """An SVG log–log plot: ``series`` as dots (one ``<g>`` per series, ``data-series`` = its index; muted ones
    grey and drawn first, under the others), ``front`` as a black staircase (step after each point), an
    optional dotted horizontal line at ``target``; each series' points joined in order (a work-precision line);
    ``picks`` (x, y, name) labelled beside their point. ``label``: what a screen reader says the plot shows
    (its ``aria-label``; default: the axes' titles). ``y_extent``: values the y axis must span besides the
    points (two plots side by side given each other's errors share their y axis)."""
    xs = [p[0] for s in series for p in s.points if p[0] > 0]
    ys = [p[1] for s in series for p in s.points if p[1] > 0] + [y for y in y_extent if y > 0]
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
            marker(s.symbol, px(x), py(y), 3 if s.muted else 4.5, f"<title>{_escape(text)}</title>")
            for x, y, text in s.points if x > 0 and y > 0
        )
        drawn = [(px(x), py(y)) for x, y, _ in s.points if x > 0 and y > 0]
        dash = DASH_ARRAYS.get(s.dash, "")
        line = (f'<polyline points="{" ".join(f"{a:.0f},{b:.0f}" for a, b in drawn)}" fill="none" '
                f'stroke-width="{1 if s.muted else 1.5}"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>"
                if len(drawn) > 1 else "")
        if s.muted:
            parts.append(f'<g class="series muted" data-series="{index}" data-variant="{_escape(s.name)}" fill="{GREY}" stroke="{GREY}" fill-opacity="0.7" '
                         f'style="--own: {_escape(s.colour)}">{line}{dots}</g>')
        else:
            parts.append(f'<g class="series" data-series="{index}" data-variant="{_escape(s.name)}" fill="{_escape(s.colour)}" stroke="{_escape(s.colour)}" '
                         f'fill-opacity="0.85">{line}{dots}</g>')
    if front:
        path = [f"M{px(front[0][0]):.1f},{py(front[0][1]):.1f}"]
        for (xb, yb) in front[1:]:
            path.append(f"H{px(xb):.1f}V{py(yb):.1f}")
        parts.append(f'<path class="front" d="{"".join(path)}" fill="none" stroke="#222" stroke-width="2"/>')
    placed: list[tuple[float, float, float]] = []  # (start, end, baseline) of the labels drawn so far
    for x, y, name in sorted((p for p in picks if p[0] > 0 and p[1] > 0), key=lambda p: -p[1]):
        start, base = px(x) + 7, py(y) - 7
        end = start + 6.5 * len(name)  # about the width of 11 px bold text
        while any(a < end and start < b and abs(base - c) < 13 for a, b, c in placed):
            base += 13  # below the label it would overlap
        placed.append((start, end, base))
        parts.append(f'<text class="pick" x="{start:.1f}" y="{base:.1f}" font-size="11" font-weight="600" '
                     f'paint-order="stroke" stroke="#fff" stroke-width="3">{_escape(name)}</text>')
    parts.append("</svg>")
    return Markup("".join(parts))
