"""Per-scene plots as plotly.js figure specs (plain ``{"data": [...], "layout": {...}}`` dicts).

Plain dicts rather than ``plotly.graph_objects`` figures: the page draws them
with the plotly.js bundle embedded once (see :mod:`reports.render`), so all
Python has to do is produce JSON, and building dicts is much faster than
validating graph objects (the tests validate the specs against plotly's
schema instead).

Details: docs/report.md, "Module notes", ``reports/figures.py``.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterable, Sequence, TypeGuard

from compare.results.record import CaseRecord, Status
from compare.results.series import SERIES_DIGITS
from compare.results.sweep import ORDER_METRIC, VariantSweep
from compare.results.table import estimate_text, scene_reference
from compare.results.verdict import points

from reports.decimate import MAX_POINTS, decimate
from reports.emphasis import emphasise, named_variants
from reports.load import SceneResults
from reports.palette import REFERENCE_COLOUR, Palette, family_of

REFERENCE_STYLE = {"color": REFERENCE_COLOUR, "width": 5}
#: A value past this many times its bound is clipped to it (and the blow-up marked).
CLIP_FACTOR = 10.0
#: Significant digits of the numbers in a figure spec (the stored series keep 6).
DIGITS = 4
#: The relative resolution of a stored series (SERIES_DIGITS = 6 significant digits, each value within 5e-6 of
#: itself): a difference of two stored values below this fraction of their size may be round-off.
SERIES_RESOLUTION = 10.0 ** (1 - SERIES_DIGITS)


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


@dataclass(frozen=True)
class Ceilings:
    """Where each time-series quantity is clipped: position error m, energy drift E*, constraint error m, force N."""

    position_error: float
    energy_drift: float
    constraint_error: float
    force: float = math.inf

    @classmethod
    def for_scene(cls, length: float, energy_bound: float, constraint_bound: float, force: float = math.inf) -> "Ceilings":
        """CLIP_FACTOR × (L, the energy bound, the constraint bound · L); ``force`` : N (CLIP_FACTOR × m g)."""
        return cls(CLIP_FACTOR * length, CLIP_FACTOR * energy_bound, CLIP_FACTOR * constraint_bound * length, force)


@dataclass(frozen=True)
class Thinning:
    """How a plot's time series are thinned: points per trace (LTTB), significant digits (None: DIGITS), and points
    per trace of a variant outside ``named`` (None: ``limit``), drawn for context. A big suite's page thins more
    (reports.render.LAZY_SERIES)."""

    limit: int = MAX_POINTS
    digits: int | None = None
    muted_limit: int | None = None
    named: frozenset[str] = frozenset()

    def points(self, engine: str) -> int:
        return self.limit if self.muted_limit is None or engine in self.named else self.muted_limit


def plot_text(value: Any) -> str:
    """``value`` as text that plotly.js shows literally (its pseudo-HTML escaped)."""
    return html.escape(str(value), quote=False)


def _round(value: Any) -> Any:
    """A number to DIGITS significant digits (None stays None): smaller specs, same plot."""
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(f"{value:.{DIGITS}g}")


def _rounded(values: Iterable[Any], digits: int | None = None) -> list[Any]:
    """``values`` to ``digits`` (default DIGITS) significant digits."""
    if digits is None:
        return [_round(v) for v in values]
    return [None if v is None or not isinstance(v, (int, float)) or not math.isfinite(v) else float(f"{v:.{digits}g}")
            for v in values]


def _positive(value: Any) -> TypeGuard[float]:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def _axis_type(values: Iterable[Any]) -> str:
    """"log" when the positive values span more than a decade (errors usually span many), else "linear"."""
    positive = [abs(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v) and v != 0]
    return "log" if positive and max(positive) > 10 * min(positive) else "linear"


#: Pixels per legend entry (a variant, or a family's title; the gaps between families included): a plot grows
#: with its legend, so a suite of 30 variants needs no legend scrolling (tests/test_report_browser.py).
LEGEND_ROW = 21


def _layout(n_legend: int, height: int = 460, **extra: Any) -> dict[str, Any]:
    base = {
        "height": max(height, 100 + LEGEND_ROW * n_legend),
        "margin": {"l": 70, "r": 20, "t": 30, "b": 50},
        "hovermode": "closest",
        "legend": {"font": {"size": 11}, "groupclick": "toggleitem"},
        "plot_bgcolor": "#fbfbfb",
    }
    base.update(extra)
    return base


def _axis(title: str, kind: str = "log", **extra: Any) -> dict[str, Any]:
    # automargin and a standoff keep the title clear of the tick labels, however wide they are.
    return {"title": {"text": title, "standoff": 10}, "type": kind, "exponentformat": "power", "gridcolor": "#e4e4e4",
            "automargin": True, **extra}


def _by_family(items: Sequence[Any], engine: Callable[[Any], str]) -> list[Any]:
    """``items`` with each family's together, families in order of first appearance (stable within a family)."""
    order: dict[str, int] = {}
    for item in items:
        order.setdefault(family_of(engine(item)), len(order))
    return sorted(items, key=lambda item: order[family_of(engine(item))])


def _group(trace: dict[str, Any], engine: str, titled: set[str]) -> dict[str, Any]:
    """Put ``trace`` in its family's legend group (the first of a family carries the group's title)."""
    name = family_of(engine)
    trace["legendgroup"] = plot_text(name)
    if name not in titled:
        trace["legendgrouptitle"] = {"text": plot_text(name)}
        titled.add(name)
    return trace


# -- across the dt sweep ------------------------------------------------------------


def sweep_points(sweep: VariantSweep, x_key: str) -> tuple[list[float], list[float], list[list[Any]]]:
    """The ``ok`` cases of ``sweep`` that a log-log plot can show: (x, error m, [variant, dt]); x is dt, or for
    "cost" the variant's modelled cost per simulated second (compare.results.cost: monotone in dt)."""
    if x_key == "cost":
        found = points(sweep)
        return [p.cost for p in found], [p.error for p in found], [[plot_text(sweep.engine), p.dt] for p in found]
    xs: list[float] = []
    ys: list[float] = []
    custom: list[list[Any]] = []
    for record in sweep.records:
        dt = record.case.dt
        if x_key == "dt" and record.case.tolerance is not None:
            continue  # a tolerance-axis case has no time step to plot against (its dt is only the largest step)
        x = dt if x_key == "dt" else record.metrics.get(x_key)
        y = record.metrics.get(ORDER_METRIC)
        if record.status is Status.OK and _positive(x) and _positive(y):
            xs.append(x)
            ys.append(y)
            custom.append([plot_text(sweep.engine), dt])
    return xs, ys, custom


def _sweep_traces(scene: SceneResults, palette: Palette, x_key: str, name: Callable[[VariantSweep], str],
                  hovertemplate: str) -> tuple[list[dict[str, Any]], str]:
    """One lines+markers trace per variant through its dt sweep (see :func:`sweep_points`), grouped by
    family, and a note naming the variants left out; ``name(sweep)`` is the legend text."""
    traces, missing = [], []
    titled: set[str] = set()
    for sweep in _by_family(scene.sweeps, lambda s: s.engine):
        xs, ys, custom = sweep_points(sweep, x_key)
        if not xs:
            missing.append(sweep.engine)
            continue
        style = palette.style(sweep.engine)
        traces.append(_group({
            "type": "scatter", "mode": "lines+markers", "name": plot_text(name(sweep)), "meta": plot_text(sweep.engine),
            "x": xs, "y": ys, "customdata": custom, "line": style, "hovertemplate": hovertemplate,
            "marker": {"symbol": palette.symbol(sweep.engine), "color": style["color"], "size": 7},
        }, sweep.engine, titled))
    needs = "a positive error and cost" if x_key != "dt" else "a positive error"
    note = f" Not drawn (no ok case with {needs}): " + ", ".join(missing) + "." if missing else ""
    return traces, note


def work_precision(scene: SceneResults, palette: Palette) -> Plot | None:
    """Max position error (m) against stepping cost per simulated second (s/s), log-log, one line per variant."""
    traces, not_drawn = _sweep_traces(
        scene, palette, "cost", lambda sweep: sweep.engine,
        "%{customdata[0]}<br>dt = %{customdata[1]:.3g} s<br>error = %{y:.3g} m<br>cost = %{x:.3g} s/s<extra></extra>",
    )
    if not traces:
        return None
    figure = {
        "data": traces,
        "layout": _layout(
            len(traces) + len({t["legendgroup"] for t in traces}),
            xaxis=_axis("stepping cost per simulated second / (s/s of CPU)"),
            yaxis=_axis("max position error / m"),
        ),
    }
    caption = ("Lower left is better: less error for less run time. Each line is one engine variant through its "
               "dt sweep (ok cases only), its cost the variant's fitted per-step CPU cost × steps per simulated "
               "second; hover a point for its dt. In colour: the variants the verdict names (the front, each "
               "family's best); the button above shows all." + not_drawn)
    return Plot("wp", "Work–precision: error against run time", caption, figure)


def _order_label(sweep: VariantSweep) -> str:
    fit = sweep.order
    if fit is None or fit.order is None:
        return f"{sweep.engine} (order –)"
    return f"{sweep.engine} (order {fit.order:.2f})"


def error_vs_dt(scene: SceneResults, palette: Palette) -> Plot | None:
    """Max position error (m) against dt (s), log-log; the legend gives each variant's observed order."""
    traces, not_drawn = _sweep_traces(
        scene, palette, "dt", _order_label, "%{customdata[0]}<br>dt = %{x:.3g} s<br>error = %{y:.3g} m<extra></extra>",
    )
    if not traces:
        return None
    figure = {
        "data": traces,
        "layout": _layout(len(traces) + len({t["legendgroup"] for t in traces}),
                          xaxis=_axis("time step dt / s"), yaxis=_axis("max position error / m")),
    }
    caption = ("The slope of each line is the observed order (fitted over the asymptotic range, see the table); "
               "a line that flattens has reached the reference's accuracy or saturated. A line that flattens above "
               "the verdict tolerance converges to something other than the reference (inconsistent)." + not_drawn)
    return Plot("dt", "Error against time step", caption, figure)


# -- at the chosen dt -----------------------------------------------------------------


#: The time-series panels: series key, axis title, whether the absolute value is drawn, the Ceilings field.
SERIES_PANELS = (
    ("position_error", "position error / m", False, "position_error"),
    ("energy_drift", "|E(t) − E(0)| / E*", True, "energy_drift"),
    ("constraint_error", "constraint error / m", False, "constraint_error"),
)


def _chosen_cases(scene: SceneResults, dt: float | None = None) -> list[tuple[int, VariantSweep, CaseRecord]]:
    """(variant index, sweep, record) of every variant with stored series at ``dt`` (s; default the chosen dt)."""
    dt = scene.chosen_dt if dt is None else dt
    chosen = []
    for index, sweep in enumerate(scene.sweeps):
        record = scene.case_at(sweep, dt)
        # A failed run has no samples: nothing to draw (its message is in the problems list).
        if record is not None and (record.series or {}).get("t"):
            chosen.append((index, sweep, record))
    return chosen


def _label(sweep: VariantSweep, record: CaseRecord) -> str:
    return sweep.engine if record.status is Status.OK else f"{sweep.engine} ({record.status.value})"


def clip(t: Sequence[float], values: Sequence[Any], ceiling: float) -> tuple[list[Any], float | None]:
    """``values`` with every finite value above ``ceiling`` set to it, and the first t at which that happened
    (None: never); a None (non-finite) sample after a clipped one stays clipped, so the line ends at the ceiling."""
    out: list[Any] = []
    blew: float | None = None
    for time, value in zip(t, values):
        if value is not None and isinstance(value, (int, float)) and value > ceiling:
            blew = time if blew is None else blew
            out.append(ceiling)
        elif value is None and blew is not None:
            out.append(ceiling)
        else:
            out.append(value)
    return out, blew


def last_finite(t: Sequence[float], values: Sequence[Any], duration: float) -> tuple[float, float] | None:
    """(t, value) of the last finite sample of a series that ends before ``duration`` (s) or turns
    non-finite; None when it runs to the end."""
    finite = [k for k, v in enumerate(values) if isinstance(v, (int, float)) and math.isfinite(v)]
    if not finite:
        return None
    k = finite[-1]
    ends_early = t[min(len(t), len(values)) - 1] < duration * (1 - 1e-9) - 1e-12
    if k == len(values) - 1 and not ends_early:
        return None
    return t[k], values[k]


#: Where successive "blew up at t = …" labels go around their ×, so that neighbours do not overlap.
BLOWUP_CORNERS = ("bottom right", "top left", "top right", "bottom left")


def _blowup_marker(t: float, y: float, colour: str, axis: tuple[str, str], engine: str,
                   text: str = "blew up at t = {t:.3g} s") -> dict[str, Any]:
    """An × at (t, y) with ``text`` beside it (formatted with t): where a run left the plot."""
    label = text.format(t=t)
    return {
        "type": "scatter", "mode": "markers+text", "x": [_round(t)], "y": [_round(y)],
        "marker": {"symbol": "x", "size": 11, "color": colour}, "text": [label],
        "textposition": "bottom right", "textfont": {"size": 10, "color": colour}, "showlegend": False,
        "name": plot_text(engine), "xaxis": axis[0], "yaxis": axis[1],
        "hovertemplate": plot_text(engine) + "<br>" + label + "<extra></extra>",
    }


#: Blow-ups of one panel closer in t than this fraction of the run share one label ("3 runs blew up at
#: t = 1.9–2 s"): several runs that blow up near the end would otherwise print their labels over each other.
BLOWUP_CLUSTER = 0.06


def place_blowup_labels(markers: list[dict[str, Any]], duration: float) -> None:
    """Label the blow-up markers of a figure so that no two labels overlap, in place.

    Per panel (y axis) and kind ("blew up" / "non-finite"), markers along t closer than BLOWUP_CLUSTER ×
    ``duration`` (s; the markers' own span when 0) to the first of their cluster share one label on that
    first marker, which names how many runs and over which t; every × keeps its own hover text. Successive
    labels take the next corner (BLOWUP_CORNERS), in dark text (a variant's own shade can be pale on white),
    not clipped at the axis (a label near the end of the run stays readable past it)."""
    span = duration or max((m["x"][0] for m in markers), default=0.0)
    gap = BLOWUP_CLUSTER * span
    clusters: list[list[dict[str, Any]]] = []
    def kind(marker: dict[str, Any]) -> str:  # "blew up at", "non-finite after"
        return str(marker["text"][0]).partition(" t = ")[0]

    for marker in sorted(markers, key=lambda m: (m["yaxis"], kind(m), m["x"][0])):
        last = clusters[-1] if clusters else None
        if (last is not None and last[0]["yaxis"] == marker["yaxis"] and kind(last[0]) == kind(marker)
                and marker["x"][0] - last[0]["x"][0] <= gap):
            last.append(marker)
        else:
            clusters.append([marker])
    seen: dict[str, int] = {}
    for cluster in sorted(clusters, key=lambda c: c[0]["x"][0]):  # along t, within each panel
        first = cluster[0]
        k = seen[first["yaxis"]] = seen.get(first["yaxis"], -1) + 1
        first["textposition"] = BLOWUP_CORNERS[k % len(BLOWUP_CORNERS)]
        first["textfont"] = {**first["textfont"], "color": "#333"}
        first["cliponaxis"] = False
        if len(cluster) > 1:
            low, high = first["x"][0], max(m["x"][0] for m in cluster)
            when = f"{low:.3g} s" if f"{low:.3g}" == f"{high:.3g}" else f"{low:.3g}–{high:.3g} s"
            first["text"] = [f"{len(cluster)} runs {kind(first)} t = {when}"]
            for other in cluster[1:]:
                other["mode"] = "markers"
                other["cliponaxis"] = False
                del other["text"], other["textposition"]


def time_series(scene: SceneResults, palette: Palette, ceilings: Ceilings, dt: float | None = None,
                named: set[str] | None = None, limit: int = MAX_POINTS, digits: int | None = None,
                muted_limit: int | None = None) -> Plot | None:
    """Position error, |energy drift| and constraint error against t at ``dt`` (s; default the chosen dt):
    three stacked panels; ``named`` (default: reports.emphasis.named_variants) in colour, the rest grey;
    each trace thinned to ``limit`` points (LTTB), a grey one's to ``muted_limit`` (default ``limit``), at
    ``digits`` significant digits (default DIGITS)."""
    dt = scene.chosen_dt if dt is None else dt
    chosen = _by_family(_chosen_cases(scene, dt), lambda c: c[1].engine)
    if not chosen:
        return None
    traces, markers = [], []
    duration = float(scene.scene.get("duration") or 0.0)
    panel_values: list[list[Any]] = [[] for _ in SERIES_PANELS]
    for index, sweep, record in chosen:
        series = record.series or {}
        colour = palette.colour(sweep.engine)
        points = limit if muted_limit is None or named is None or sweep.engine in named else muted_limit
        for panel, (key, _, absolute, ceiling_name) in enumerate(SERIES_PANELS):
            values = list(series.get(key) or [])
            if absolute:
                values = [None if v is None else abs(v) for v in values]
            ceiling = getattr(ceilings, ceiling_name)
            values, blew = clip(series["t"], values, ceiling)
            t, values = decimate(series["t"][:len(values)], values, limit=points)
            panel_values[panel].extend(values)
            axis = ("x", "y" if panel == 0 else f"y{panel + 1}")
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "meta": plot_text(sweep.engine), "legendgroup": f"v{index}", "showlegend": panel == 0,
                "x": _rounded(t, digits), "y": _rounded(values, digits), "line": {**palette.style(sweep.engine), "width": 1.5},
                "xaxis": axis[0], "yaxis": axis[1],
                "hovertemplate": "%{fullData.name}<br>t = %{x:.3g} s<br>%{y:.3g}<extra></extra>",
            })
            if blew is not None:
                markers.append(_blowup_marker(blew, ceiling, colour, axis, sweep.engine))
            elif record.status is Status.UNSTABLE and panel == 0:
                # Cut at its first non-finite state before passing the ceiling: mark where it stops.
                end = last_finite(series["t"], values, duration)
                if end is not None:
                    markers.append(_blowup_marker(end[0], end[1], colour, axis, sweep.engine,
                                                  "non-finite after t = {t:.3g} s"))
    # Three panels stacked on one shared time axis (plotly's low-level subplot layout).
    domains = ([0.70, 1.0], [0.36, 0.64], [0.0, 0.30])
    axes = {}
    for panel, (_, title, _, _) in enumerate(SERIES_PANELS):
        name = "yaxis" if panel == 0 else f"yaxis{panel + 1}"
        axes[name] = _axis(title, _axis_type(panel_values[panel]), domain=domains[panel])
    layout = _layout(len(chosen), height=720, xaxis=_axis("t / s", "linear", anchor="y3"), **axes)
    layout["legend"]["tracegroupgap"] = 0  # a group per variant (its three panels): no gap between them
    horizon = next((r.reference_horizon for _, _, r in chosen if r.reference_horizon is not None), None)
    if horizon is not None and horizon < duration:
        # Past the horizon the reference's own two solves disagree (chaos): errors there are not the engine's.
        layout["shapes"] = [{"type": "rect", "xref": "x", "yref": "paper", "x0": horizon, "x1": duration,
                             "y0": 0, "y1": 1, "fillcolor": "#888888", "opacity": 0.15, "line": {"width": 0},
                             "layer": "below"}]
    place_blowup_labels(markers, duration)
    figure = emphasise({"data": traces + markers, "layout": layout}, [t.get("meta") for t in traces + markers],
                       named_variants(scene) if named is None else named)
    caption = (f"Every variant at the dt of the scene's table (first {dt:.3g} s; the dt selector switches this plot "
               "with the table). A panel is logarithmic when its values span more "
               "than a decade; zeros (the start, an exact constraint) are not drawn on a log axis. A value past "
               f"{CLIP_FACTOR:g}× its bound is drawn at that ceiling and marked “blew up at t = …”.")
    if horizon is not None and horizon < duration:
        caption += (f" Shaded from t = {horizon:.3g} s: past the reference horizon, where the reference's own two "
                    "solves (its tolerance and one 100× tighter) part; the case's error metrics are taken before it.")
        reference = scene_reference(r for _, _, r in chosen) or {}
        caption += (f" As estimates with their intervals (docs/metrics.md): the horizon "
                    f"{estimate_text(horizon, reference.get('reference_horizon_interval'), 's', 3)}, the largest "
                    f"Lyapunov exponent {estimate_text(reference.get('lyapunov_exponent'), reference.get('lyapunov_interval'), '/s')}.")
    return Plot("ts", f"Time series at dt = {dt:.3g} s", caption, figure)


def _norms(forces: Sequence[Any], constraint: int) -> list[Any]:
    """‖F‖ (N) of one constraint over samples; None where a sample is missing."""
    out: list[Any] = []
    for sample in forces:
        f = None if sample is None or constraint >= len(sample) else sample[constraint]
        if f is None or any(c is None for c in f):
            out.append(None)
        else:
            out.append(math.sqrt(sum(c * c for c in f)))
    return out


#: Most particles whose paths are all drawn; a longer chain shows its first particle and its tip.
MAX_PATH_PARTICLES = 4
#: Most constraints given a panel of their own in the constraint-force plot.
MAX_FORCE_PANELS = 3


def _force_difference(forces: Sequence[Any], reference: Sequence[Any], n_constraints: int) -> list[Any]:
    """max over the first ``n_constraints`` constraints of ‖F_k − F_k^ref‖ (N) per sample; None where either is
    missing (a sample past the reference's, a non-finite force)."""
    out: list[Any] = []
    for k, sample in enumerate(forces):
        theirs = reference[k] if k < len(reference) else None
        worst: float | None = None
        for c in range(n_constraints):
            f = None if sample is None or c >= len(sample) else sample[c]
            r = None if theirs is None or c >= len(theirs) else theirs[c]
            if f is None or r is None or any(v is None for v in (*f, *r)):
                worst = None
                break
            d = math.sqrt(sum((a - b) ** 2 for a, b in zip(f, r)))
            worst = d if worst is None else max(worst, d)
        out.append(worst)
    return out


def constraint_forces(scene: SceneResults, palette: Palette, ceilings: Ceilings, thin: Thinning = Thinning()) -> Plot | None:
    """‖F‖ (N) of each constraint (up to MAX_FORCE_PANELS, stacked) against t at the chosen dt, over the reference's,
    and below them the largest difference from the reference's force, max_k ‖F_k − F_k^ref‖ (N, log axis when it
    spans decades): at a small dt the ‖F‖ lines lie on one another, their differences do not."""
    chosen = [c for c in _by_family(_chosen_cases(scene), lambda c: c[1].engine)
              if (c[2].series or {}).get("constraint_forces")]
    if not chosen:
        return None
    n_constraints = min(MAX_FORCE_PANELS, max(len(next((s for s in c[2].series["constraint_forces"] if s), []))
                                              for c in chosen))
    if n_constraints == 0:
        return None
    traces, markers, differences = [], [], []
    reference = next((c[2].series.get("reference_constraint_forces") for c in chosen
                      if c[2].series.get("reference_constraint_forces")), None)
    t_reference = next((c[2].series["t"] for c in chosen if c[2].series.get("reference_constraint_forces")), None)
    n_panels = n_constraints + (reference is not None)
    domains = [[k / n_panels + 0.04, (k + 1) / n_panels - 0.02] for k in reversed(range(n_panels))]
    for k in range(n_constraints):
        axis = ("x", "y" if k == 0 else f"y{k + 1}")
        if reference is not None and t_reference is not None:
            t, values = decimate(t_reference, _norms(reference, k), limit=thin.limit)
            traces.append({"type": "scatter", "mode": "lines", "name": "reference", "legendgroup": "reference",
                           "showlegend": k == 0, "x": _rounded(t, thin.digits), "y": _rounded(values, thin.digits),
                           "line": REFERENCE_STYLE,
                           "xaxis": axis[0], "yaxis": axis[1], "hoverinfo": "skip"})
        for index, sweep, record in chosen:
            values, blew = clip(record.series["t"], _norms(record.series["constraint_forces"], k), ceilings.force)
            t, values = decimate(record.series["t"][:len(values)], values, limit=thin.points(sweep.engine))
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": k == 0, "x": _rounded(t, thin.digits), "y": _rounded(values, thin.digits),
                "line": {**palette.style(sweep.engine), "width": 1.5}, "xaxis": axis[0], "yaxis": axis[1],
                "hovertemplate": f"%{{fullData.name}}<br>constraint {k}<br>t = %{{x:.3g}} s<br>‖F‖ = %{{y:.3g}} N<extra></extra>",
            })
            if blew is not None:
                markers.append(_blowup_marker(blew, ceilings.force, palette.colour(sweep.engine), axis, sweep.engine))
    if reference is not None:
        axis = ("x", f"y{n_panels}")
        # The stored forces keep 6 significant digits: a difference below 1e-5 of the largest force is not
        # resolved, and is drawn at that floor rather than as a gap (a zero on a log axis) or as round-off.
        floor = SERIES_RESOLUTION * max((v for k in range(n_constraints) for v in _norms(reference, k) if v), default=0.0)
        for index, sweep, record in chosen:
            own = record.series.get("reference_constraint_forces") or reference
            difference = [None if d is None else max(d, floor)
                          for d in _force_difference(record.series["constraint_forces"], own, n_constraints)]
            values, blew = clip(record.series["t"], difference, ceilings.force)
            t, values = decimate(record.series["t"][:len(values)], values, limit=thin.points(sweep.engine))
            differences.extend(values)
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": False, "x": _rounded(t, thin.digits), "y": _rounded(values, thin.digits),
                "line": {**palette.style(sweep.engine), "width": 1.5}, "xaxis": axis[0], "yaxis": axis[1],
                "hovertemplate": "%{fullData.name}<br>t = %{x:.3g} s<br>max ‖F − F<sup>ref</sup>‖ = %{y:.3g} N<extra></extra>",
            })
            if blew is not None:
                markers.append(_blowup_marker(blew, ceilings.force, palette.colour(sweep.engine), axis, sweep.engine))
    place_blowup_labels(markers, float(scene.scene.get("duration") or 0.0))
    axes = {("yaxis" if k == 0 else f"yaxis{k + 1}"): _axis(f"‖F{k}‖ / N", "linear", domain=domains[k])
            for k in range(n_constraints)}
    if reference is not None:
        axes[f"yaxis{n_panels}"] = _axis("max ‖F − F<sup>ref</sup>‖ / N", _axis_type(differences),
                                         domain=domains[n_panels - 1])
    layout = _layout(len(chosen) + 1, height=200 * n_panels + 120,
                     xaxis=_axis("t / s", "linear", anchor=f"y{n_panels}" if n_panels > 1 else "y"), **axes)
    layout["legend"]["tracegroupgap"] = 0  # a group per variant (its panels): no gap between them, no scrolling
    figure = {"data": traces + markers, "layout": layout}
    caption = (f"The magnitude of the force each constraint exerts on its (first) particle, at dt = "
               f"{scene.chosen_dt:.3g} s, over the reference's (wide grey line); only the variants whose engine "
               "reports constraint forces.")
    if reference is not None:
        caption += (" The lowest panel is each variant's largest difference from the reference's force over the "
                    "constraints, max ‖F − Fʳᵉᶠ‖ (N): where the lines above lie on one another, it tells them apart. "
                    f"It is taken from the stored forces (6 significant digits), which cannot resolve a difference "
                    f"below {SERIES_RESOLUTION:g} of the largest reference force: such a difference is drawn at that "
                    f"floor, {floor:.2g} N (the case's constraint-force error, in the table, is exact).")
    return Plot("force", "Constraint forces", caption, figure)


def _pendulum_pin(scene: SceneResults) -> dict[str, Any] | None:
    """The scene's first pin (a pendulum's pivot), or None when it has none."""
    return next((c for c in scene.scene.get("constraints", []) if c.get("kind") == "pin"), None)


def phase_curve(t: Sequence[float], positions: Sequence[Any], velocities: Sequence[Any] | None,
                particle: int, anchor: Sequence[float], planar: bool) -> tuple[list[Any], list[Any]]:
    """(θ rad, ω rad/s) of ``particle`` about ``anchor``: θ from the downward vertical (signed in the x–z
    plane for a planar scene, the polar angle otherwise); ω from the velocities, or by central differences of
    θ over the samples when they are not stored."""
    thetas: list[Any] = []
    omegas: list[Any] = []
    for k, sample in enumerate(positions):
        p = None if sample is None or particle >= len(sample) else sample[particle]
        if p is None or any(c is None for c in p):
            thetas.append(None)
            omegas.append(None)
            continue
        rx, ry, rz = (p[i] - anchor[i] for i in range(3))
        horizontal = rx if planar else math.hypot(rx, ry)
        thetas.append(math.atan2(horizontal, -rz))
        v = None
        if velocities is not None and k < len(velocities) and velocities[k] is not None:
            v = velocities[k][particle]
        if v is not None and all(c is not None for c in v):
            r2 = rx * rx + rz * rz if planar else rx * rx + ry * ry + rz * rz
            if planar:
                omegas.append((rx * v[2] - rz * v[0]) / r2 if r2 else None)
            else:
                # Rate of the polar angle: d/dt atan2(ρ, −z) with ρ = √(x² + y²).
                rho = math.hypot(rx, ry)
                rho_dot = (rx * v[0] + ry * v[1]) / rho if rho else 0.0
                omegas.append((-rz * rho_dot + rho * v[2]) / r2 if r2 else None)
        else:
            omegas.append(None)
    if velocities is None:
        omegas = []
        for k in range(len(thetas)):
            a, b = max(k - 1, 0), min(k + 1, len(thetas) - 1)
            if thetas[a] is None or thetas[b] is None or t[b] == t[a]:
                omegas.append(None)
            else:
                d = thetas[b] - thetas[a]
                d = (d + math.pi) % (2 * math.pi) - math.pi  # across the ±π seam
                omegas.append(d / (t[b] - t[a]))
    return thetas, omegas


def _thin(xs: list[Any], ys: list[Any], limit: int = MAX_POINTS) -> tuple[list[Any], list[Any]]:
    """Every k-th point of a curve that is not a function of x (a phase curve, a path), at most ``limit`` of them
    and always the last (where a run ends)."""
    step = max(1, math.ceil(len(xs) / limit))
    if step == 1:
        return xs, ys
    keep = list(range(0, len(xs), step))
    if keep[-1] != len(xs) - 1:
        keep.append(len(xs) - 1)
    return [xs[k] for k in keep], [ys[k] for k in keep]


def phase_plot(scene: SceneResults, palette: Palette, thin: Thinning = Thinning()) -> Plot | None:
    """Angle against angular velocity of the first pinned particle (pendulum scenes), every variant and the reference."""
    pin = _pendulum_pin(scene)
    chosen = [c for c in _by_family(_chosen_cases(scene), lambda c: c[1].engine) if (c[2].series or {}).get("positions")]
    if pin is None or not chosen:
        return None
    particle, anchor = pin["particle"], pin["anchor"]
    planar = all(abs(p["position"][1]) < 1e-12 and abs(p["velocity"][1]) < 1e-12
                 for p in scene.scene.get("particles", []))
    traces = []
    first = chosen[0][2].series
    if first.get("reference_positions"):
        theta, omega = phase_curve(first["t"], first["reference_positions"], first.get("reference_velocities"),
                                   particle, anchor, planar)
        theta, omega = _thin(theta, omega, thin.limit)
        traces.append({"type": "scatter", "mode": "lines", "name": "reference", "legendgroup": "reference",
                       "x": _rounded(theta, thin.digits), "y": _rounded(omega, thin.digits), "line": REFERENCE_STYLE, "hoverinfo": "skip"})
    titled: set[str] = set()
    for _index, sweep, record in chosen:
        series = record.series
        theta, omega = _thin(*phase_curve(series["t"], series["positions"], series.get("velocities"), particle, anchor,
                                          planar), thin.points(sweep.engine))
        traces.append(_group({
            "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
            "x": _rounded(theta, thin.digits), "y": _rounded(omega, thin.digits),
            "line": {**palette.style(sweep.engine), "width": 1.5},
            "hovertemplate": "%{fullData.name}<br>θ = %{x:.3g} rad<br>ω = %{y:.3g} rad/s<extra></extra>",
        }, sweep.engine, titled))
    how = "from the stored velocities" if first.get("velocities") else "by differences of θ between samples"
    figure = {"data": traces, "layout": _layout(len(traces) + len(titled), height=480,
                                                xaxis=_axis("θ / rad", "linear"), yaxis=_axis("ω / (rad/s)", "linear"))}
    kind = "signed, in the x–z plane" if planar else "the polar angle"
    caption = (f"Particle {particle} about its pivot at dt = {scene.chosen_dt:.3g} s: θ from the downward vertical "
               f"({kind}) against ω ({how}). A closed curve is a conserved swing; a spiral in or out is energy lost "
               "or gained.")
    return Plot("phase", "Phase plot (angle, angular velocity)", caption, figure)


def _reference_positions(scene: SceneResults) -> tuple[list[Any] | None, str]:
    """Reference particle positions to draw under the paths, and where they came from.

    Taken from the records' stored reference positions when the results have
    them, else from the reference engine's own case (at the chosen dt, or any).
    """
    for _, _, record in _chosen_cases(scene):
        if (stored := (record.series or {}).get("reference_positions")):
            return stored, "the reference solution"
    for sweep in (s for s in scene.sweeps if s.is_reference):
        for record in sorted(sweep.records, key=lambda r: r.case.dt != scene.chosen_dt):
            if record.status is Status.OK and (stored := (record.series or {}).get("positions")):
                return stored, f"{sweep.engine} at dt = {record.case.dt:.3g} s"
    return None, ""


def _particle_xz(positions: list[Any], particle: int) -> tuple[list[Any], list[Any]]:
    xs = [None if p is None or p[particle] is None else p[particle][0] for p in positions]
    zs = [None if p is None or p[particle] is None else p[particle][2] for p in positions]
    return xs, zs


def _clip_path(xs: list[Any], zs: list[Any], box: float) -> tuple[list[Any], list[Any]]:
    """A path cut where it leaves ±``box`` m (a blow-up), so the axes keep to the scene."""
    out_x: list[Any] = []
    out_z: list[Any] = []
    for x, z in zip(xs, zs):
        if x is None or z is None or abs(x) > box or abs(z) > box:
            out_x.append(None)
            out_z.append(None)
        else:
            out_x.append(x)
            out_z.append(z)
    return out_x, out_z


def paths(scene: SceneResults, palette: Palette, thin: Thinning = Thinning()) -> Plot | None:
    """Particle paths in the x–z plane at the chosen dt, drawn over the reference's (wide grey line), and below
    them each variant's position error against t (m, the stored series: max over particles of ‖p − pʳᵉᶠ‖ at full
    precision, where positions are stored to 6 digits): where the paths lie on one another (a small dt), the
    errors tell the variants apart."""
    chosen = [c for c in _by_family(_chosen_cases(scene), lambda c: c[1].engine) if (c[2].series or {}).get("positions")]
    if not chosen:
        return None
    n_particles = len(scene.scene.get("particles", [])) or len(chosen[0][2].series["positions"][0])
    # A chain's every link would be hundreds of traces: its first particle and its tip tell the story.
    drawn = list(range(n_particles)) if n_particles <= MAX_PATH_PARTICLES else [0, n_particles - 1]
    box = CLIP_FACTOR * scene.length
    traces, apart = [], []
    distances: list[Any] = []
    reference, source = _reference_positions(scene)
    if reference:
        for particle in drawn:
            xs, zs = _thin(*_particle_xz(reference, particle), thin.limit)
            traces.append({
                "type": "scatter", "mode": "lines", "name": "reference", "legendgroup": "reference",
                "showlegend": particle == drawn[0], "x": _rounded(xs, thin.digits), "y": _rounded(zs, thin.digits), "line": REFERENCE_STYLE,
                "hoverinfo": "skip",
            })
    for index, sweep, record in chosen:
        for particle in drawn:
            xs, zs = _thin(*_clip_path(*_particle_xz(record.series["positions"], particle), box), thin.points(sweep.engine))
            traces.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": particle == drawn[0],
                "x": _rounded(xs, thin.digits), "y": _rounded(zs, thin.digits), "line": {**palette.style(sweep.engine), "width": 1.5},
                "hovertemplate": f"%{{fullData.name}}<br>particle {particle}<br>x = %{{x:.3g}} m<br>z = %{{y:.3g}} m<extra></extra>",
            })
        if record.series.get("position_error"):
            values, _ = clip(record.series["t"], list(record.series["position_error"]), box)
            t, values = decimate(record.series["t"][:len(values)], values, limit=thin.points(sweep.engine))
            distances.extend(values)
            apart.append({
                "type": "scatter", "mode": "lines", "name": plot_text(_label(sweep, record)),
                "legendgroup": f"v{index}", "showlegend": False, "x": _rounded(t, thin.digits),
                "y": _rounded(values, thin.digits),
                "line": {**palette.style(sweep.engine), "width": 1.5}, "xaxis": "x2", "yaxis": "y2",
                "hovertemplate": "%{fullData.name}<br>t = %{x:.3g} s<br>position error = %{y:.3g} m<extra></extra>",
            })
    # Equal scales, so a circle of the wire looks like a circle.
    axes: dict[str, Any] = {"xaxis": _axis("x / m", "linear", zeroline=False),
                            "yaxis": _axis("z / m", "linear", zeroline=False, scaleanchor="x", scaleratio=1)}
    if apart:
        axes["yaxis"]["domain"] = [0.36, 1.0]
        axes["xaxis2"] = _axis("t / s", "linear", anchor="y2")
        axes["yaxis2"] = _axis("position error / m", _axis_type(distances), domain=[0.0, 0.24], anchor="x2")
    layout = _layout(len(chosen) + bool(reference), height=800 if apart else 560, **axes)
    layout["legend"]["tracegroupgap"] = 0  # a group per variant (its particles, its distance): no gap, no scrolling
    figure = {"data": traces + apart, "layout": layout}
    under = f"the wide grey line is {source}" if reference else "no reference path is stored in these results"
    which = "Every particle" if len(drawn) == n_particles else f"The first and the last of the {n_particles} particles"
    caption = (f"{which} of every variant at dt = {scene.chosen_dt:.3g} s in the x–z plane; {under}. "
               f"A path is cut where it leaves ±{box:.3g} m (a blow-up). Click a legend entry to hide a variant.")
    if apart:
        caption += (" Below: each variant's position error against t, max over particles of ‖p − pʳᵉᶠ‖ (m; "
                    "logarithmic when it spans decades): where the paths lie on one another, it tells them apart.")
    return Plot("path", "Particle paths (x–z plane)", caption, figure)


def scene_plots(scene: SceneResults, number: int, palette: Palette | None = None,
                ceilings: Ceilings | None = None, named: set[str] | None = None) -> list[Plot]:
    """Every plot of ``scene`` that has something to draw, in page order.

    number : the scene's position on the page; DOM ids are built from it
    (``s0-wp``), never from the scene id, which comes from a file.
    ceilings : where blow-ups are clipped (default: CLIP_FACTOR × L, 1 E*, 0.1 L).
    named : the variants in colour (default: those the scene's verdict names, reports.emphasis).
    """
    palette = palette or Palette(s.engine for s in scene.sweeps)
    ceilings = ceilings or Ceilings.for_scene(scene.length, 1.0, 0.1)
    named = named_variants(scene) if named is None else named
    built = (work_precision(scene, palette), error_vs_dt(scene, palette), time_series(scene, palette, ceilings, named=named),
             constraint_forces(scene, palette, ceilings), phase_plot(scene, palette), paths(scene, palette))
    for plot in built:
        if plot is not None and plot.id in EMPHASISED:
            emphasise(plot.figure, [trace.get("meta") for trace in plot.figure["data"]], named)
    return [replace(plot, id=f"s{number}-{plot.id}") for plot in built if plot is not None]


#: Plots that overlay every variant across the sweep: the verdict's variants in colour, the rest grey
#: (reports.emphasis; time_series does the same itself, at every dt).
EMPHASISED = ("wp", "dt")
