"""Per-scene plots as plotly.js figure specs (plain ``{"data": [...], "layout": {...}}`` dicts).

Plain dicts rather than ``plotly.graph_objects`` figures: the page draws them
with the plotly.js bundle embedded once (see :mod:`reports.render`), so all
Python has to do is produce JSON, and building dicts is much faster than
validating graph objects (the tests validate the specs against plotly's
schema instead).

Every string from a results file that plotly.js renders (trace names, hover
text) goes through :func:`plot_text`: plotly.js interprets a subset of HTML
in those strings, so an engine label such as ``<b>x</b>`` would otherwise be
rendered as markup. HTML-escaped text is decoded back to the literal
characters by plotly.js, so the user sees exactly what the file says.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterable

from compare.results.sweep import ORDER_METRIC, VariantSweep

from reports.load import SceneResults, is_reference

#: Distinct colours, one per engine variant in a scene (D3/Tableau category20 without its pale halves first).
PALETTE = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd",
    "#e6550d", "#31a354", "#756bb1", "#636363",
)
#: Line dashes cycled once the palette is used up, so two variants never look alike.
DASHES = ("solid", "dot", "dash", "longdash", "dashdot")
REFERENCE_STYLE = {"color": "rgba(0,0,0,0.45)", "width": 5}


@dataclass(frozen=True)
class Plot:
    """One plot of the page: a DOM id (a kind such as "wp" until scene_plots numbers it), heading, caption (plain text; escaped by the template) and the figure spec."""

    id: str
    title: str
    caption: str
    figure: dict[str, Any]

    @property
    def n_traces(self) -> int:
        return len(self.figure["data"])


def plot_text(value: Any) -> str:
    """``value`` as text that plotly.js shows literally (its pseudo-HTML escaped)."""
    return html.escape(str(value), quote=False)


def style(index: int) -> dict[str, Any]:
    """Line colour and dash of the ``index``-th variant of a scene."""
    return {"color": PALETTE[index % len(PALETTE)], "dash": DASHES[(index // len(PALETTE)) % len(DASHES)]}


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def _axis_type(values: Iterable[Any]) -> str:
    """"log" when the positive values span more than a decade (errors usually span many), else "linear"."""
    positive = [abs(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v) and v != 0]
    return "log" if positive and max(positive) > 10 * min(positive) else "linear"


#: Pixels per legend entry: a plot grows with its legend, so a suite of 30 variants needs no legend scrolling.
LEGEND_ROW = 19


def _layout(n_legend: int, height: int = 460, **extra: Any) -> dict[str, Any]:
    base = {
        "height": max(height, 80 + LEGEND_ROW * n_legend),
        "margin": {"l": 70, "r": 20, "t": 30, "b": 50},
        "hovermode": "closest",
        "legend": {"font": {"size": 11}},
        "plot_bgcolor": "#fbfbfb",
    }
    base.update(extra)
    return base


def _axis(title: str, kind: str = "log", **extra: Any) -> dict[str, Any]:
    return {"title": {"text": title}, "type": kind, "exponentformat": "power", "gridcolor": "#e4e4e4", **extra}


# -- across the dt sweep ------------------------------------------------------------


def _sweep_points(sweep: VariantSweep, x_key: str) -> tuple[list[float], list[float], list[list[Any]]]:
    """The ``ok`` cases of ``sweep`` that a log-log plot can show: (x, error m, [variant, dt, status])."""
    xs, ys, custom = [], [], []
    for record in sweep.records:
        metrics = record.metrics
        dt = record.case.dt
        x = dt if x_key == "dt" else metrics.get(x_key)
        y = metrics.get(ORDER_METRIC)
        if record.status == "ok" and _positive(x) and _positive(y):
            xs.append(x)
            ys.append(y)
            custom.append([plot_text(sweep.engine), dt])
    return xs, ys, custom


def _sweep_traces(scene: SceneResults, x_key: str, name: Callable[[VariantSweep], str], hovertemplate: str) -> tuple[list[dict[str, Any]], str]:
    """One lines+markers trace per variant through its dt sweep (see :func:`_sweep_points`), and a note naming
    the variants left out; ``name(sweep)`` is the legend text."""
    traces, missing = [], []
    for index, sweep in enumerate(scene.sweeps):
        xs, ys, custom = _sweep_points(sweep, x_key)
        if not xs:
            missing.append(sweep.engine)
            continue
        traces.append({
            "type": "scatter", "mode": "lines+markers", "name": plot_text(name(sweep)),
            "x": xs, "y": ys, "customdata": custom, "line": style(index), "hovertemplate": hovertemplate,
        })
    needs = "a positive error and cost" if x_key != "dt" else "a positive error"
    note = f" Not drawn (no ok case with {needs}): " + ", ".join(missing) + "." if missing else ""
    return traces, note


def work_precision(scene: SceneResults) -> Plot | None:
    """Max position error (m) against stepping cost per simulated second (s/s), log-log, one line per variant."""
    traces, not_drawn = _sweep_traces(
        scene, "cost_per_simulated_second", lambda sweep: sweep.engine,
        "%{customdata[0]}<br>dt = %{customdata[1]:.3g} s<br>error = %{y:.3g} m<br>cost = %{x:.3g} s/s<extra></extra>",
    )
    if not traces:
        return None
    figure = {
        "data": traces,
        "layout": _layout(
            len(traces),
            xaxis=_axis("stepping cost per simulated second / (s/s)"),
            yaxis=_axis("max position error / m"),
        ),
    }
    caption = ("Lower left is better: less error for less run time. Each line is one engine variant through its "
               "dt sweep (ok cases only); hover a point for its dt." + not_drawn)
    return Plot("wp", "Work–precision: error against run time", caption, figure)


def _order_label(sweep: VariantSweep) -> str:
    fit = sweep.order
    if fit is None or fit.order is None:
        return f"{sweep.engine} (order –)"
    return f"{sweep.engine} (order {fit.order:.2f})"


def error_vs_dt(scene: SceneResults) -> Plot | None:
    """Max position error (m) against dt (s), log-log; the legend gives each variant's observed order."""
    traces, not_drawn = _sweep_traces(
        scene, "dt", _order_label, "%{customdata[0]}<br>dt = %{x:.3g} s<br>error = %{y:.3g} m<extra></extra>",
    )
    if not traces:
        return None
    figure = {
        "data": traces,
        "layout": _layout(len(traces), xaxis=_axis("time step dt / s"), yaxis=_axis("max position error / m")),
    }
    caption = ("The slope of each line is the observed order (fitted over the asymptotic range, see the table); "
               "a line that flattens has reached the reference's accuracy or saturated." + not_drawn)
    return Plot("dt", "Error against time step", caption, figure)


# -- at the chosen dt -----------------------------------------------------------------


#: The time-series panels: series key, axis title, whether the absolute value is drawn.
SERIES_PANELS = (
    ("position_error", "position error / m", False),
    ("energy_drift", "|E(t) − E(0)| / E*", True),
    ("constraint_error", "constraint error / m", False),
)


def _chosen_cases(scene: SceneResults) -> list[tuple[int, VariantSweep, dict[str, Any]]]:
    """(variant index, sweep, record) of every variant with stored series at the chosen dt."""
    chosen = []
    for index, sweep in enumerate(scene.sweeps):
        record = scene.case_at(sweep, scene.chosen_dt)
        # A failed run has no samples: nothing to draw (its message is in the problems list).
        if record is not None and (record.series or {}).get("t"):
            chosen.append((index, sweep, record))
    return chosen


def _label(sweep: VariantSweep, record: dict[str, Any]) -> str:
    return sweep.engine if record.status == "ok" else f"{sweep.engine} ({record.status.value})"


def time_series(scene: SceneResults) -> Plot | None:
    """Position error, |energy drift| and constraint error against t at the chosen dt: three stacked panels."""
    chosen = _chosen_cases(scene)
    if not chosen:
        return None
    traces = []
    panel_values: list[list[Any]] = [[] for _ in SERIES_PANELS]
    for index, sweep, record in chosen:
        series = record.series
        for panel, (key, _, absolute) in enumerate(SERIES_PANELS):
            values = series.get(key) or []
            if absolute:
                values = [None if v is None else abs(v) for v in values]
            panel_values[panel].extend(values)
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": panel == 0,
                "x": series["t"], "y": values, "line": {**style(index), "width": 1.5},
                "xaxis": "x", "yaxis": "y" if panel == 0 else f"y{panel + 1}",
                "hovertemplate": "%{fullData.name}<br>t = %{x:.3g} s<br>%{y:.3g}<extra></extra>",
            })
    # Three panels stacked on one shared time axis (plotly's low-level subplot layout).
    domains = ([0.70, 1.0], [0.36, 0.64], [0.0, 0.30])
    axes = {}
    for panel, (_, title, _) in enumerate(SERIES_PANELS):
        name = "yaxis" if panel == 0 else f"yaxis{panel + 1}"
        axes[name] = _axis(title, _axis_type(panel_values[panel]), domain=domains[panel])
    figure = {
        "data": traces,
        "layout": _layout(len(chosen), height=720, xaxis=_axis("t / s", "linear", anchor="y3"), **axes),
    }
    caption = (f"Every variant at dt = {scene.chosen_dt:.3g} s. A panel is logarithmic when its values span more "
               "than a decade; zeros (the start, an exact constraint) are not drawn on a log axis. A line that "
               "stops early is a run cut at its first non-finite state.")
    return Plot("ts", "Time series at the chosen dt", caption, figure)


def _reference_positions(scene: SceneResults) -> tuple[list[Any] | None, str]:
    """Reference particle positions to draw under the paths, and where they came from.

    Taken from the records' stored reference positions when the results have
    them, else from the reference engine's own case (at the chosen dt, or any).
    """
    for _, _, record in _chosen_cases(scene):
        if record.series.get("reference_positions"):
            return record.series["reference_positions"], "the reference solution"
    for sweep in filter(is_reference, scene.sweeps):
        for record in sorted(sweep.records, key=lambda r: r.case.dt != scene.chosen_dt):
            if record.status == "ok" and (record.series or {}).get("positions"):
                return record.series["positions"], f"{sweep.engine} at dt = {record.case.dt:.3g} s"
    return None, ""


def _particle_xz(positions: list[Any], particle: int) -> tuple[list[Any], list[Any]]:
    xs = [None if p is None or p[particle] is None else p[particle][0] for p in positions]
    zs = [None if p is None or p[particle] is None else p[particle][2] for p in positions]
    return xs, zs


def paths(scene: SceneResults) -> Plot | None:
    """Particle paths in the x–z plane at the chosen dt, drawn over the reference's (wide grey line)."""
    chosen = _chosen_cases(scene)
    chosen = [(i, s, r) for i, s, r in chosen if (r.series or {}).get("positions")]
    if not chosen:
        return None
    n_particles = len(scene.scene.get("particles", [])) or len(chosen[0][2].series["positions"][0])
    traces = []
    reference, source = _reference_positions(scene)
    if reference:
        for particle in range(n_particles):
            xs, zs = _particle_xz(reference, particle)
            traces.append({
                "type": "scatter", "mode": "lines", "name": "reference", "legendgroup": "reference",
                "showlegend": particle == 0, "x": xs, "y": zs, "line": REFERENCE_STYLE, "hoverinfo": "skip",
            })
    for index, sweep, record in chosen:
        for particle in range(n_particles):
            xs, zs = _particle_xz(record.series["positions"], particle)
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": particle == 0,
                "x": xs, "y": zs, "line": {**style(index), "width": 1.5},
                "hovertemplate": f"%{{fullData.name}}<br>particle {particle}<br>x = %{{x:.3g}} m<br>z = %{{y:.3g}} m<extra></extra>",
            })
    figure = {
        "data": traces,
        "layout": _layout(
            len(chosen) + bool(reference),
            height=560,
            xaxis=_axis("x / m", "linear", zeroline=False),
            # Equal scales, so a circle of the wire looks like a circle.
            yaxis=_axis("z / m", "linear", zeroline=False, scaleanchor="x", scaleratio=1),
        ),
    }
    under = f"the wide grey line is {source}" if reference else "no reference path is stored in these results"
    caption = (f"Every particle of every variant at dt = {scene.chosen_dt:.3g} s in the x–z plane; {under}. "
               "Click a legend entry to hide a variant.")
    return Plot("path", "Particle paths (x–z plane)", caption, figure)


def scene_plots(scene: SceneResults, number: int) -> list[Plot]:
    """Every plot of ``scene`` that has something to draw, in page order.

    number : the scene's position on the page; DOM ids are built from it
    (``s0-wp``), never from the scene id, which comes from a file.
    """
    built = (work_precision(scene), error_vs_dt(scene), time_series(scene), paths(scene))
    return [replace(plot, id=f"s{number}-{plot.id}") for plot in built if plot is not None]
