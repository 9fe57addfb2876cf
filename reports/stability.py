"""Report sections for ``xval stability`` output: the largest-stable-dt table and bar chart, the gain-map heat maps.

Shown only when the results directory holds ``stability.json`` and/or
``gainmap.json`` (:mod:`compare.stability.search`, :mod:`compare.stability.gainmap`). Figures
are plotly.js specs like :mod:`reports.figures`; their ``n_traces`` counts
only scatter traces, the ones the page's drawing check finds in the DOM
(bars, heat maps and contours are drawn in other layers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from compare.stability.gainmap import load_gainmap
from compare.stability.search import BOUNDED, SKIPPED, STABLE_AT_LARGEST, UNDECIDED, UNSTABLE_AT_SMALLEST, load_stability

from reports.figures import Plot, _axis, _layout, plot_text
from reports.palette import FAMILY_COLOURS as PALETTE  # one colour per scene here (not per engine)


@dataclass(frozen=True)
class ExtraPlot(Plot):
    """A plot of these sections; it counts only its scatter traces, because bars, heat maps and
    contours are drawn in other plotly layers than the ones the browser test counts."""

    @property
    def n_traces(self) -> int:
        return sum(1 for trace in self.figure["data"] if trace.get("type", "scatter") == "scatter")


# -- stability search -----------------------------------------------------------------------


def _cell(result: dict[str, Any]) -> dict[str, str]:
    """Table cell of one pair: text, CSS status class, hover title."""
    verdict = result["verdict"]
    theory = result.get("analytic_dt")
    note = f"; theory {theory:.3g} s" if theory else ""
    if verdict == BOUNDED:
        return {"text": f"{result['largest_stable_dt']:.3g}", "status": "ok",
                "title": f"stable at {result['largest_stable_dt']:.4g} s, unstable at "
                         f"{result['smallest_unstable_dt']:.4g} s{note}; {result.get('reason', '')}"}
    if verdict == STABLE_AT_LARGEST:
        return {"text": f"≥ {result['largest_stable_dt']:.3g}", "status": "ok",
                "title": f"stable at the largest dt tried{note}"}
    if verdict == UNSTABLE_AT_SMALLEST:
        return {"text": f"< {result['smallest_unstable_dt']:.3g}", "status": "unstable",
                "title": f"unstable even at the smallest dt tried{note}; {result.get('reason', '')}"}
    if verdict == UNDECIDED:
        return {"text": "undecided", "status": "timeout",
                "title": f"a trial at {result.get('undecided_dt') or 0:.4g} s timed out twice: the boundary is "
                         f"{_bracket(result)}{note}; {result.get('reason', '')}"}
    return {"text": "skipped", "status": "skipped", "title": result.get("reason", "")}


def _bracket(result: dict[str, Any]) -> str:
    """Where an undecided pair's boundary lies, as far as its decided trials say."""
    lo, hi = result.get("largest_stable_dt"), result.get("smallest_unstable_dt")
    if lo is not None and hi is not None:
        return f"between {lo:.3g} and {hi:.3g} s"
    if lo is not None:
        return f"at or above {lo:.3g} s"
    return f"below {hi:.3g} s" if hi is not None else "unknown"


def _by_pair(document: dict[str, Any]) -> dict[tuple[str, str], dict[str, Any]]:
    """The search's results keyed by (scene id, engine label); a pair not searched (yet) is absent."""
    return {(r["scene_id"], r["engine"]): r for r in document.get("results", [])}


def stability_table(document: dict[str, Any]) -> dict[str, Any]:
    """Rows = engine variants, columns = scenes, cells = largest stable dt (s)."""
    scenes = list(document.get("scenes") or {})
    by_pair = _by_pair(document)
    rows = []
    for engine in document.get("engines", []):
        cells = [(_cell(by_pair[(s, engine)]) if (s, engine) in by_pair else
                  {"text": "–", "status": "", "title": "not searched (yet)"}) for s in scenes]
        theory = next((by_pair[(s, engine)].get("analytic_dt") for s in scenes if (s, engine) in by_pair), None)
        rows.append({"engine": engine, "cells": cells, "theory": theory})
    unstable = [(r["scene_id"], r["engine"]) for r in document.get("results", []) if r["verdict"] == UNSTABLE_AT_SMALLEST]
    return {"scenes": scenes, "rows": rows, "unstable": unstable}


def stability_bars(document: dict[str, Any]) -> ExtraPlot | None:
    """Largest stable dt (s, log axis) per engine variant, one bar colour per scene.

    A variant unstable even at the smallest dt gets a cross-hatched bar at half that dt;
    one stable at the largest dt tried, a striped bar at that dt (the true limit is higher).
    """
    settings = document.get("settings") or {}
    dt_min, dt_max = settings.get("dt_min"), settings.get("dt_max")
    engines = document.get("engines", [])
    by_pair = _by_pair(document)
    traces = []
    for index, scene in enumerate(document.get("scenes") or {}):
        ys, patterns, hover = [], [], []
        for engine in engines:
            result = by_pair.get((scene, engine)) or {}
            verdict = result.get("verdict")
            if verdict == BOUNDED:
                y, pattern, text = result["largest_stable_dt"], "", "largest stable dt"
            elif verdict == STABLE_AT_LARGEST:
                y, pattern, text = result["largest_stable_dt"], "/", "stable at the largest dt tried"
            elif verdict == UNSTABLE_AT_SMALLEST and dt_min:
                y, pattern, text = dt_min / 2, "x", f"UNSTABLE even at {dt_min:g} s"
            elif verdict == UNDECIDED:
                y, pattern, text = result.get("largest_stable_dt"), ".", f"undecided: {_bracket(result)}"
            else:
                y, pattern, text = None, "", "skipped" if verdict == SKIPPED else "not searched"
            ys.append(y)
            patterns.append(pattern)
            hover.append(text)
        traces.append({
            "type": "bar", "name": plot_text(scene), "x": [plot_text(e) for e in engines], "y": ys,
            "marker": {"color": PALETTE[index % len(PALETTE)], "pattern": {"shape": patterns}},
            "customdata": hover,
            "hovertemplate": "%{x}<br>" + plot_text(scene) + ": %{y:.3g} s<br>%{customdata}<extra></extra>",
        })
    if not traces:
        return None
    low = math.log10(dt_min / 4) if dt_min else None
    high = math.log10(dt_max * 1.5) if dt_max else None
    yaxis = _axis("largest stable dt / s")
    if low is not None and high is not None:
        yaxis["range"] = [low, high]
    figure = {"data": traces, "layout": _layout(len(traces), height=520, barmode="group",
                                                xaxis={"tickangle": -45, "automargin": True}, yaxis=yaxis)}
    caption = (f"Per engine variant and scene, the largest time step found stable (searched from {dt_max:g} s "
               f"down to {dt_min:g} s, to 10 %). Cross-hatched bars at half the smallest dt mark variants unstable "
               f"even there; striped bars were stable at the largest dt tried, so their limit is higher.")
    return ExtraPlot("stability-bars", "Largest stable dt", caption, figure)


# -- gain map ------------------------------------------------------------------------------------


def _log10(value: Any) -> float | None:
    """log10 of a positive finite value to 3 decimals (a colour needs no more), else None."""
    return round(math.log10(value), 3) if isinstance(value, (int, float)) and value > 0 and math.isfinite(value) else None


#: Most grid lines per axis of a theory boundary drawn as a contour: the zero line of a smooth ρ − 1 needs
#: no finer grid, and 121 × 121 full-precision values in each of a map's three panels were most of a report.
THEORY_GRID = 61


def _thinned_theory(theory: dict[str, Any]) -> tuple[list[Any], list[Any], list[list[Any]]]:
    """(log10 x, log10 y, log10 ρ) of a theory grid, every k-th line so that at most THEORY_GRID remain, 4 digits."""
    xs, ys, z = theory["log10_x"], theory["log10_y"], theory["log10_rho"]
    kx = max(1, math.ceil(len(xs) / THEORY_GRID))
    ky = max(1, math.ceil(len(ys) / THEORY_GRID))

    def r(v: Any) -> Any:
        return None if v is None else float(f"{v:.4g}")

    return ([r(v) for v in xs[::kx]], [r(v) for v in ys[::ky]], [[r(v) for v in row[::kx]] for row in z[::ky]])


def gain_heatmaps(document: dict[str, Any]) -> list[ExtraPlot]:
    """Per engine variant: stability, log10 constraint error and log10 energy drift over log10 x × log10 y
    (the two swept options), with the engine's own theory boundary (spectral radius ρ = 1) where it has one."""
    x_name, y_name = document["x"], document["y"]
    xs = [math.log10(v) for v in document["x_values"]]
    ys = [math.log10(v) for v in document["y_values"]]
    dt = document["dt"]
    plots = []
    for number, (engine, grid) in enumerate(document["maps"].items()):
        theory = grid.get("theory")
        layers = []
        if theory is not None:
            layers.append({
                "type": "contour", **dict(zip(("x", "y", "z"), _thinned_theory(theory))),
                "contours": {"start": 0, "end": 0, "size": 1, "coloring": "lines"}, "showscale": False,
                "line": {"color": "black", "width": 3}, "colorscale": [[0, "black"], [1, "black"]],
                "name": "theory: ρ = 1", "showlegend": True, "hoverinfo": "skip",
            })
        # A cell that timed out twice decides nothing: blank, like one not run (compare.stability.trial.timed_retry).
        stable = [[None if s in (None, "timeout") else (1 if s == "ok" else 0) for s in row] for row in grid["status"]]
        panels = [
            ("stability", stable, [[0, "#f4a582"], [0.5, "#f4a582"], [0.5, "#92c5de"], [1, "#92c5de"]],
             "measured: blue = ok, orange = unstable, blank = undecided (timed out twice)", {"zmin": 0, "zmax": 1, "showscale": False}),
            ("constraint error", [[_log10(v) for v in row] for row in grid["constraint_error"]], "Viridis",
             "log10 constraint error / m", {}),
            ("energy drift", [[_log10(v) for v in row] for row in grid["energy_drift"]], "Viridis",
             "log10 energy drift / E*", {}),
        ]
        theory_text = (
            "Black line: the engine's own linear stability theory (stable inside, where the spectral radius of "
            "its linearized one-step matrix is ≤ 1). " if theory is not None else "The engine states no theory. "
        )
        for kind, z, colorscale, label, extra in panels:
            heat = {"type": "heatmap", "x": xs, "y": ys, "z": z, "colorscale": colorscale,
                    "colorbar": {"title": {"text": label}}, "name": label,
                    "hovertemplate": f"log10 {x_name} = %{{x:.2f}}<br>log10 {y_name} = %{{y:.2f}}<br>"
                                     + label + ": %{z:.3g}<extra></extra>",
                    **extra}
            figure = {"data": [heat, *layers], "layout": _layout(
                1, height=460,
                xaxis={"title": {"text": f"log10 {x_name}"}}, yaxis={"title": {"text": f"log10 {y_name}"}},
                legend={"orientation": "h", "y": 1.08})}
            slug = kind.replace(" ", "-")
            plots.append(ExtraPlot(
                f"gainmap-{number}-{slug}", f"{engine}: {kind}",
                f"{engine} on {document['scene_id']} at dt = {dt:g} s over {x_name} × {y_name}. {theory_text}"
                f"{'Blue cells stayed within the bounds, orange ones did not.' if kind == 'stability' else 'Blank cells had no finite value (the run blew up).'}",
                figure))
    return plots


def stability_context(directory: str | Path) -> dict[str, Any] | None:
    """What the template's stability and gain-map sections need, or None when ``directory`` has neither file."""
    stability = load_stability(directory)
    gainmap = load_gainmap(directory)
    if stability is None and gainmap is None:
        return None
    context: dict[str, Any] = {"search": None, "gainmap": None, "plots": []}
    if stability is not None:
        bars = stability_bars(stability)
        context["search"] = {"document": stability, "table": stability_table(stability), "bars": bars}
        if bars is not None:
            context["plots"].append(bars)
    if gainmap is not None:
        heatmaps = gain_heatmaps(gainmap)
        context["gainmap"] = {"document": gainmap, "plots": heatmaps}
        context["plots"].extend(heatmaps)
    return context
