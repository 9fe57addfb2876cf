"""Baselines: the gate-relevant part of a results directory, in one small versioned JSON file.

A baseline keeps, per case, what a later run is compared with:

- the case's identity: scene id and content hash, engine label, engine id,
  variant, options and dt (``case_key`` joins them; a scene edited without
  renaming gets a new hash, so it is reported as changed, not compared);
- the engine version that produced it (another version is "not comparable");
- status and message;
- the deterministic metrics (``compare.suite.tolerance.RULES``: errors, drifts,
  constraint errors, divergence time, the sweep's observed order);
- the timing: median cost per simulated second and the per-repeat costs, so
  the gate can tell a slowdown from the spread of the repeats.

Series, scenes and references are left out: a baseline of a large suite stays
a few hundred bytes per case and diffs readably in review.

File layout (``BASELINE_SCHEMA_VERSION``)::

    {"kind": "xval-baseline", "schema_version": 1,
     "suite": {"name", "fingerprint", "path"}, "created", "results": {...},
     "machine": {"cpu", "cpu_count", "machine"}, "engines": {name: version},
     "cases": {case_key: entry, ...}}
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from engines.errors import UserError

from compare.results.files import atomic_write_text
from compare.results.record import CaseKey, CaseRecord
from compare.results.store import Results, jsonable, now
from compare.results.sweep import VariantSweep
from compare.suite.tolerance import RULES, TIMING_METRIC

#: Bump when a field of the baseline file changes meaning.
BASELINE_SCHEMA_VERSION = 1
#: The ``kind`` that tells a baseline from any other JSON file.
BASELINE_KIND = "xval-baseline"
#: Environment fields that decide whether timings measured on two machines compare.
MACHINE_FIELDS = ("cpu", "cpu_count", "machine")


def case_key(case: CaseKey | dict[str, Any], scene_hash: str) -> str:
    """The key a case is stored and matched under: scene id and content hash, engine, variant, options, dt.

    case : a record's CaseKey, or a baseline entry (a dict with the same fields).
    The scene id is part of it so two scenes with identical content (a
    suite may list one scene twice under different ids) stay distinct.
    """
    if isinstance(case, CaseKey):
        scene_id, engine, variant, options, dt = case.scene_id, case.engine, case.variant, case.options, case.dt
    else:
        scene_id, engine, variant, options, dt = (
            case["scene_id"], case["engine"], case.get("variant"), case.get("options"), case["dt"]
        )
    text = json.dumps(dict(options or {}), sort_keys=True, separators=(",", ":"))
    return f"{scene_id}#{scene_hash}|{engine}|{variant}|{text}|dt={dt:.12g}"


def case_name(entry: dict[str, Any]) -> str:
    """``scene · engine · dt=…``: how a case is named in tables, JUnit and Markdown."""
    return f"{entry['scene_id']} · {entry['engine']} · dt={entry['dt']:.3g}"


def engine_version(record: CaseRecord, header: dict[str, Any]) -> str | None:
    """The version of the engine that ran ``record``: from its RunInfo, else (skipped cases) from run.json."""
    if record.engine_version:
        return record.engine_version
    engine_name = record.case.engine_id.split("/")[0]
    return (header.get("environment") or {}).get("engines", {}).get(engine_name)


def _timing(record: CaseRecord) -> dict[str, Any] | None:
    """Median cost (s per simulated s) and the cost of every repeat, or None without timings."""
    cost, wall = record.metrics.get(TIMING_METRIC), record.metrics.get("wall_time")
    repeats = record.wall_times
    if cost is None or not wall or not repeats:
        return None
    # Each repeat stepped the same simulated time, so cost scales with wall time.
    per_repeat = [w * cost / wall for w in repeats]
    timing = {"cost": cost, "repeats": per_repeat, "spread": [min(per_repeat), max(per_repeat)]}
    cpu_times = record.extra.get("cpu_times") or []
    calibrations = record.extra.get("calibrations") or []
    if (len(cpu_times) == len(calibrations) == len(repeats)
            and all(isinstance(c, (int, float)) and c > 0 for c in [*cpu_times, *calibrations])):
        # CPU s per simulated s of each repeat, and the calibration kernel's CPU s timed beside it:
        # what the timing gate compares when both sides have them.
        timing["cpu"] = [c * cost / wall for c in cpu_times]
        timing["calibration"] = list(calibrations)
    return timing


def entry_from_record(record: CaseRecord, header: dict[str, Any], sweep: VariantSweep | None = None) -> dict[str, Any]:
    """The baseline entry of one case record; ``sweep`` gives its variant's order and consistency."""
    case = record.case
    metrics = dict(record.metrics)
    metrics["observed_order"] = sweep.order.order if sweep is not None and sweep.order else None
    verdict = sweep.consistency if sweep is not None else None
    return {
        "scene_id": case.scene_id,
        "scene_hash": record.scene_hash,
        "engine": case.engine,
        "engine_id": case.engine_id,
        "variant": case.variant,
        "options": dict(case.options),
        "dt": case.dt,
        "position": list(case.position),
        "engine_version": engine_version(record, header),
        "status": record.status.value,
        "message": record.message,
        "metrics": {name: metrics.get(name) for name in RULES} if record.has_metrics else None,
        "consistent": verdict.consistent if verdict else None,
        "consistency": verdict.reason if verdict else "",
        "timing": _timing(record),
    }


def entries(results: Results) -> dict[str, dict[str, Any]]:
    """Baseline entries of every case in ``results``, keyed by ``case_key``, in the suite's order."""
    out: dict[str, dict[str, Any]] = {}
    for sweep in results.sweeps():
        for record in sweep.records:
            out[case_key(record.case, record.scene_hash)] = entry_from_record(record, results.header, sweep)
    return out


def build_baseline(results: Results, then: str = "make the baseline") -> dict[str, Any]:
    """The baseline document of a finished results directory.

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
    environment = header.get("environment") or {}
    return jsonable(
        {
            "kind": BASELINE_KIND,
            "schema_version": BASELINE_SCHEMA_VERSION,
            "suite": {k: header["suite"].get(k) for k in ("name", "fingerprint", "path")},
            "created": now(),
            "results": {
                "started": header.get("started"),
                "git_commit": environment.get("git_commit"),
                "xval_version": header.get("xval_version"),
            },
            "machine": {k: environment.get(k) for k in MACHINE_FIELDS},
            "engines": environment.get("engines", {}),
            "cases": entries(results),
        }
    )


def write_baseline(document: dict[str, Any], path: str | Path) -> None:
    # indent=1 and sorted keys: a regenerated baseline diffs line by line in review.
    atomic_write_text(path, json.dumps(document, indent=1, sort_keys=True, allow_nan=False) + "\n")


REMAKE = "make it again with 'xval baseline DIR --output {path}' from a results directory of the suite"


def load_baseline(path: str | Path) -> dict[str, Any]:
    """Read and check a baseline file; UserError naming the file and the fix for anything else."""
    path = Path(path)
    fix = REMAKE.format(path=path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"--baseline: {path}: no such file; {fix}") from None
    except UnicodeDecodeError as exc:
        raise UserError(f"--baseline: {path}: not UTF-8 text (byte {exc.start}), so not an xval baseline; {fix}") from None
    except IsADirectoryError:
        raise UserError(f"--baseline: {path} is a directory; give the baseline JSON file (xval baseline DIR --output FILE)") from None
    except OSError as exc:
        raise UserError(f"--baseline: {path}: cannot read it ({exc.strerror})") from None
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
    return document
