"""Shared by tests/test_report*.py: a broken test engine, results directories made by real runs, and a page parser.

The results come from ``tests/report_suite.toml`` run through the real runner
once per test session (per xdist worker), so the report is tested on records
exactly as ``xval run`` writes them. Variants of that directory (one case
only, a hostile id, an unfinished run) are copies with files removed or
fields changed, as another producer or an interrupted run would leave them.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any, Callable

import numpy as np

from engines.adapter import Engine, RawRun, Schedule
from engines.scene.scene import Scene
from reports.pack import ENCODING, unpacked

TESTS = Path(__file__).resolve().parent
SUITE = TESTS / "report_suite.toml"
#: Where the browser test leaves its screenshot (kept by CI as an artifact).
ARTIFACTS = TESTS.parent / "artifacts"
#: A string that runs code if it ever reaches the page unescaped.
HOSTILE = '<script>window.__xval_injected = 1</script><img src=x onerror="window.__xval_injected = 2">'


class BrokenEngine(Engine):
    """A test engine that goes wrong on purpose, fast and the same way every time.

    raise : every run raises (a ``failed`` case, with markup in its message).
    blow-up : the particles stay where they start for half the run, then the
        state is NaN (an ``unstable`` case, cut at its first non-finite sample).
    """

    name = "broken"
    capabilities = frozenset({"3d", "constraint-forces"})
    variants = {"raise": {"mode": "raise"}, "blow-up": {"mode": "blow-up"}}
    variant_docs = {"raise": "raises on every run", "blow-up": "NaN state half way through"}

    def version(self) -> str:
        return "0"

    def _run(self, scene: Scene, schedule: Schedule, settings: Any) -> RawRun:
        if settings["mode"] == "raise":
            raise RuntimeError("deliberate failure of <b>the test engine</b> & friends")
        n = len(schedule.sample_steps)
        positions = np.repeat(scene.initial_positions[None], n, axis=0)
        positions[n // 2:] = np.nan
        # Sample 0 must be the scene's initial state (the adapter protocol checks it).
        velocities = np.repeat(scene.initial_velocities[None], n, axis=0)
        velocities[n // 2:] = np.nan
        return RawRun(positions, velocities, None, steps=schedule.n_steps, wall_time=1e-6)


BROKEN = BrokenEngine()

_runs: dict[str, Path] = {}


def run_suite_once(base: Path, suite_path: Path = SUITE, edit: Callable[[str], str] | None = None) -> Path:
    """Run ``suite_path`` (its text passed through ``edit``) into a directory under ``base``, once per session."""
    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite

    text = suite_path.read_text()
    if edit is not None:
        text = edit(text)
    if text not in _runs:
        output = base / f"results-{len(_runs)}"
        run_suite(parse_suite(text, str(suite_path)), output, jobs=2)
        _runs[text] = output
    return _runs[text]


def copy_results(source: Path, target: Path, keep: Callable[[dict[str, Any]], bool] = lambda r: True,
                 change: Callable[[dict[str, Any]], None] = lambda r: None,
                 change_header: Callable[[dict[str, Any]], None] = lambda h: None) -> Path:
    """A copy of the results directory ``source`` with only the records ``keep`` accepts, each passed to ``change``."""
    (target / "cases").mkdir(parents=True)
    shutil.copy(source / "suite.toml", target / "suite.toml")
    header = json.loads((source / "run.json").read_text())
    change_header(header)
    (target / "run.json").write_text(json.dumps(header))
    for file in sorted((source / "cases").glob("*.json")):
        record = json.loads(file.read_text())
        if keep(record):
            change(record)
            (target / "cases" / file.name).write_text(json.dumps(record))
    return target


# -- the page's structure ----------------------------------------------------------------


@dataclass
class Table:
    css_class: str
    rows: list[list[str]] = field(default_factory=list)  # cell texts, header rows included
    best: int = 0  # cells marked best


@dataclass
class Section:
    id: str
    heading: str = ""
    tables: list[Table] = field(default_factory=list)
    plots: list[tuple[str, int]] = field(default_factory=list)  # (DOM id, expected traces)


class PageStructure(HTMLParser):
    """Sections (header, scene sections, problems, how to read) with their tables and plots, and every script."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.sections: list[Section] = []
        self.scripts: list[dict[str, str]] = []  # attributes of each <script>
        self.script_bodies: list[str] = []
        self.urls: list[str] = []  # every src / href / action
        self.status: dict[str, str] = {}
        self._table: Table | None = None
        self._cell: list[str] | None = None
        self._in: str | None = None  # "h1", "h2", "script"
        self._text: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        for key in ("src", "href", "action"):
            if key in a:
                self.urls.append(a[key])
        if tag in ("header", "section"):
            self.sections.append(Section(a.get("id", "")))
        elif tag in ("h1", "h2", "script"):
            self._in, self._text = tag, []
            if tag == "script":
                self.scripts.append(a)
        elif tag == "table" and self.sections:
            self._table = Table(a.get("class", ""))
            self.sections[-1].tables.append(self._table)
        elif tag == "tr" and self._table is not None:
            self._table.rows.append([])
        elif tag in ("td", "th") and self._table is not None:
            self._cell = []
            if "best" in a.get("class", "").split():
                self._table.best += 1
        elif tag == "div" and "xval-plot" in a.get("class", "").split() and self.sections:
            self.sections[-1].plots.append((a["id"], int(a["data-expected-traces"])))
        if a.get("id") == "xval-render-status":
            self.status = a

    def handle_endtag(self, tag: str) -> None:
        if tag == self._in:
            text = "".join(self._text)
            if tag == "script":
                self.script_bodies.append(text)
            elif self.sections:
                self.sections[-1].heading = " ".join(text.split())
            self._in = None
        elif tag in ("td", "th") and self._cell is not None and self._table is not None and self._table.rows:
            self._table.rows[-1].append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data: str) -> None:
        if self._in is not None:
            self._text.append(data)
        if self._cell is not None:
            self._cell.append(data)

    def section(self, section_id: str) -> Section:
        return next(s for s in self.sections if s.id == section_id)

    @property
    def plots(self) -> list[tuple[str, int]]:
        return [p for s in self.sections for p in s.plots]

    def packs(self) -> dict[str, Any]:
        """Every packed element's content (id -> text), unpacked as the page does (7-bit text, then gzip)."""
        found = {}
        for attrs, body in zip(self.scripts, self.script_bodies):
            if attrs.get("data-encoding") == ENCODING:
                found[attrs["id"]] = unpacked(body)
        return found

    def figure_specs(self) -> dict[str, dict[str, Any]]:
        """Plot DOM id -> the figure spec the page packs for it (animation data under ``anim-N``)."""
        specs: dict[str, Any] = {}
        for name, text in self.packs().items():
            if name.startswith("pack-"):
                specs.update(json.loads(text))
        return {k: v for k, v in specs.items() if not k.startswith("anim-")}

    def animations(self) -> dict[str, dict[str, Any]]:
        specs: dict[str, Any] = {}
        for name, text in self.packs().items():
            if name.startswith("pack-"):
                specs.update(json.loads(text))
        return {k: v for k, v in specs.items() if k.startswith("anim-")}

    def problems_table(self) -> Table | None:
        """The table of unstable and failed cases (packed in the page), or None when there is none."""
        text = self.packs().get("problems-packed", "")
        tables = PageStructure(f"<section id='x'>{text}</section>").sections[0].tables if text else []
        return tables[0] if tables else None

    def other_dt_tables(self, scene: int) -> list[Table]:
        """The summary tables of scene number ``scene`` at its other dts (packed in the page)."""
        text = self.packs().get(f"tables-{scene}-packed", "")
        return PageStructure(f"<section id='x'>{text}</section>").sections[0].tables if text else []


# -- hostile strings ----------------------------------------------------------------------

HOSTILE_SUITE = f"""
name = '{HOSTILE}'
description = '{HOSTILE}'
duration = 0.2
dt = [1e-2, 5e-3]
scenes = [{{ id = "bead", scene = "bead" }}]
engines = [
    {{ id = "pymunk/pin", label = '{HOSTILE}' }},
    {{ id = "report_support:BROKEN/raise", label = "broken/raise" }},
]
"""


def hostile_results(base: Path) -> Path:
    """Results whose every string a file can carry is HOSTILE.

    The suite name, description and an engine label come from a real run (a
    suite may say anything there); the scene id (which a suite restricts to
    a readable id), the messages, engine options and machine description are
    then rewritten, as a results file from elsewhere could have them.
    """
    if "hostile" in _runs:
        return _runs["hostile"]
    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite

    run = base / "hostile-run"
    run_suite(parse_suite(HOSTILE_SUITE, HOSTILE), run, jobs=2)

    def change(record: dict[str, Any]) -> None:
        record["case"]["scene_id"] = HOSTILE
        record["case"]["options"] = {HOSTILE: HOSTILE}
        if record["status"] != "ok":
            record["message"] = f"{record['message']} {HOSTILE}"

    def change_header(header: dict[str, Any]) -> None:
        header["environment"]["cpu"] = HOSTILE
        header["environment"]["engines"][HOSTILE] = HOSTILE

    _runs["hostile"] = copy_results(run, base / "hostile", change=change, change_header=change_header)
    return _runs["hostile"]
