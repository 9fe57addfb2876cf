"""Baselines: the gate-relevant part of a results directory, in one small versioned JSON file.

A baseline keeps, per case, a :class:`~compare.gate.entry.BaselineEntry`
(its key: scene id and content hash, engine, variant, options, dt; the engine
version; status; the gated metrics; the timing and its repeats), made from the
case record by :func:`compare.gate.entry.entry_of`. :class:`Baseline` is the
typed document a gate compares: a baseline file, the current results, or a
window of the history's runs.

Details: docs/gate.md, "Module notes", ``compare/gate/baseline.py``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from engines.errors import UserError

from compare.gate.entry import BaselineEntry, EntryError, entry_of, record_key
from engines.files import atomic_write_text, read_user_text
from compare.results.store import jsonable, now
from compare.run.results import Results

#: Bump when a field of the baseline file changes meaning.
BASELINE_SCHEMA_VERSION = 1
#: The ``kind`` that tells a baseline from any other JSON file.
BASELINE_KIND = "xval-baseline"
#: Environment fields that decide whether timings measured on two machines compare.
MACHINE_FIELDS = ("cpu", "cpu_count", "machine")


@dataclass(frozen=True)
class Baseline:
    """What a gate compares: per case key its entry, and where the entries came from.

    suite : name, fingerprint, path of the suite; created : when it was made; results :
    started, git_commit, xval_version of the run; machine : MACHINE_FIELDS of the machine it
    ran on; engines : engine name -> version; window : the history runs it was made of (None:
    one results directory).
    """

    suite: Mapping[str, Any]
    cases: Mapping[str, BaselineEntry]
    created: str | None = None
    results: Mapping[str, Any] = field(default_factory=dict)
    machine: Mapping[str, Any] = field(default_factory=dict)
    engines: Mapping[str, Any] = field(default_factory=dict)
    window: tuple[int, ...] | None = None

    def to_json(self) -> dict[str, Any]:
        """The baseline file's document."""
        document = {
            "kind": BASELINE_KIND, "schema_version": BASELINE_SCHEMA_VERSION, "suite": dict(self.suite),
            "created": self.created, "results": dict(self.results), "machine": dict(self.machine),
            "engines": dict(self.engines), "cases": {key: entry.to_json() for key, entry in self.cases.items()},
        }
        if self.window is not None:
            document["window"] = list(self.window)
        return jsonable(document)

    @classmethod
    def of_run(cls, header: Mapping[str, Any], cases: Mapping[str, BaselineEntry], created: str | None,
               window: tuple[int, ...] | None = None) -> "Baseline":
        """A baseline of ``cases`` that says it came from the run whose run.json is ``header``: a results
        directory's (build_baseline) or a stored run's (compare.history.store.StoredRun.as_baseline)."""
        environment = header.get("environment") or {}
        return cls(
            suite={k: (header.get("suite") or {}).get(k) for k in ("name", "fingerprint", "path")},
            cases=cases,
            created=created,
            results={
                "started": header.get("started"),
                "git_commit": environment.get("git_commit"),
                "xval_version": header.get("xval_version"),
            },
            machine={k: environment.get(k) for k in MACHINE_FIELDS},
            engines=environment.get("engines", {}),
            window=window,
        )

    @classmethod
    def from_json(cls, document: dict[str, Any], where: str) -> "Baseline":
        """Type a baseline document whose kind and version were checked; EntryError naming a damaged entry."""
        window = document.get("window")
        return cls(
            suite=document["suite"],
            cases={key: BaselineEntry.from_json(entry, f"{where}: case {key}") for key, entry in document["cases"].items()},
            created=document.get("created"), results=document.get("results") or {},
            machine=document.get("machine") or {}, engines=document.get("engines") or {},
            window=None if window is None else tuple(int(i) for i in window),
        )


def entries(results: Results) -> dict[str, BaselineEntry]:
    """Baseline entries of every case in ``results``, keyed by ``case_key``, in the suite's order."""
    out: dict[str, BaselineEntry] = {}
    for sweep in results.sweeps():
        for record in sweep.records:
            out[record_key(record)] = entry_of(record, results.header, sweep)
    return out


def build_baseline(results: Results, then: str = "make the baseline") -> Baseline:
    """The baseline of a finished results directory.

    An unfinished run is refused (UserError ending "then ``then``"): its
    absent cases would otherwise be silently missing from a baseline, or
    reported missing by a gate that should have failed the interrupted job.
    """
    header = results.header
    if not header.get("finished"):
        raise UserError(
            f"{results.path}: the run is unfinished; finish it first "
            f"(xval run SUITE --output {results.path} --resume), then {then}"
        )
    return Baseline.of_run(header, entries(results), now())


def write_baseline(baseline: Baseline, path: str | Path) -> None:
    # indent=1 and sorted keys: a regenerated baseline diffs line by line in review.
    atomic_write_text(path, json.dumps(baseline.to_json(), indent=1, sort_keys=True, allow_nan=False) + "\n")


REMAKE = "make it again with 'xval baseline DIR --output {path}' from a results directory of the suite"


def load_baseline(path: str | Path) -> Baseline:
    """Read and check a baseline file; UserError naming the file and the fix for anything else."""
    path = Path(path)
    fix = REMAKE.format(path=path)
    # A results directory passed for its baseline: remaking the baseline at that path would not do.
    text = read_user_text(path, f"--baseline: {path}", fix,
                          directory_fix="give the baseline JSON file (xval baseline DIR --output FILE)")
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"--baseline: {path}: not valid JSON ({exc.msg} at line {exc.lineno}); {fix}") from None
    if not isinstance(document, dict) or document.get("kind") != BASELINE_KIND:
        raise UserError(f"--baseline: {path}: not an xval baseline (no \"kind\": \"{BASELINE_KIND}\"); {fix}")
    version = document.get("schema_version")
    if version != BASELINE_SCHEMA_VERSION:
        raise UserError(
            f"--baseline: {path}: baseline schema version {version!r}, but this xval reads version "
            f"{BASELINE_SCHEMA_VERSION}; {fix}"
        )
    if not isinstance(document.get("cases"), dict) or not isinstance(document.get("suite"), dict):
        raise UserError(f"--baseline: {path}: the baseline has no cases or suite; {fix}")
    try:
        return Baseline.from_json(document, f"--baseline: {path}")
    except EntryError as exc:
        raise UserError(f"{exc}; {fix}") from None
