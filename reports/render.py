"""Render a results directory to one self-contained HTML file.

The page is a Jinja2 template (``templates/report.html.j2``) with
autoescaping on, so every string that comes from a suite or results file is
escaped wherever it lands in the HTML. Figure specs go into
``<script type="application/json">`` blocks through Jinja's ``tojson``
filter, which escapes ``<``, ``>`` and ``&`` so no string can close the
script element. plotly.js is embedded once, inline, from the plotly
package: the page makes no request, so it works offline and attached to a
CI run or a mail.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup

from compare.results.files import atomic_write_text, check_writable
from compare.results.metrics import ORDER_CEILING, ORDER_FLOOR, ORDER_MIN_POINTS
from compare.suite.reader import RunSettings, load_run_settings
from engines.errors import UserError

from reports.figures import Plot, scene_plots
from reports.load import ReportData, load_report_data
from reports.stability import stability_context
from reports.summary import summary_table

#: File name of the report inside the results directory when no --output is given.
DEFAULT_NAME = "report.html"


@functools.lru_cache(maxsize=1)
def plotly_js() -> Markup:
    """The plotly.js bundle shipped with the plotly package, safe to inline in a ``<script>`` element."""
    from plotly.offline import get_plotlyjs

    source = get_plotlyjs()
    # "</script" would end the element early; in JavaScript source "<\/" means the same as "</".
    return Markup(source.replace("</script", "<\\/script").replace("</SCRIPT", "<\\/SCRIPT"))


@functools.lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("reports", "templates"),
        autoescape=True,  # every {{ }} is escaped unless marked safe; file names end in .j2, so say so explicitly
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["seconds"] = lambda v: "–" if v is None else f"{v:.3g} s"
    env.filters["g3"] = lambda v: "–" if v is None else f"{v:.3g}"
    return env


def suite_settings(directory: Path) -> dict[str, Any]:
    """δ and the status bounds the run used, from the stored suite.toml (read without loading engines)."""
    try:
        settings = load_run_settings(directory / "suite.toml")
    except UserError:
        settings = RunSettings()
    return {"delta": settings.delta, "energy_bound": settings.bounds.energy_drift,
            "constraint_bound": settings.bounds.constraint_error, "verdict_tolerance": settings.verdict_tolerance}


def page_context(data: ReportData) -> dict[str, Any]:
    """Everything the template needs, computed here so the template only lays it out."""
    scenes = []
    for number, scene in enumerate(data.scenes):
        scenes.append({
            "number": number,
            "results": scene,
            "table": summary_table(scene) if scene.sweeps else None,
            "plots": scene_plots(scene, number),
        })
    plots: list[Plot] = [p for s in scenes for p in s["plots"]]
    stability = stability_context(data.path)  # None unless DIR holds xval stability output
    if stability is not None:
        plots = plots + stability["plots"]
    header = data.header
    return {
        "data": data,
        "suite": header.get("suite") or {},
        "env": header.get("environment") or {},
        "header": header,
        "counts": data.counts,
        "ran": sum(n for status, n in data.counts.items() if status != "skipped"),
        "scenes": scenes,
        "n_plots": len(plots),
        "n_traces": sum(p.n_traces for p in plots),
        "settings": suite_settings(data.path),
        "order_floor": f"{ORDER_FLOOR:g}",
        "order_ceiling": f"{ORDER_CEILING:g}",
        "order_min_points": ORDER_MIN_POINTS,
        "plotly_js": plotly_js(),
        "stability": stability,
    }


def render(data: ReportData) -> str:
    """The report page of ``data`` as HTML text."""
    return environment().get_template("report.html.j2").render(page_context(data))


@dataclass(frozen=True)
class Written:
    """A written report: path, size in bytes, render time in s (reading the results included)."""

    path: Path
    size: int
    seconds: float


def write_report(directory: str | Path, output: str | Path | None = None, dt: float | None = None) -> Written:
    """Render the results in ``directory`` to ``output`` (default DIR/report.html), atomically.

    dt : s, the time step of the summary tables and time series (the nearest
    one each scene has); chosen per scene when None.
    """
    started = time.perf_counter()
    data = load_report_data(directory, dt)  # first, so a wrong DIR is named as such
    target = check_writable(Path(output) if output is not None else Path(directory) / DEFAULT_NAME)
    text = render(data)
    atomic_write_text(target, text)
    return Written(target, len(text.encode()), time.perf_counter() - started)
