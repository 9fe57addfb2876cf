"""The report's gradient section: each variant's gradient error against the horizon t, beside the reference's.

For a suite with ``[gradients]`` (docs/gradients.md) each case record carries the gradient metrics and the
series compare.gradients.measure.gradient_series stores: the reference Jacobian's norm ‖J_ref(t)‖_F and its
own error (its two solves' difference) over time, its horizon, and the engine's error over time (at T alone
for an engine whose own derivatives give the Jacobian at T only). Per scene, at its chosen dt, two inline SVG
plots on one time axis (semi-log): the error of each variant with the reference's own error under it, and
the reference Jacobian's norm growth; both mark the reference's horizon. Variants are told apart by their
family's marker and their dash (reports.palette), so the plot reads without colour; a table gives the numbers.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import Any, Sequence

from markupsafe import Markup

from compare.results.record import CaseRecord
from reports.load import ReportData, SceneResults
from reports.palette import REFERENCE_COLOUR, Palette
from reports.svgplot import DASH_ARRAYS, marker

#: Markers drawn on a variant's error line (the rest of its samples are joined by the line alone).
MARKERS_PER_LINE = 8


@dataclass(frozen=True)
class Line:
    """One curve: name (legend), colour, dash (a plotly dash name), symbol (marker shape, or "" for none),
    points (t s, value) in time order."""

    name: str
    colour: str
    dash: str
    symbol: str
    points: Sequence[tuple[float, float]]


def _escape(text: Any) -> str:
    return html.escape(str(text), quote=True)


def time_svg(lines: Sequence[Line], *, duration: float, y_title: str, label: str, horizon: float | None = None,
             element_id: str = "", width: int = 720, height: int = 300) -> Markup:
    """An SVG plot of ``lines`` against time 0..``duration`` s (linear) on a log y axis, a dashed vertical line at
    ``horizon`` (s) when given, a legend beside it; ``label`` is its ``aria-label``. Values ≤ 0 or not finite are
    left out (a line breaks there)."""
    ys = [y for line in lines for _, y in line.points if math.isfinite(y) and y > 0]
    if not ys or duration <= 0:
        return Markup("")
    y0, y1 = math.floor(math.log10(min(ys))), math.ceil(math.log10(max(ys)))
    y1 = y1 if y1 > y0 else y0 + 1
    left, right, top, bottom, legend = 70, 15, 12, 44, 220
    plot_w, plot_h = width - left - right - legend, height - top - bottom

    def px(t: float) -> float:
        return left + t / duration * plot_w

    def py(y: float) -> float:
        return top + (y1 - math.log10(y)) / (y1 - y0) * plot_h

    parts = [f'<svg class="gradient-plot" id="{_escape(element_id)}" viewBox="0 0 {width} {height}" width="{width}" '
             f'style="max-width: 100%; height: auto" role="img" '
             f'aria-label="{_escape(label)}" font-family="system-ui, sans-serif" font-size="12">',
             f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="#fbfbfb" stroke="#ccc"/>']
    step = max(1, math.ceil((y1 - y0) / 8))
    for k in range(y0, y1 + 1, step):
        y = py(10.0 ** k)
        parts.append(f'<line x1="{left}" y1="{y:.1f}" x2="{left + plot_w}" y2="{y:.1f}" stroke="#e4e4e4"/>'
                     f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">10<tspan dy="-0.5em" '
                     f'font-size="0.75em">{k}</tspan></text>')
    for k in range(6):
        t = duration * k / 5
        parts.append(f'<text x="{px(t):.1f}" y="{top + plot_h + 16}" text-anchor="middle">{t:.3g}</text>')
    parts.append(f'<text x="{left + plot_w / 2:.1f}" y="{height - 6}" text-anchor="middle">t (s), the horizon of '
                 f'the derivative</text>')
    parts.append(f'<text transform="translate(14 {top + plot_h / 2:.1f}) rotate(-90)" text-anchor="middle">'
                 f'{_escape(y_title)}</text>')
    if horizon is not None and 0 <= horizon <= duration:
        x = px(horizon)
        right_half = x > left + plot_w / 2  # its label on the side with room
        parts.append(f'<g class="horizon"><line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{top + plot_h}" '
                     f'stroke="#444" stroke-dasharray="5 3"/><text x="{x - 4 if right_half else x + 4:.1f}" '
                     f'y="{top + plot_h - 8}" font-size="11" text-anchor="{"end" if right_half else "start"}" '
                     f'paint-order="stroke" stroke="#fff" stroke-width="3">reference horizon {horizon:.3g} s</text></g>')
    for index, line in enumerate(lines):
        kept = [(t, y) for t, y in line.points if math.isfinite(y) and y > 0 and 0 <= t <= duration]
        dash = DASH_ARRAYS.get(line.dash, "")
        runs: list[list[tuple[float, float]]] = [[]]
        for t, y in line.points:  # a value left out breaks the line
            if math.isfinite(y) and y > 0 and 0 <= t <= duration:
                runs[-1].append((t, y))
            elif runs[-1]:
                runs.append([])
        body = "".join(
            f'<polyline points="{" ".join(f"{px(t):.1f},{py(y):.1f}" for t, y in run)}" fill="none" '
            f'stroke-width="1.5"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>"
            for run in runs if len(run) > 1)
        if line.symbol and kept:
            every = max(1, len(kept) // MARKERS_PER_LINE)
            chosen = kept[::-every][::-1]  # the last point (T) always marked
            body += "".join(marker(line.symbol, px(t), py(y), 4, f"<title>{_escape(line.name)}: {y:.3g} at "
                                                                 f"{t:.3g} s</title>") for t, y in chosen)
        legend_y = top + 14 + 18 * index
        legend_x = left + plot_w + 14
        sample = (f'<line x1="{legend_x}" y1="{legend_y - 4}" x2="{legend_x + 28}" y2="{legend_y - 4}" '
                  f'stroke-width="1.5"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")
        if line.symbol:
            sample += marker(line.symbol, legend_x + 14, legend_y - 4, 4)
        parts.append(f'<g class="series" data-variant="{_escape(line.name)}" fill="{_escape(line.colour)}" '
                     f'stroke="{_escape(line.colour)}">{body}{sample}<text x="{legend_x + 34}" y="{legend_y}" '
                     f'stroke="none" fill="#222">{_escape(line.name)}</text></g>')
    parts.append("</svg>")
    return Markup("".join(parts))


def _class(wrong: Any, horizon: float | None, duration: float) -> str:
    """The class the record's metrics imply: "wrong or nan" (gradient_wrong = 1), "chaotic" (T past the reference's
    horizon), else "correct" (compare/gradients/measure.py's classes)."""
    if wrong == 1:
        return "wrong or nan"
    return "chaotic" if horizon is not None and horizon < duration else "correct"


def _series(record: CaseRecord, name: str) -> list[float]:
    values = (record.series or {}).get(name) or []
    return [math.nan if v is None else float(v) for v in values]


def _record(sweep: Any, dt: float | None) -> CaseRecord | None:
    """The sweep's record at ``dt`` with gradient series, else its smallest dt's that has them."""
    carrying = [r for r in sweep.records if r.series and r.series.get("gradient_error_over_time") is not None
                and (r.metrics or {}).get("gradient_error") is not None]
    at = [r for r in carrying if r.case.dt == dt]
    return (at or sorted(carrying, key=lambda r: r.case.dt))[0] if carrying else None


def scene_gradients(scene: SceneResults, number: int, palette: Palette) -> dict[str, Any] | None:
    """One scene's gradient view (None when no record of it carries gradient metrics): its table rows, its two
    plots, the reference's horizon and its norm growth over the run."""
    picked = [(sweep.engine, r) for sweep in scene.sweeps if (r := _record(sweep, scene.chosen_dt)) is not None]
    if not picked:
        return None
    first = picked[0][1]
    times = _series(first, "gradient_t")
    norm = _series(first, "gradient_reference_norm")
    difference = _series(first, "gradient_reference_difference")
    horizon_values = _series(first, "gradient_horizon")
    horizon = horizon_values[0] if horizon_values else None
    duration = float(scene.scene.get("duration") or (times[-1] if times else 0.0))
    start = next((v for v in norm if math.isfinite(v) and v > 0), None)
    relative = norm[0] > 0 if norm else False  # J_ref(0) = 0 when only physical parameters are differentiated
    growth = [(t, v / norm[0] if relative else v) for t, v in zip(times, norm)]
    reference = Line("reference's own error", REFERENCE_COLOUR, "dot", "", list(zip(times, difference)))
    lines, rows = [reference], []
    for engine, record in picked:
        style = palette.style(engine)
        lines.append(Line(engine, style["color"], style["dash"], palette.symbol(engine),
                          list(zip(_series(record, "gradient_error_t"), _series(record, "gradient_error_over_time")))))
        metrics = record.metrics or {}
        rows.append({"engine": engine, "dt": record.case.dt, "error": metrics.get("gradient_error"),
                     "self_consistency": metrics.get("gradient_self_consistency"),
                     "class": _class(metrics.get("gradient_wrong"), horizon, duration)})
    names = ", ".join(engine for engine, _ in picked)
    where = f"; the reference's horizon at {horizon:.3g} s" if horizon is not None else "; no reference horizon"
    error_svg = time_svg(lines, duration=duration, y_title="relative error of J", horizon=horizon,
                         element_id=f"gradient-error-{number}",
                         label=f"Gradient error against the horizon t on {scene.scene_id}, log scale: {names}, and "
                               f"the reference's own error{where}")
    growth_title = "‖J_ref(t)‖ / ‖J_ref(0)‖" if relative else "‖J_ref(t)‖_F"
    growth_svg = time_svg([Line("reference Jacobian norm", "#222", "solid", "", growth)], duration=duration,
                          y_title=growth_title, horizon=horizon, element_id=f"gradient-growth-{number}",
                          label=f"Growth of the reference Jacobian's norm against t on {scene.scene_id}, log "
                                f"scale{where}")
    end = next((v for v in reversed(norm) if math.isfinite(v) and v > 0), None)
    rate = (math.log(end / start) / duration if start and end and duration > 0 else None)
    return {"number": number, "scene_id": scene.scene_id, "dt": scene.chosen_dt, "horizon": horizon, "rows": rows,
            "error_svg": error_svg, "growth_svg": growth_svg, "growth_title": growth_title, "rate": rate}


def gradient_views(data: ReportData, palette: Palette) -> list[dict[str, Any]]:
    """Per scene with gradient metrics, :func:`scene_gradients`'s view, in the suite's order ([] without
    ``[gradients]``: the section is left out)."""
    views = (scene_gradients(scene, number, palette) for number, scene in enumerate(data.scenes))
    return [view for view in views if view is not None]
