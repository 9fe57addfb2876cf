"""Render a results directory to one self-contained HTML file.

The page is a Jinja2 template (``templates/report.html.j2``) with
autoescaping on, so every string that comes from a suite or results file is
escaped wherever it lands in the HTML. Figure specs go into
``<script type="application/json">`` blocks through Jinja's ``tojson``
filter, which escapes ``<``, ``>`` and ``&`` so no string can close the
script element. plotly.js and the figure specs are embedded packed
(``reports.pack``, shared with the history's trend page: gzip written seven
bits to a character, 1.68 MB instead of 4.8 MB for plotly.js); the page unpacks them with the
browser's own DecompressionStream and makes no request, so it works offline
and attached to a CI run or a mail.

Details: docs/report.md, "Module notes", ``reports/render.py``.
"""

from __future__ import annotations

import functools
import math
import re
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup
from markupsafe import escape as markupsafe_escape

from compare.results.verdict import families
from engines.errors import UserError
from engines.scene.catalog import CATALOG

from engines.files import atomic_write_text, check_writable

from compare.results.record import engine_output_lines
from compare.results.store import results_inputs
from compare.results.metrics import ORDER_CEILING, ORDER_FLOOR, ORDER_MIN_POINTS
from compare.suite.reader import RunSettings

from reports.overview import import_findings, overview, reconcile
from reports.parity import parity_view
from reports.animation import animation_data
from reports.decimate import MAX_POINTS
from reports.gradients import gradient_views
from reports.figures import (
    CLIP_FACTOR, Ceilings, Plot, Thinning, constraint_forces, paths, phase_plot, scene_plots, time_series,
)
from reports.load import ReportData, load_report_data
from reports.pack import pack, packed_text, template_values
from reports.palette import Palette
from reports.stability import stability_context
from reports.summary import summary_tables
from reports.verdict import verdict_views

#: File name of the report inside the results directory when no --output is given.
DEFAULT_NAME = "report.html"


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
    env.filters["packed"] = lambda text: packed_text(str(text))
    env.filters["numbers"] = unbroken_numbers
    env.filters["engine_output"] = engine_output_lines
    return env


#: A number in running text: 1.28e-03, 2.34e+04, 0.016 (not inside a word, an entity or a path).
_NUMBER = re.compile(r"(?<![\w#&;/.-])-?\d+(?:\.\d+)?(?:e[-+]\d+)?(?![\w;])")


def unbroken_numbers(text: str) -> Markup:
    """``text`` escaped, each number in a ``<span class="num">`` (white-space: nowrap), so "1.28e-03" never
    breaks at its hyphen."""
    return Markup(_NUMBER.sub(lambda m: f'<span class="num">{m.group(0)}</span>', str(markupsafe_escape(text))))


def suite_settings(settings: RunSettings) -> dict[str, Any]:
    """δ, the status bounds and the verdict tolerance the run used (ReportData.settings), as the page names them."""
    return {"delta": settings.delta, "energy_bound": settings.bounds.energy_drift,
            "constraint_bound": settings.bounds.constraint_error, "verdict_tolerance": settings.verdict_tolerance}


#: Above this many scenes, each scene's verdict body and tables are packed and unpacked when the scene comes
#: into view or a link asks for it (a big suite's page stays light and interactive at once).
LAZY_SCENES = 8
#: In such a suite, the time series at a scene's other dts (shown when the dt selector asks): points per trace
#: (LTTB keeps peaks and blow-ups), significant digits, and points per trace of a variant drawn grey (one the
#: verdict does not name: context, not evidence).
LAZY_SERIES = (30, 3, 8)
#: Points per grey trace of the time series at the chosen dt in such a suite.
LAZY_CHOSEN_MUTED = 12


def page_context(data: ReportData, focus: str | None = None, lazy: bool | None = None) -> dict[str, Any]:
    """Everything the template needs, computed here so the template only lays it out.

    focus : the engine family the verdict compares with the others (default: the suite's first).
    lazy : pack each scene's details (default: when there are more than LAZY_SCENES scenes).
    """
    focus = check_focus(data, focus)
    lazy_page = len(data.scenes) > LAZY_SCENES if lazy is None else lazy
    settings = suite_settings(data.settings)
    palette = Palette(s.engine for scene in data.scenes for s in scene.sweeps)
    verdicts = verdict_views(data, palette, focus)
    named = {view.number: view.named for view in verdicts}  # each scene's verdict, computed once, colours its plots
    scenes: list[dict[str, Any]] = []
    for number, scene in enumerate(data.scenes):
        ceilings = Ceilings.for_scene(scene.length, settings["energy_bound"], settings["constraint_bound"],
                                      CLIP_FACTOR * _weight(scene.scene))
        scenes.append({
            "number": number,
            "results": scene,
            "tables": summary_tables(scene, palette) if scene.sweeps else [],
            "plots": _lighter(scene_plots(scene, number, palette, ceilings, named.get(number, set())), scene, number,
                              palette, ceilings, named.get(number, set())) if lazy_page else
                     scene_plots(scene, number, palette, ceilings, named.get(number, set())),
            "animation": animation_data(scene, palette),
            "ceilings": ceilings,
            "parameters": scene_parameters(scene.scene_name, scene.scene.get("parameters") or {}),
            "parity": parity_view(data.path, scene.scene_id, scene.scene) if scene.scene.get("kind") == "model" else None,
        })
    plots: list[Plot] = [p for s in scenes for p in s["plots"]]
    packs: dict[str, Markup] = {}
    pack_of: dict[str, str] = {}
    for entry in scenes:
        name = f"pack-{entry['number']}"
        items: dict[str, Any] = {p.id: p.figure for p in entry["plots"]}
        results = entry["results"]
        if any(p.id == f"s{entry['number']}-ts" for p in entry["plots"]):
            # The time series at the scene's other dts: the dt selector switches the plot with the table.
            for j, dt in enumerate(results.dts):
                if dt != results.chosen_dt:
                    other = time_series(results, palette, entry["ceilings"], dt, named.get(entry["number"], set()),
                                        *(LAZY_SERIES if lazy_page else ()))
                    if other is not None:
                        items[f"s{entry['number']}-ts@{j}"] = other.figure
        if entry["animation"] is not None:
            items[f"anim-{entry['number']}"] = entry["animation"].data
        packs[name] = pack(items)
        pack_of.update({p.id: name for p in entry["plots"]})
    stability = stability_context(data.path)  # None unless DIR holds xval stability output
    if stability is not None:
        plots = plots + stability["plots"]
        for name, members in (("pack-stability", [stability["search"]["bars"]] if stability.get("search") and stability["search"].get("bars") else []),
                              ("pack-gainmap", stability["gainmap"]["plots"] if stability.get("gainmap") else [])):
            packs[name] = pack({p.id: p.figure for p in members})
            pack_of.update({p.id: name for p in members})
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
        "settings": settings,
        "verdicts": verdicts,
        "lazy": lazy_page,
        "overview": overview(verdicts, {entry["number"]: entry["parity"] for entry in scenes}),
        "leads": model_leads(verdicts, scenes, settings["verdict_tolerance"]),
        "focus": focus,
        "scene_numbers": {scene.scene_id: number for number, scene in enumerate(data.scenes)},
        "clip_factor": f"{CLIP_FACTOR:g}",
        "max_points": f"{MAX_POINTS:,}",
        "order_floor": f"{ORDER_FLOOR:g}",
        "order_ceiling": f"{ORDER_CEILING:g}",
        "order_min_points": ORDER_MIN_POINTS,
        **template_values(),
        "packs": packs,
        "pack_of": pack_of,
        "stability": stability,
        "gradients": gradient_views(data, palette),
    }


def _lighter(plots: list[Plot], scene: Any, number: int, palette: Palette, ceilings: Ceilings,
             named: set[str]) -> list[Plot]:
    """``plots`` with the time series at the chosen dt at LAZY_SERIES' digits and a grey variant thinned to
    LAZY_CHOSEN_MUTED points (a big suite's page; the named variants keep every point), and the constraint forces,
    phase curves and paths thinned as the time series at the other dts are (LAZY_SERIES)."""
    digits = LAZY_SERIES[1]
    thin = Thinning(LAZY_SERIES[0], digits, LAZY_SERIES[2], frozenset(named))
    lighter = {"ts": time_series(scene, palette, ceilings, None, named, MAX_POINTS, digits, LAZY_CHOSEN_MUTED),
               "force": constraint_forces(scene, palette, ceilings, thin), "path": paths(scene, palette, thin),
               "phase": phase_plot(scene, palette, thin)}
    out = []
    for plot in plots:
        kind = plot.id.split("-", 1)[1]
        light = lighter.get(kind)
        out.append(replace(light, id=plot.id) if light is not None else plot)
    return out


def model_leads(verdicts: list[Any], scenes: list[dict[str, Any]], tolerance: float) -> dict[int, dict[str, Any]]:
    """Per model scene with a parity table, what its verdict leads with: the engines whose import disagrees
    with the model reference (reports.overview.import_findings) and, for those that agree yet err beyond the
    verdict tolerance (``tolerance`` · L), whether that is the stepping or chaos (reports.overview.reconcile)."""
    leads = {}
    for view in verdicts:
        entry = scenes[view.number]
        if not entry["parity"]:
            continue
        results = entry["results"]
        horizon = next((r.reference_horizon for s in results.sweeps for r in s.records
                        if r.reference_horizon is not None), None)
        duration = results.scene.get("duration")
        imports = import_findings(view.number, view.scene_id, entry["parity"], {b.family for b in view.verdict.best})
        agreeing = reconcile(view, entry["parity"], tolerance * results.length, horizon, duration)
        if imports or agreeing:
            leads[view.number] = {"imports": imports, "agreeing": agreeing}
    return leads


def scene_parameters(name: str, values: dict[str, Any]) -> list[str]:
    """A catalog scene's parameters as "theta0 = 60 deg", each with the unit its builder declares
    (engines.scene.catalog), value and unit joined by a no-break space."""
    builder = CATALOG.get(name)
    units = {p.name: p.unit for p in builder.parameters} if builder is not None else {}
    return [f"{key} = {value}" + (f"\u00a0{units[key]}" if units.get(key) else "") for key, value in values.items()]


def _weight(scene: dict[str, Any]) -> float:
    """Total mass · |g| of a scene dict (N): the scale of its constraint forces."""
    mass = sum(p.get("mass", 0.0) for p in scene.get("particles", []))
    g = math.sqrt(sum(c * c for c in scene.get("gravity", [0.0, 0.0, -9.81])))
    return mass * g if mass * g > 0 else math.inf


def check_focus(data: ReportData, focus: str | None) -> str | None:
    """``focus``, or the suite's first engine family when None; UserError naming the families when unknown."""
    found = families([s for scene in data.scenes for s in scene.sweeps])
    if focus is None:
        return found[0] if found else None
    if focus not in found:
        choices = ", ".join(found) or "none ran"
        raise UserError(f"--focus: no engine family {focus!r} in these results; choose one of: {choices}")
    return focus


#: Indentation before a tag at the start of a line: the template's, not the data's (text from a file is escaped,
#: so a line of it never starts with "<").
_INDENT = re.compile(r"\n[ \t]+<")


def render(data: ReportData, focus: str | None = None, lazy: bool | None = None) -> str:
    """The report page of ``data`` as HTML text (``focus``: the engine family the verdict compares; ``lazy``:
    see :func:`page_context`).

    The template's indentation is dropped (a fifth of a large report's bytes); the page is unchanged.
    """
    return _INDENT.sub("\n<", environment().get_template("report.html.j2").render(page_context(data, focus, lazy)))


@dataclass(frozen=True)
class Written:
    """A written report: path, size in bytes, render time in s (reading the results included)."""

    path: Path
    size: int
    seconds: float


def write_report(directory: str | Path, output: str | Path | None = None, dt: float | None = None,
                 focus: str | None = None) -> Written:
    """Render the results in ``directory`` to ``output`` (default DIR/report.html), atomically.

    dt : s, the time step of the summary tables and time series (the nearest
    one each scene has); chosen per scene when None. focus : the engine family the verdict compares
    with the best of the others (default: the first family of the suite).
    """
    started = time.perf_counter()
    data = load_report_data(directory, dt)  # first, so a wrong DIR is named as such
    check_focus(data, focus)
    target = check_writable(Path(output) if output is not None else Path(directory) / DEFAULT_NAME,
                            inputs=results_inputs(directory))
    text = render(data, focus)
    atomic_write_text(target, text)
    return Written(target, len(text.encode()), time.perf_counter() - started)
