"""One trial (a run at one dt, judged by the suite's bounds) and the output files of the stability stage.

Shared by the stability search (:mod:`compare.stability.search`) and the gain
map (:mod:`compare.stability.gainmap`); neither imports the other.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from engines.adapter import Schedule
from engines.external.command import spec_of
from engines.errors import UserError

from engines.files import atomic_write_text
from compare.results.measure import CaseOutcome, CaseStatus, bounds_exceeded, decide_status
from compare.results.metrics import Bounds, case_metrics
from compare.results.store import jsonable
from compare.run.isolation import CaseTask, execute
from compare.run.runner import compare_version
from compare.suite.reader import EngineSpec, SceneSpec, Suite


@dataclass(frozen=True)
class Trial:
    """One run at one dt: status after the bounds, why, energy drift (E*), constraint error (m), elapsed (s)."""

    dt: float
    status: str
    message: str = ""
    energy_drift: float | None = None
    constraint_error: float | None = None
    elapsed: float = 0.0

    @property
    def stable(self) -> bool:
        return self.status == "ok"


# -- one trial through the runner's isolation -------------------------------------------------

#: A trial that timed out runs once more with this many times the limit; a second timeout decides nothing
#: (the search's pair is undecided, the gain map's cell blank), never unstable: a loaded machine is slow.
RETRY_FACTOR = 4.0



def run_trial(scene_spec: SceneSpec, engine: EngineSpec, dt: float, suite: Suite, timeout: float,
              sample_interval: float | None = None) -> Trial:
    """Simulate one (scene, variant) at ``dt`` (s) in a case host and classify it by the suite's bounds.

    sample_interval : s between samples (None: the suite's).
    """
    scene = scene_spec.scene
    sample_interval = sample_interval or suite.sample_interval
    task = CaseTask(
        case_id=f"stability|{scene_spec.id}|{engine.label}|dt={dt:.12g}",
        engine_id=engine.id,
        variant=engine.variant,
        options=dict(engine.options),
        scene=scene,
        dt=dt,
        sample_interval=sample_interval,
        repeats=1,
        timeout=timeout,
        command=spec_of(engine.engine),
    )
    outcome: CaseOutcome = execute(task)
    return classify(scene, outcome, dt, sample_interval, suite.bounds)


def timed_retry(trial: Callable[[float, float], Trial], timeout: float) -> Callable[[float], Trial]:
    """The trial at dt, run once more with RETRY_FACTOR × ``timeout`` (s) when it ran past ``timeout``: the
    second run's Trial (a ``timeout`` again says so in its message)."""
    def run(dt: float) -> Trial:
        first = trial(dt, timeout)
        if first.status != "timeout":
            return first
        second = trial(dt, RETRY_FACTOR * timeout)
        if second.status != "timeout":
            return second
        return replace(second, message=f"ran past {timeout:g} s, then past {RETRY_FACTOR * timeout:g} s: "
                                        f"undecided, not unstable")
    return run


def classify(scene, outcome: CaseOutcome, dt: float, sample_interval: float, bounds: Bounds) -> Trial:
    """The Trial of a finished case: the engine's status, then the suite's bounds (decided as ``xval run``
    decides a case's, by compare.results.measure.decide_status)."""
    trajectory = outcome.trajectory
    host = CaseStatus(outcome.status, outcome.message)
    if trajectory is None:
        status, message = decide_status(host=host)
        return Trial(dt, status.value, message, elapsed=outcome.elapsed)
    scheduled = Schedule.make(scene.duration, dt, sample_interval).times
    # Position metrics need the reference, which the criterion does not use: compare against NaN.
    no_reference = np.full((len(scheduled), len(scene.particles), 3), np.nan)
    metrics, _ = case_metrics(scene, trajectory, no_reference, None, scheduled_times=scheduled,
                              wall_times=outcome.wall_times)
    status, message = decide_status(host=host, run=CaseStatus(trajectory.info.status, trajectory.info.message),
                                    exceeded=bounds_exceeded(metrics, bounds, scene))
    return Trial(dt, status.value, message, _finite_or_none(metrics.energy_drift),
                 _finite_or_none(metrics.constraint_error), outcome.elapsed)


def _finite_or_none(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


# -- the output files (stability.json here, gainmap.json in compare.stability.gainmap) ----------------------

#: The command that rewrites either file, named in every error about one.
RERUN = "xval stability SUITE --output DIR --force"


def document_head(suite: Suite, schema: str, version: int) -> dict[str, Any]:
    """The fields both output files open with: format, suite, xval version and the bounds the trials were judged by."""
    return {
        "schema": schema,
        "schema_version": version,
        "suite": {"name": suite.name, "path": suite.path, "fingerprint": suite.fingerprint()},
        "xval_version": compare_version(),
        "bounds": {"energy_drift": suite.bounds.energy_drift, "constraint_error": suite.bounds.constraint_error},
    }


def write_document(target: Path, document: dict[str, Any], indent: int | None = None) -> None:
    """Write ``document`` to ``target`` atomically (a reader never sees half a file)."""
    atomic_write_text(target, json.dumps(jsonable(document), indent=indent, allow_nan=False) + "\n")


def load_document(directory: str | Path, name: str, schema: str, version: int,
                  upgrades: Mapping[int, Callable[[dict[str, Any]], dict[str, Any]]] | None = None,
                  ) -> dict[str, Any] | None:
    """``directory/name`` as written by this module or gainmap; None when absent, UserError naming RERUN when unreadable.

    upgrades : older version -> the function that turns such a document into one of ``version``.
    """
    file = Path(directory) / name
    if not file.exists():
        return None
    try:
        data = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"{file}: cannot read it ({exc}); rerun {RERUN}") from None
    if isinstance(data, dict) and data.get("schema") == schema and data.get("schema_version") in (upgrades or {}):
        data = (upgrades or {})[data["schema_version"]](data)
    if not isinstance(data, dict) or data.get("schema") != schema or data.get("schema_version") != version:
        found = data.get("schema_version") if isinstance(data, dict) else None
        raise UserError(f"{file}: {schema} version {found!r}, but this xval reads version {version}; rerun {RERUN}")
    return data


def check_output(output: str | Path, name: str, force: bool) -> Path:
    """The file ``output/name`` to write: the directory is created; an existing file needs ``force``."""
    directory = Path(output)
    if directory.exists() and not directory.is_dir():
        raise UserError(f"--output: {directory} is a file; give a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"--output: cannot create {directory} ({exc.strerror}); choose a writable directory") from None
    target = directory / name
    if target.exists() and not force:
        raise UserError(f"--output: {target} exists; pass --force to replace it, or choose another directory")
    return target
