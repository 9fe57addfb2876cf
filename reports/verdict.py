"""The report's first section: per scene, the answer before the tables.

Per scene, from :mod:`compare.results.verdict`: the Pareto front of error against cost, the cost to
reach the tolerance, the focus family against the best other, the stability heat map and the problems.

Details: docs/report.md, "Module notes", ``reports/verdict.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from compare.results.sweep import VariantSweep
from compare.results.verdict import (
    SEVERITIES, Problem, Reach, SceneVerdict, default_focus, families, family, lower_envelope, points, scene_verdicts,
)

import numpy as np
from markupsafe import Markup

from compare.stability.dissipation import load_probe_files
from reports.emphasis import named_by
from reports.load import ReportData, SceneResults
from reports.numbers import si
from reports.palette import Palette
from reports.figures import sweep_points
from reports.svgplot import Series, key_svg, loglog_svg

#: Text of a heat-map cell per status.
#: Text of a heat-map cell per status (no glyph that needs an emoji font: "T" for a timeout).
STATUS_MARK = {"ok": "✓", "unstable": "↑", "failed": "✗", "timeout": "T", "skipped": "–"}


def row_id(scene: int, variant: int, dt: int) -> str:
    """DOM id of a variant's row in a scene's table at the scene's ``dt``-th time step."""
    return f"s{scene}-d{dt}-v{variant}"


@dataclass(frozen=True)
class HeatCell:
    """One case in the heat map: its status, the mark shown, and the link to its row ("" when it did not run)."""

    status: str
    mark: str
    href: str


@dataclass(frozen=True)
class HeatRow:
    engine: str
    family: str
    colour: str
    cells: list[HeatCell]


@dataclass(frozen=True)
class ProblemItem:
    """One problem as the page lists it: kind, variant, text, the link to its evidence (a case row, or the plot
    that shows it with ``engine`` highlighted), its rank in SEVERITIES, and for a blow-up the time series at
    its largest unstable dt ("" otherwise)."""

    kind: str
    engine: str
    text: str
    href: str
    severity: int = 2
    blowup: str = ""
    plateau: float | None = None
    worst_link: str = ""  # on a model scene: which link errs most at the variant's finest ok dt, and by how much

    @property
    def severity_name(self) -> str:
        return SEVERITIES[self.severity]


@dataclass(frozen=True)
class ReachRow:
    engine: str
    family: str
    colour: str
    reach: Reach
    focus: bool

    @property
    def sort_value(self) -> float:
        return self.reach.cost if self.reach.cost is not None else float("inf")


@dataclass(frozen=True)
class SceneVerdictView:
    """One scene's verdict as the template lays it out."""

    number: int
    scene_id: str
    verdict: SceneVerdict
    sentence: str
    pareto: ParetoPlot | None
    reaches: list[ReachRow]
    dts: list[float]
    heat: list[HeatRow]
    problems: list[ProblemItem] = field(default_factory=list)
    named: set[str] = field(default_factory=set)  # the variants the verdict names (plots colour only these)


@dataclass(frozen=True)
class LegendEntry:
    """One variant in the verdict plots' legend: its series index in both SVGs, label, colour, whether it is
    muted (grey until "all variants in colour"), its key (line style and marker, as drawn) and its observed
    order ("3.98", or "–" when none could be fitted)."""

    index: int
    engine: str
    colour: str
    muted: bool = False
    key: Markup = Markup("")
    order: str = "–"


@dataclass(frozen=True)
class ParetoPlot:
    """The verdict's plots: the work–precision diagram (inline SVG), error against dt beside it (same series,
    same y axis; "" when no variant has a dt sweep) and their one legend, grouped by engine family."""

    svg: Markup
    legend: list[tuple[str, list[LegendEntry]]]
    dt_svg: Markup = Markup("")

    @property
    def muted(self) -> bool:
        """Whether some variants are grey (the page then offers "all variants in colour")."""
        return any(entry.muted for _, entries in self.legend for entry in entries)


def _order_text(sweep: VariantSweep) -> str:
    """The observed order of ``sweep`` (the slope of log error against log dt over its asymptotic range)."""
    fit = sweep.order
    return "–" if fit is None or fit.order is None else f"{fit.order:.2f}"


#: Size (px of the viewBox) of each verdict plot; two side by side with their legend fit a 1400-px screen.
VERDICT_PLOT = (500, 400)


def pareto_plot(scene: SceneResults, number: int, verdict: SceneVerdict, palette: Palette,
                named: set[str] | None = None) -> ParetoPlot | None:
    """The verdict's two plots of every competing variant, None when neither has a point: error against cost
    (every ok run, each variant's runs joined in dt order, the Pareto front) and error against dt (each
    variant's observed order in the legend), one shared legend.

    named : the variants in colour (default: every one); the others grey, as the plotly plots mute theirs,
    unless that would grey all or none. A variant that converges to the wrong answer is in colour too, and
    named on the dt plot: its plateau is the evidence.
    """
    competing = {r.engine for r in verdict.reaches}
    sweeps = [s for s in scene.sweeps if s.engine in competing]
    drawn = [s.engine for s in sweeps if points(s)]
    mute = named is not None and any(e in named for e in drawn) and any(e not in named for e in drawn)
    wrong = {p.engine for p in verdict.problems if p.kind == "inconsistent"}
    order: dict[str, int] = {}
    for sweep in sweeps:
        order.setdefault(family(sweep.engine), len(order))
    sweeps.sort(key=lambda s: order[family(s.engine)])  # a family's variants together
    on_front = {p.case_id: p.margin for p in verdict.front}
    series: list[Series] = []
    by_dt: list[Series] = []
    groups: dict[str, list[LegendEntry]] = {}
    for sweep in sweeps:
        pts = points(sweep)
        dts, errors, _ = sweep_points(sweep, "dt")
        if not pts and not dts:
            continue
        colour = palette.colour(sweep.engine)
        symbol, dash = palette.symbol(sweep.engine), palette.style(sweep.engine)["dash"]
        muted = mute and sweep.engine not in named and sweep.engine not in wrong  # type: ignore[operator]
        series.append(Series(sweep.engine, colour, family(sweep.engine), [
            (p.cost, p.error, f"{p.engine}: dt {p.dt:.3g} s, error {p.error:.3g} m, cost {p.cost:.3g} s/s"
             + _front_text(on_front, p.case_id)) for p in pts], muted, symbol, dash))
        by_dt.append(Series(sweep.engine, colour, family(sweep.engine), [
            (dt, error, f"{sweep.engine}: dt {dt:.3g} s, error {error:.3g} m")
            for dt, error in zip(dts, errors)], muted, symbol, dash))
        groups.setdefault(family(sweep.engine), []).append(LegendEntry(
            len(series) - 1, sweep.engine, colour, muted, key_svg(symbol, dash, colour, muted), _order_text(sweep)))
    if not any(s.points for s in series) and not any(s.points for s in by_dt):
        return None
    errors = [y for s in series + by_dt for _, y, _ in s.points]
    width, height = VERDICT_PLOT
    svg = loglog_svg(series, [(p.cost, p.error) for p in lower_envelope(verdict.front)],
                     x_title="stepping cost per simulated second / (s/s)", y_title="max position error / m",
                     target=verdict.target, target_label="1e-6·L", element_id=f"pareto-{number}",
                     width=width, height=height, y_extent=errors,
                     picks=[(b.reading.budget, b.reading.error, b.reading.engine) for b in verdict.best
                            if b.reading is not None],
                     label=f"Scene {scene.scene_id}: max position error against stepping cost, log–log, every ok run "
                           f"of {len(series)} variants, the Pareto front as a staircase and the target 1e-6·L "
                           f"as a dotted line")
    picked = {b.reading.engine for b in verdict.best if b.reading is not None}
    # Each family's pick and each wrong answer named at its finest dt (where a plateau shows).
    labels = [(*min(s.points)[:2], f"{s.name}: wrong answer" if s.name in wrong else s.name)
              for s in by_dt if s.points and (s.name in wrong or s.name in picked)]
    dt_svg = loglog_svg(by_dt, [], x_title="time step dt / s", y_title="max position error / m",
                        target=verdict.target, target_label="1e-6·L", element_id=f"dtplot-{number}",
                        width=width, height=height, y_extent=errors, picks=labels,
                        label=f"Scene {scene.scene_id}: max position error against the time step dt, log–log, every "
                              f"ok run of {len(by_dt)} variants; each variant's observed order, the slope, is in the "
                              f"legend") if any(s.points for s in by_dt) else Markup("")
    return ParetoPlot(svg, list(groups.items()), dt_svg)


def _front_text(on_front: dict[str, float | None], case_id: str) -> str:
    """A hover's note of the point's place on the Pareto front and its margin (docs/metrics.md)."""
    if case_id not in on_front:
        return ""
    margin = on_front[case_id]
    return "; on the front" + ("" if margin is None else f", margin {margin:.2g}")


def _evidence(problem: Problem, number: int, scene: SceneResults, variants: dict[str, int]) -> str:
    """Where a problem's evidence is: the case's row (unstable, failed, timeout), else the error-vs-dt plot."""
    k = variants.get(problem.engine)
    if k is None:
        return f"#scene-{number}"
    if problem.kind == "inconsistent":
        return f"#s{number}-dt"
    if problem.dts and problem.dts[0] in scene.dts:
        return "#" + row_id(number, k, scene.dts.index(problem.dts[0]))
    return f"#scene-{number}"


def _blowup(problem: Problem, number: int, scene: SceneResults) -> str:
    """For an unstable problem, the time series at its largest unstable dt (where it blows up), else ""."""
    if problem.kind != "unstable" or not problem.dts or problem.dts[0] not in scene.dts:
        return ""
    j = scene.dts.index(problem.dts[0])
    return f"#s{number}-ts" if scene.dts[j] == scene.chosen_dt else f"#s{number}-ts@{j}"


def worst_link(scene: SceneResults, engine: str) -> str:
    """On a model scene, the link with the largest position error of ``engine``'s finest ok run and how far the
    others stay ("panda_leftfinger 16 mm; the other links within 9.5 mm"), from the stored positions; "" when
    the scene is no model or the run kept no positions."""
    links = [p.get("link") for p in scene.scene.get("particles", [])]
    sweep = next((s for s in scene.sweeps if s.engine == engine), None)
    if scene.scene.get("kind") != "model" or sweep is None or not sweep.ok_records or not all(links):
        return ""
    record = min(sweep.ok_records, key=lambda r: r.case.dt)
    series = record.series or {}
    try:
        mine = np.asarray(series["positions"], dtype=float)
        reference = np.asarray(series["reference_positions"], dtype=float)
        per_link = np.nanmax(np.linalg.norm(mine - reference, axis=2), axis=0)
    except (KeyError, TypeError, ValueError):
        return ""
    if per_link.shape != (len(links),) or not np.isfinite(per_link).any():
        return ""
    worst = int(np.nanargmax(per_link))
    others = np.delete(per_link, worst)
    rest = f"; the other links within {si(float(np.nanmax(others)), 'm')}" if others.size else ""
    return f"largest at {links[worst]} ({si(float(per_link[worst]), 'm')}{rest})"


def _item(problem: Problem, number: int, scene: SceneResults, variants: dict[str, int]) -> ProblemItem:
    plateau = next((s.consistency.plateau for s in scene.sweeps if s.engine == problem.engine and s.consistency),
                   None) if problem.kind == "inconsistent" else None
    return ProblemItem(problem.kind, problem.engine, problem.text, _evidence(problem, number, scene, variants),
                       problem.severity, _blowup(problem, number, scene), plateau,
                       worst_link(scene, problem.engine) if problem.kind == "inconsistent" else "")


def verdict_views(data: ReportData, palette: Palette, focus: str | None = None) -> list[SceneVerdictView]:
    """The verdict of every scene that ran, in suite order (numbers match the scene sections')."""
    all_sweeps = [s for scene in data.scenes for s in scene.sweeps]
    focus = focus or default_focus(all_sweeps)
    probes = [p for p in load_probe_files(data.path) if p.get("hidden_dissipation") is True]
    views = []
    for number, scene in enumerate(data.scenes):
        if not scene.sweeps:
            continue
        verdict = scene_verdicts(scene.sweeps, focus)[0]  # once per scene: the plots' colours come from it too
        named = named_by(verdict)
        variants = {s.engine: k for k, s in enumerate(scene.sweeps)}
        heat = []
        for k, sweep in enumerate(scene.sweeps):
            by_dt = {r.case.dt: r for r in sweep.records}
            cells = []
            for j, dt in enumerate(scene.dts):
                record = by_dt.get(dt)
                if record is None:
                    cells.append(HeatCell("none", "", ""))
                    continue
                status = record.status.value
                # No tooltip: the message is one click away (the case's row), and 1,000 of them doubled the section.
                cells.append(HeatCell(status, STATUS_MARK.get(status, "?"), "#" + row_id(number, k, j)))
            heat.append(HeatRow(sweep.engine, family(sweep.engine), palette.colour(sweep.engine), cells))
        items = [_item(p, number, scene, variants) for p in verdict.problems]
        for probe in probes:
            if probe["engine"] in variants:
                rate = probe.get("rate")
                text = "the energy-loss rate extrapolated to dt → 0 is above zero" + (
                    f" ({rate:.2g} E*/s)" if isinstance(rate, (int, float)) else "")
                items.append(ProblemItem("hidden dissipation", probe["engine"], text, f"#scene-{number}", 2))
        items.sort(key=lambda item: item.severity)  # the probes' among the others of their rank (stable sort)
        reaches = [ReachRow(r.engine, family(r.engine), palette.colour(r.engine), r, family(r.engine) == focus)
                   for r in verdict.reaches]
        if verdict.comparison is not None:
            sentence = verdict.comparison.describe()
        elif focus is None or not (present := families(scene.sweeps)):
            sentence = "no engine variant competed on this scene"
        elif focus not in present:
            sentence = f"no {focus} variant ran on this scene"
        else:
            sentence = f"only one engine family ran on this scene; nothing to compare {focus} with"
        views.append(SceneVerdictView(number, scene.scene_id, verdict, sentence,
                                      pareto_plot(scene, number, verdict, palette, named), reaches, scene.dts, heat,
                                      items, named))
    return views

