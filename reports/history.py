"""``xval history report``: the trend page of a history, one self-contained HTML file.

Per machine × suite (machines are never mixed: a timing from another CPU is
not a trend), per scene × variant, one figure with a row per metric — each
gated accuracy metric the variant has values for, the observed order, and
the cost — and a line per dt across runs (x = history order, labelled by
commit; hover = commit, date, run, value, status). Step changes found by
compare.history.trend.steps are marked on the figure (a dashed line before
the first run after the step) and listed at the top of the page.

Details: docs/history.md, "Module notes", ``reports/history.py``.
"""

from __future__ import annotations

import functools
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import click
import jinja2
from markupsafe import Markup

from compare.cli import history_option
from compare.history.store import History, StoredRun
from compare.history.trend import Series, build_series, run_groups, trend_metrics
from engines.files import atomic_write_text, check_writable

from reports.figures import Plot, plot_text
from reports.pack import pack, template_values

#: One colour per dt of a variant (largest dt first).
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")
#: Height of one metric's row in a figure, px.
ROW_HEIGHT = 170


#: Significant digits a trend value keeps in the page, and its hover shows (the gate tolerates 10 % and more).
DIGITS = 3


def _round(value: float | None) -> float | None:
    """``value`` to :data:`DIGITS` significant digits (None stays None)."""
    return None if value is None else float(f"{value:.{DIGITS - 1}e}")


def run_label(run: StoredRun) -> str:
    """A run as a plot's hover names it: run number, commit, start time."""
    return plot_text(f"run {run.id} · commit {run.origin.short} · {str(run.started)[:16].replace('T', ' ')}")


def _variant_figure(number: int, scene: str, engine: str, series: Sequence[Series], runs: Sequence[StoredRun]) -> Plot:
    """One figure: a row per metric (in declaration order), a line per dt, step markers."""
    present = {s.metric.name for s in series}
    metrics = [m for m in trend_metrics() if m.name in present]
    dts = sorted({s.dt for s in series}, reverse=True)
    rows = len(metrics)
    gap = 0.06 / max(rows, 1)
    data: list[dict[str, Any]] = []
    layout: dict[str, Any] = {
        "height": ROW_HEIGHT * rows + 90, "margin": {"l": 70, "r": 20, "t": 30, "b": 80},
        "hovermode": "closest", "legend": {"orientation": "h", "y": 1.02, "yanchor": "bottom"}, "shapes": [],
        "annotations": [],
    }
    ticks = [r.origin.short for r in runs]
    for row, metric in enumerate(metrics):
        axis = "" if row == 0 else str(row + 1)
        top = 1 - row / rows
        bottom = 1 - (row + 1) / rows + gap
        in_row = [s for s in series if s.metric.name == metric.name]
        if metric.per == "variant":  # the observed order is one number per variant: draw it once
            in_row = in_row[:1]
        positive = all(p.value > 0 for s in in_row for p in s.points if p.value is not None)
        unit = f" ({metric.unit})" if metric.unit else ""
        layout[f"yaxis{axis}"] = {
            "domain": [bottom, top], "anchor": f"x{axis}", "type": "log" if positive and metric.name != "observed_order" else "linear",
            "title": {"text": plot_text(metric.name.replace("_", " ") + unit), "font": {"size": 10}}, "exponentformat": "power",
        }
        last_row = row == rows - 1
        layout[f"xaxis{axis}"] = {
            "anchor": f"y{axis}", "tickvals": list(range(len(runs))), "ticktext": [plot_text(t) for t in ticks],
            "showticklabels": last_row, "tickangle": -45, "range": [-0.5, len(runs) - 0.5],
            **({"matches": "x"} if row else {}),
            **({"title": {"text": "run (commit; * = uncommitted changes)"}} if last_row else {}),
        }
        for s in in_row:
            colour = COLOURS[dts.index(s.dt) % len(COLOURS)] if metric.per != "variant" else "#444"
            name = "observed order" if metric.per == "variant" else f"dt = {s.dt:.3g} s"
            data.append({
                "type": "scatter", "mode": "lines+markers", "xaxis": f"x{axis}", "yaxis": f"y{axis}",
                "x": [p.order for p in s.points], "y": [_round(p.value) for p in s.points], "connectgaps": False,
                "name": plot_text(name), "legendgroup": plot_text(name), "showlegend": row == 0 or metric.per == "variant",
                "line": {"color": colour, "width": 1.5}, "marker": {"size": 6, "color": colour},
                # customdata: the run's label (run_label), which the page fills in from x before it draws.
                "hovertemplate": "%{customdata}<br>" + plot_text(metric.name) + " = %{y:.3g}" + plot_text(unit) + "<extra></extra>",
            })
            for step in s.steps:
                x = s.points[step.index].order - 0.5
                colour_step = "#d62728" if step.outcome == "worse" else "#2ca02c"
                layout["shapes"].append({
                    "type": "line", "xref": f"x{axis}", "yref": f"y{axis} domain", "x0": x, "x1": x, "y0": 0, "y1": 1,
                    "line": {"color": colour_step, "dash": "dash", "width": 2},
                })
                ratio = f"×{step.ratio:.3g}" if step.ratio is not None else f"{step.before:.3g} → {step.after:.3g}"
                layout["annotations"].append({
                    "xref": f"x{axis}", "yref": f"y{axis} domain", "x": x, "y": 1, "yanchor": "bottom", "showarrow": False,
                    "text": plot_text(f"{ratio} {step.outcome}"), "font": {"size": 10, "color": colour_step},
                })
    title = f"{scene} · {engine}"
    caption = (f"{len(runs)} runs; one row per metric, one line per dt; a dashed line marks a step change "
               f"(red: worse, green: better) before the first run after it. Gaps are runs where the case was not ok.")
    return Plot(f"trend-{number}", title, caption, {"data": data, "layout": layout})


def page_context(history: History, suite: str | None = None, last: int | None = None) -> dict[str, Any]:
    """Everything the template lays out."""
    runs_all = history.runs(suite=suite)
    # One section per group of build_series (by the machine's fingerprint): a point's x is its run's place
    # in its group's window, and the hover names the run at that place in this section's window. Two
    # machines can share a name (fields that differ only where the name shows nothing).
    groups = run_groups(runs_all, last)
    all_series = build_series(history, groups=groups)
    name_of = {fingerprint: runs[0].machine.name for (fingerprint, _), runs in groups.items()}
    alike = Counter(name_of.values())
    sections: list[dict[str, Any]] = []
    figures: list[Plot] = []
    step_rows = []
    packs: dict[str, Markup] = {}
    for (fingerprint, suite_name), runs in groups.items():
        machine = name_of[fingerprint] + (f" (fingerprint {fingerprint})" if alike[name_of[fingerprint]] > 1 else "")
        mine = [s for s in all_series if (s.fingerprint, s.suite) == (fingerprint, suite_name)]
        variants: dict[tuple[str, str], list[Series]] = {}
        for s in mine:
            variants.setdefault((s.scene_id, s.engine), []).append(s)
            for step in s.steps:
                point = s.points[step.index]
                step_rows.append({
                    "machine": machine, "suite": suite_name, "scene": s.scene_id, "engine": s.engine, "dt": s.dt,
                    "metric": s.metric.name, "unit": s.metric.unit, "commit": point.commit, "run": point.run_id,
                    "date": point.date, "before": step.before, "after": step.after, "ratio": step.ratio,
                    "outcome": step.outcome,
                })
        plots: list[Plot] = []
        for (scene, engine), series in variants.items():
            plots.append(_variant_figure(len(figures) + len(plots), scene, engine, series, runs))
        figures.extend(plots)
        name = f"pack-{len(sections)}"
        packs[name] = pack({"runs": [run_label(r) for r in runs], **{p.id: p.figure for p in plots}})
        sections.append({"machine": machine, "suite": suite_name, "runs": runs, "plots": plots, "pack": name})
    return {
        "history": history.name, "runs": runs_all, "sections": sections, "steps": group_steps(step_rows),
        "n_steps": len(step_rows), "n_plots": len(figures), "n_traces": sum(f.n_traces for f in figures),
        **template_values(), "packs": packs, "generated": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "several_machines": len({f for f, _ in groups}) > 1,
    }


def group_steps(step_rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Steps of one variant at one run in one direction, as one row: the metrics and dts it moved, the ratios' range."""
    grouped: dict[tuple, dict[str, Any]] = {}
    for row in step_rows:
        key = (row["machine"], row["suite"], row["scene"], row["engine"], row["run"], row["outcome"])
        group = grouped.setdefault(key, {**row, "metrics": [], "dts": [], "ratios": []})
        if row["metric"] not in group["metrics"]:
            group["metrics"].append(row["metric"])
        if row["metric"] != "observed_order" and row["dt"] not in group["dts"]:
            group["dts"].append(row["dt"])
        if row["ratio"] is not None:
            group["ratios"].append(row["ratio"])
    out = list(grouped.values())
    for group in out:
        ratios = group["ratios"]
        group["ratio_text"] = "–" if not ratios else (
            f"×{min(ratios):.3g}" if f"{min(ratios):.3g}" == f"{max(ratios):.3g}" else f"×{min(ratios):.3g} … ×{max(ratios):.3g}")
        group["dts"] = sorted(group["dts"], reverse=True)
    out.sort(key=lambda g: (g["outcome"] != "worse", g["machine"], g["suite"], g["scene"], g["engine"], g["run"]))
    return out


@functools.lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("reports", "templates"), autoescape=True,
        undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
    )
    env.filters["g3"] = lambda v: "–" if v is None else f"{v:.3g}"
    env.filters["when"] = lambda v: "–" if not v else str(v)[:16].replace("T", " ")
    return env


def render(history: History, suite: str | None = None, last: int | None = None) -> str:
    return environment().get_template("history.html.j2").render(page_context(history, suite, last))


@dataclass(frozen=True)
class Written:
    """path; size in bytes; seconds to read the history and render; runs and steps shown."""

    path: Path
    size: int
    seconds: float
    runs: int
    steps: int


def write_history_report(location: str | None, output: str | Path, suite: str | None = None, last: int | None = None) -> Written:
    """Render the history at ``location`` to ``output`` (atomically)."""
    started = time.perf_counter()
    target = check_writable(Path(output), "--output")
    with History.open(location) as history:
        context = page_context(history, suite, last)
        text = environment().get_template("history.html.j2").render(context)
    atomic_write_text(target, text)
    return Written(target, len(text.encode()), time.perf_counter() - started, len(context["runs"]), context["n_steps"])


@click.command("report")
@history_option(help="The history (default: $XVAL_HISTORY, else results/history.sqlite).")
@click.option("--output", "-o", required=True, metavar="FILE.html", help="Where to write the page.")
@click.option("--suite", default=None, metavar="NAME", help="Only runs of this suite.")
@click.option("--last", type=click.IntRange(min=1), default=None, metavar="N", help="Only the last N runs of each machine × suite.")
def command(location, output, suite, last) -> None:
    """Write the trend page of the history: accuracy and cost per scene × variant across runs, step changes marked.

    The file is self-contained: plots are interactive and it needs no network.
    """
    written = write_history_report(location, output, suite, last)
    click.echo(f"history report: {written.path} ({written.runs} runs, {written.steps} step changes, "
               f"{written.size / 1e6:.1f} MB, {written.seconds:.2f} s)")
