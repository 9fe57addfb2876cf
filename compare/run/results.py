"""A finished run read back: run.json's header, its case records, and the suite settings that judge them.

The case files are read by compare.results.store (:func:`~compare.results.store.read_run`); this module
pairs them with the suite kept beside them (``DIR/suite.toml``, through compare.suite.reader), which is
why it sits above both: the records know nothing of suites.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from compare.results.record import CaseRecord, status_counts
from compare.results.store import read_run
from compare.results.sweep import VariantSweep, sweeps
from compare.suite.reader import RunSettings, load_run_settings


@dataclass(frozen=True)
class Results:
    """A results directory as read back, once: ``header`` (run.json) and the typed case ``records``.

    The views the commands need: :meth:`by_scene`, :meth:`by_variant` and
    :meth:`sweeps` (per scene × variant across dt, with the observed order and
    the consistency verdict).
    """

    path: Path
    header: dict[str, Any]
    records: list[CaseRecord]

    def by_scene(self) -> dict[str, list[CaseRecord]]:
        """Records grouped by scene id, in suite order."""
        groups: dict[str, list[CaseRecord]] = {}
        for record in sorted(self.records, key=lambda r: r.case.position):
            groups.setdefault(record.case.scene_id, []).append(record)
        return groups

    def by_variant(self) -> dict[tuple[str, str], list[CaseRecord]]:
        """Records grouped by (scene id, engine label), in suite order (largest dt first)."""
        groups: dict[tuple[str, str], list[CaseRecord]] = {}
        for record in sorted(self.records, key=lambda r: r.case.position):
            groups.setdefault((record.case.scene_id, record.case.engine), []).append(record)
        return groups

    @functools.cached_property
    def settings(self) -> RunSettings:
        """The compare.suite.reader.RunSettings (δ, bounds, [gate], verdict tolerance) of the suite.toml kept
        with these results, read once."""
        return load_run_settings(self.path / "suite.toml")

    @property
    def verdict_tolerance(self) -> float:
        """The consistency tolerance (fraction of L) of the suite that made these results."""
        return self.settings.verdict_tolerance

    def sweeps(self) -> list[VariantSweep]:
        """Per (scene, variant): records across dt, observed order and consistency (compare.results.sweep),
        judged once (``xval run --history`` prints them and stores the baseline made of them)."""
        return self._sweeps

    @functools.cached_property
    def _sweeps(self) -> list[VariantSweep]:
        return sweeps(self.records, self.verdict_tolerance)

    def counts(self) -> dict[str, int]:
        """How many cases ended in each status, in Status order."""
        return status_counts(self.records)


def load_results(path: str | Path) -> Results:
    """Read a results directory once; UserError when it is not one, is damaged, or has another schema version."""
    return Results(*read_run(path))
