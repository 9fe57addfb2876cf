"""A results directory read back and arranged the way the report shows it: by scene, by engine variant.

Reading and grouping go through :mod:`compare.results.store` and
:mod:`compare.results.sweep`, so the report shows the same numbers (observed orders,
work-precision points) as ``xval show``. Nothing here formats text or builds
plots; it only decides *what* is shown:

- the scenes, each with its engine variants' dt sweeps in the suite's order;
- per scene, the *chosen dt*: the one time step at which the summary table
  compares the variants and the time series are drawn (one dt for every
  variant, so a column's best value is a fair comparison);
- the status counts, the skipped (scene, engine) pairs with their reasons,
  and the cases that went unstable, failed or timed out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from compare.run.results import load_results
from compare.results.record import PROBLEMS, CaseRecord, status_counts
from compare.results.sweep import VariantSweep, sweeps
from compare.suite.reader import RunSettings



@dataclass(frozen=True)
class SkippedPair:
    """A (scene, engine variant) left out of the run, with the reason the runner recorded."""

    scene_id: str
    engine: str
    reason: str


@dataclass(frozen=True)
class SceneResults:
    """One scene of the suite.

    sweeps : the variants that ran (at least one case not skipped), suite order.
    skipped : the variants left out, with their reasons.
    dts : every time step of the scene's cases, s, largest first.
    chosen_dt : s, the dt of the summary table and time series (None when
        nothing ran).
    scene : the Scene as a dict (``Scene.to_dict``); length : L in m.
    """

    scene_id: str
    scene_name: str
    scene: dict[str, Any]
    scene_hash: str
    length: float
    sweeps: list[VariantSweep]
    skipped: list[SkippedPair]
    dts: list[float]
    chosen_dt: float | None

    def case_at(self, sweep: VariantSweep, dt: float | None) -> CaseRecord | None:
        """``sweep``'s record at time step ``dt`` (s), or None."""
        return next((r for r in sweep.records if dt is not None and r.case.dt == dt), None)


@dataclass(frozen=True)
class ReportData:
    """Everything the report shows, arranged; ``header`` is run.json as stored; ``settings`` the δ, bounds
    and verdict tolerance of the suite.toml stored with the results (compare.run.results.Results.settings)."""

    path: Path
    header: dict[str, Any]
    scenes: list[SceneResults]
    counts: dict[str, int]
    problems: list[CaseRecord] = field(default_factory=list)
    settings: RunSettings = field(default_factory=RunSettings)
    #: The cases whose engine printed something while they ran (CaseRecord.engine_output), in scene order.
    printed: list[CaseRecord] = field(default_factory=list)

    @property
    def n_cases(self) -> int:
        return sum(self.counts.values())


def choose_dt(scene_sweeps: list[VariantSweep], dts: list[float], requested: float | None = None) -> float | None:
    """The time step (s) at which a scene's variants are compared and drawn.

    requested : the user's choice; the scene's dt nearest to it on a log
        scale is used (scenes of one suite share dts, but a filtered or
        resumed directory may not).
    Otherwise the dt at which the most variants are ``ok``, the smallest
    such dt on a tie: the most variants in the comparison, each at its most
    accurate. None when the scene has no case that ran.
    """
    if not dts:
        return None
    if requested is not None:
        return min(dts, key=lambda dt: abs(math.log(dt / requested)))

    def ok_count(dt: float) -> int:
        return sum(1 for s in scene_sweeps for r in s.records if r.case.dt == dt and r.status == "ok")

    return max(dts, key=lambda dt: (ok_count(dt), -dt))


def _skip_reason(sweep: VariantSweep) -> str:
    messages = [r.message for r in sweep.records if r.message]
    return messages[0] if messages else "no reason recorded"


def arrange(path: Path, header: dict[str, Any], records: list[CaseRecord], dt: float | None = None,
            settings: RunSettings | None = None) -> ReportData:
    """Group ``records`` by scene (suite order) and variant; ``dt`` (s) is the requested chosen dt, if any;
    settings : the suite's, whose verdict tolerance judges consistency (None: the defaults)."""
    settings = settings or RunSettings()
    by_scene: dict[str, list[VariantSweep]] = {}
    for sweep in sweeps(records, settings.verdict_tolerance):
        by_scene.setdefault(sweep.scene_id, []).append(sweep)
    scenes = []
    for scene_id, scene_sweeps in by_scene.items():
        ran = [s for s in scene_sweeps if s.statuses.get("skipped", 0) < len(s.records)]
        skipped = [SkippedPair(scene_id, s.engine, _skip_reason(s)) for s in scene_sweeps if s not in ran]
        first = scene_sweeps[0].records[0]
        dts = sorted({r.case.dt for s in ran for r in s.records}, reverse=True)
        scenes.append(
            SceneResults(
                scene_id=scene_id,
                scene_name=first.case.scene_name,
                scene=dict(first.scene),
                scene_hash=first.scene_hash,
                length=first.characteristic.length,
                sweeps=ran,
                skipped=skipped,
                dts=dts,
                chosen_dt=choose_dt(ran, dts, dt),
            )
        )
    problems = [r for s in scenes for sw in s.sweeps for r in sw.records if r.status in PROBLEMS]
    printed = [r for s in scenes for sw in s.sweeps for r in sw.records if r.engine_output]
    return ReportData(path, header, scenes, status_counts(records), problems, settings, printed)


def load_report_data(directory: str | Path, dt: float | None = None) -> ReportData:
    """Read the results in ``directory`` (UserError when it is not a results directory) and arrange them."""
    stored = load_results(directory)
    return arrange(stored.path, stored.header, stored.records, dt, stored.settings)
