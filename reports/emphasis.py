"""Which variants a plot draws in colour: the Pareto front and each family's best, the rest grey until asked.

At 30 variants and more every line in colour is a tangle. By default a
plot colours the variants the verdict names (compare.results.verdict: those
with a run on the Pareto front, each family's cheapest to reach 1e-6·L and
the variants tied with it) and draws the others thin and grey; one click on
"all variants in colour" (a plotly button) gives every trace its colour, and
"the verdict's in colour" goes back. A legend click still hides one variant.
"""

from __future__ import annotations

from typing import Any, Iterable

from compare.results.verdict import SceneVerdict, scene_verdicts

from reports.load import SceneResults
from reports.palette import GREY

#: Line width of a variant the verdict does not name (its colour: reports.palette.GREY).
GREY_WIDTH = 1.0


def named_variants(scene: SceneResults) -> set[str]:
    """Labels of the variants the verdict names for ``scene`` (front, family winners and their ties); the report
    computes each scene's verdict once and calls :func:`named_by` with it."""
    return named_by(scene_verdicts(scene.sweeps)[0]) if scene.sweeps else set()


def named_by(verdict: SceneVerdict) -> set[str]:
    """Labels of the variants ``verdict`` names: those with a run on the front, family winners and their ties."""
    named = {p.engine for p in verdict.front}
    for winner in verdict.winners:
        named.add(winner.reach.engine)
        named.update(winner.ties)
    return named


def emphasise(figure: dict[str, Any], engines: Iterable[str | None], named: set[str]) -> dict[str, Any]:
    """Grey out the traces of ``figure`` whose variant (``engines``, one per trace; None: leave it) is not in
    ``named``, and add the two buttons that switch every variant's colour on and back off.

    Only when some trace would be greyed and some kept: a plot of a few variants stays as it is.
    """
    traces = figure["data"]
    engines = list(engines)
    grey = [engine is not None and engine not in named for engine in engines]
    if not any(grey) or all(grey[k] or engines[k] is None for k in range(len(traces))):
        return figure
    coloured: dict[str, list[Any]] = {"line.color": [], "marker.color": [], "line.width": [], "opacity": []}
    muted: dict[str, list[Any]] = {key: [] for key in coloured}
    for trace, off in zip(traces, grey):
        line, marker = trace.get("line") or {}, trace.get("marker") or {}
        own = {"line.color": line.get("color"), "marker.color": marker.get("color", line.get("color")),
               "line.width": line.get("width", 2), "opacity": trace.get("opacity", 1)}
        dull = {"line.color": GREY, "marker.color": GREY, "line.width": GREY_WIDTH, "opacity": 0.7} if off else own
        for key in coloured:
            coloured[key].append(own[key])
            muted[key].append(dull[key])
        if off:
            trace["line"] = {**line, "color": GREY, "width": GREY_WIDTH}
            if "marker" in trace:
                trace["marker"] = {**marker, "color": GREY}
            trace["opacity"] = 0.7
    figure["layout"]["updatemenus"] = [{
        "type": "buttons", "direction": "right", "x": 0, "xanchor": "left", "y": 1.0, "yanchor": "bottom",
        "pad": {"t": 2, "b": 2}, "showactive": True, "active": 0,
        "buttons": [
            {"label": "the verdict's variants in colour", "method": "restyle", "args": [muted]},
            {"label": "all variants in colour", "method": "restyle", "args": [coloured]},
        ],
    }]
    figure["layout"].setdefault("margin", {})["t"] = max(figure["layout"].get("margin", {}).get("t", 30), 44)
    return figure
