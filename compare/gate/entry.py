"""A baseline entry: the part of one CaseRecord a gate compares, typed, and the one function that makes it.

A baseline file, the history's stored cases and the window of recent runs
all hold these entries; :func:`entry_of` derives one from a CaseRecord (and
its variant's sweep), :meth:`BaselineEntry.to_json` / :meth:`~BaselineEntry.from_json`
are its JSON (one object under a baseline's ``cases``, or a history row's
``entry``). Series, scenes and references are left out: an entry stays a few
hundred bytes and diffs readably in review.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Mapping

from engines.errors import UserError

from compare.results.declared import current_names
from compare.results.record import CaseRecord, Status
from compare.results.sweep import VariantSweep
from compare.suite.gate_rules import RULES, TIMING_METRIC


def case_key(scene_id: str, scene_hash: str, engine: str, variant: str | None, options: Mapping[str, Any] | None,
             dt: float) -> str:
    """The key a case is stored and matched under: scene id and content hash, engine, variant, options, dt.

    The scene id is part of it so two scenes with identical content (a suite
    may list one scene twice under different ids) stay distinct.
    """
    text = json.dumps(dict(options or {}), sort_keys=True, separators=(",", ":"))
    return f"{scene_id}#{scene_hash}|{engine}|{variant}|{text}|dt={dt:.12g}"


def record_key(record: CaseRecord) -> str:
    """The :func:`case_key` of a case record."""
    case = record.case
    return case_key(case.scene_id, record.scene_hash, case.engine, case.variant, case.options, case.dt)


def case_name(scene_id: str, engine: str, dt: float) -> str:
    """``scene · engine · dt=…``: how a case is named in tables, JUnit and Markdown."""
    return f"{scene_id} · {engine} · dt={dt:.3g}"


@dataclass(frozen=True)
class Timing:
    """A case's cost, s of stepping per simulated s.

    cost : the median over repeats (a window: the median of its runs' costs);
    repeats : each repeat's cost; spread : (min, max) of the repeats.
    cpu : each repeat's CPU cost, and calibration : the calibration kernel's CPU s timed beside
    it (None: not recorded; the gate then uses its wall-time rule).
    runs : how many runs a window's timing was made of (None for one run's).
    seconds : s of CPU of the case's fastest repeat (a window: the median over its runs), None when not
        recorded: how long the timed stepping lasted, which says whether one case's timing can be trusted.
    per_run : each run's calibrated cost, least CPU cost / least calibration (1/s of simulated time: CPU s per
        simulated s in units of the calibration kernel), oldest first; one value for one run's timing.
    """

    cost: float
    repeats: tuple[float, ...]
    spread: tuple[float, float]
    cpu: tuple[float, ...] | None = None
    calibration: tuple[float, ...] | None = None
    runs: int | None = None
    seconds: float | None = None
    per_run: tuple[float, ...] | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"cost": self.cost, "repeats": list(self.repeats), "spread": list(self.spread)}
        if self.cpu is not None and self.calibration is not None:
            out["cpu"], out["calibration"] = list(self.cpu), list(self.calibration)
        if self.runs is not None:
            out["runs"] = self.runs
        if self.seconds is not None:
            out["seconds"] = self.seconds
        if self.per_run is not None:
            out["per_run"] = list(self.per_run)
        return out

    @property
    def calibrated_runs(self) -> tuple[float, ...]:
        """:attr:`per_run`, or this one run's calibrated cost from cpu and calibration; () without them."""
        if self.per_run:
            return self.per_run
        if self.cpu and self.calibration:
            return (min(self.cpu) / min(self.calibration),)
        return ()

    @classmethod
    def from_json(cls, data: Any, where: str) -> "Timing":
        if not isinstance(data, dict):
            raise EntryError(f"{where}: field timing must be an object or null, got {data!r}"[:300])
        cpu, calibration = data.get("cpu"), data.get("calibration")
        runs, seconds, per_run = data.get("runs"), data.get("seconds"), data.get("per_run")
        return cls(
            cost=_number(data.get("cost"), f"{where}: field timing.cost"),
            repeats=_numbers(data.get("repeats", ()), f"{where}: field timing.repeats"),
            spread=_pair(data.get("spread"), f"{where}: field timing.spread"),
            cpu=None if cpu is None or calibration is None else _numbers(cpu, f"{where}: field timing.cpu"),
            calibration=None if cpu is None or calibration is None
            else _numbers(calibration, f"{where}: field timing.calibration"),
            runs=None if runs is None else int(_number(runs, f"{where}: field timing.runs")),
            seconds=None if seconds is None else _number(seconds, f"{where}: field timing.seconds"),
            per_run=None if per_run is None else _numbers(per_run, f"{where}: field timing.per_run"),
        )


class EntryError(UserError):
    """A baseline entry that is damaged or not one; the message names the file and the field."""


@dataclass(frozen=True)
class BaselineEntry:
    """One case as a baseline keeps it.

    The key's parts (scene id and content hash, engine label, engine id, variant, options, dt s),
    position : (scene, engine, dt) indices in suite order; engine_version : the engine that ran
    it (another version is "not comparable"); status, message; metrics : the gated metrics
    (compare.suite.gate_rules.RULES, observed_order among them), None when the case has none;
    consistent, consistency : its variant's verdict; timing : None when not timed.
    """

    scene_id: str
    scene_hash: str
    engine: str
    engine_id: str
    variant: str | None
    options: Mapping[str, Any]
    dt: float
    position: tuple[int, ...]
    engine_version: str | None
    status: Status
    message: str
    metrics: Mapping[str, Any] | None
    consistent: bool | None
    consistency: str
    timing: Timing | None

    @property
    def key(self) -> str:
        return case_key(self.scene_id, self.scene_hash, self.engine, self.variant, self.options, self.dt)

    def metric(self, name: str) -> Any:
        """The value of gated metric ``name``, None when absent."""
        return (self.metrics or {}).get(name)

    def to_json(self) -> dict[str, Any]:
        return {
            "scene_id": self.scene_id, "scene_hash": self.scene_hash, "engine": self.engine,
            "engine_id": self.engine_id, "variant": self.variant, "options": dict(self.options), "dt": self.dt,
            "position": list(self.position), "engine_version": self.engine_version, "status": self.status.value,
            "message": self.message, "metrics": None if self.metrics is None else dict(self.metrics),
            "consistent": self.consistent, "consistency": self.consistency,
            "timing": None if self.timing is None else self.timing.to_json(),
        }

    @classmethod
    def from_json(cls, data: Any, where: str) -> "BaselineEntry":
        """Type one entry; EntryError naming ``where`` and the field for anything else."""
        if not isinstance(data, dict):
            raise EntryError(f"{where}: not a baseline entry (an object expected, got {type(data).__name__})")

        def text(name: str, optional: bool = False) -> Any:
            value = data.get(name)
            if (value is None and not optional) or (value is not None and not isinstance(value, str)):
                raise EntryError(f"{where}: field {name} must be a string, got {value!r}"[:300])
            return value

        try:
            status = Status(data.get("status"))
        except ValueError:
            choices = ", ".join(s.value for s in Status)
            raise EntryError(f"{where}: field status is {data.get('status')!r}; expected one of {choices}") from None
        metrics, options = data.get("metrics"), data.get("options") or {}
        if metrics is not None and not (isinstance(metrics, dict) and all(
                v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in metrics.values())):
            raise EntryError(f"{where}: field metrics must be an object of numbers or null, got {metrics!r}"[:300])
        if not isinstance(options, dict):
            raise EntryError(f"{where}: field options must be an object, got {options!r}"[:300])
        consistent = data.get("consistent")
        if consistent is not None and not isinstance(consistent, bool):
            raise EntryError(f"{where}: field consistent must be true, false or null, got {consistent!r}")
        timing = data.get("timing")
        return cls(
            scene_id=text("scene_id"), scene_hash=text("scene_hash"), engine=text("engine"),
            engine_id=text("engine_id", optional=True) or text("engine"), variant=text("variant", optional=True),
            options=options, dt=_number(data.get("dt"), f"{where}: field dt"),
            position=tuple(int(i) for i in _numbers(data.get("position", (0, 0, 0)), f"{where}: field position")),
            engine_version=text("engine_version", optional=True), status=status,
            message=text("message", optional=True) or "", consistent=consistent,
            metrics=None if metrics is None else current_names(metrics),  # an earlier release's names as today's
            consistency=text("consistency", optional=True) or "",
            timing=None if timing is None else Timing.from_json(timing, where),
        )


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise EntryError(f"{what} must be a finite number, got {value!r}"[:300])
    return float(value)


def _numbers(values: Any, what: str) -> tuple[float, ...]:
    if not isinstance(values, (list, tuple)):
        raise EntryError(f"{what} must be a list of numbers, got {values!r}"[:300])
    return tuple(_number(v, what) for v in values)


def _pair(values: Any, what: str) -> tuple[float, float]:
    pair = _numbers(values, what)
    if len(pair) != 2:
        raise EntryError(f"{what} must be [min, max], got {values!r}"[:300])
    return pair[0], pair[1]


def engine_version(record: CaseRecord, header: Mapping[str, Any]) -> str | None:
    """The version of the engine that ran ``record``: from its RunInfo, else (skipped cases) from run.json."""
    if record.engine_version:
        return record.engine_version
    engine_name = record.case.engine_id.split("/")[0]
    return (header.get("environment") or {}).get("engines", {}).get(engine_name)


def timing_of(record: CaseRecord) -> Timing | None:
    """Median cost (s per simulated s) and the cost of every repeat, or None without timings."""
    cost, wall = record.metrics.get(TIMING_METRIC), record.metrics.get("wall_time")
    repeats = record.wall_times
    if cost is None or not wall or not repeats:
        return None
    # Each repeat stepped the same simulated time, so cost scales with wall time.
    per_repeat = tuple(w * cost / wall for w in repeats)
    cpu_times, calibrations = record.cpu_times or (), record.calibrations or ()
    if (len(cpu_times) == len(calibrations) == len(repeats)
            and all(isinstance(c, (int, float)) and c > 0 for c in [*cpu_times, *calibrations])):
        # CPU s per simulated s of each repeat, and the calibration kernel's CPU s timed beside it:
        # what the timing gate compares when both sides have them.
        return Timing(cost, per_repeat, (min(per_repeat), max(per_repeat)),
                      cpu=tuple(float(c) * cost / wall for c in cpu_times if c is not None),
                      calibration=tuple(float(c) for c in calibrations if c is not None),
                      seconds=float(min(c for c in cpu_times if c is not None)))
    return Timing(cost, per_repeat, (min(per_repeat), max(per_repeat)))


def entry_of(record: CaseRecord, header: Mapping[str, Any], sweep: VariantSweep | None = None) -> BaselineEntry:
    """The baseline entry of one case record (the one way a baseline or a history gets one).

    header : run.json of its results (the engine version of a skipped case); sweep : its variant's
    dt sweep, which gives the observed order and the consistency verdict.
    """
    case = record.case
    order = sweep.order.order if sweep is not None and sweep.order else None
    judged = sweep.consistency if sweep is not None else None
    metrics = {name: order if name == "observed_order" else record.metrics.get(name) for name in RULES}
    return BaselineEntry(
        scene_id=case.scene_id, scene_hash=record.scene_hash, engine=case.engine, engine_id=case.engine_id,
        variant=case.variant, options=dict(case.options), dt=case.dt, position=tuple(case.position),
        engine_version=engine_version(record, header), status=record.status, message=record.message,
        metrics=metrics if record.has_metrics else None,
        consistent=judged.consistent if judged else None, consistency=judged.reason if judged else "",
        timing=timing_of(record),
    )
