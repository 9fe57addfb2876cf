"""The case record: one frozen, validated object per case, and the status a case can end in.

The runner builds a CaseRecord and writes :meth:`CaseRecord.to_json`; a case
file (``DIR/cases/<id>.json``) is read once, by :meth:`CaseRecord.from_json`.
Everything downstream — show, report, baseline, gate, history, stability —
works on these objects, never on the raw dict, so a misspelt field is an
AttributeError at once, not a silent None.

Details: docs/running.md, "Module notes", ``compare/results/record.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, TypedDict, Union

from engines.errors import UserError
from engines.scene.trajectory import Status  # the one status enum, from an engine's RunInfo up to the record
from engines.stdio import EngineOutput

from compare.results.declared import METRICS, current_names
from compare.results.series import SeriesView

#: Version of run.json and every case record; bump it when a field changes meaning.
SCHEMA_VERSION = 1


#: The statuses of a case that went wrong: listed as problems, counted as not ok while running, and
#: a regression when the baseline's case was ok.
PROBLEMS = (Status.UNSTABLE, Status.FAILED, Status.TIMEOUT)


def status_counts(records: Iterable["CaseRecord"]) -> dict[str, int]:
    """Cases per status (its JSON spelling), in Status order (ok, unstable, failed, timeout, skipped);
    statuses with no case are left out."""
    counts = {status.value: 0 for status in Status}
    for record in records:
        counts[record.status.value] += 1
    return {status: n for status, n in counts.items() if n}


class RecordError(UserError):
    """A case file that is damaged, foreign, or of another schema version; the message names the file."""


def check_schema(data: Any, path: str | Path) -> None:
    """RecordError naming ``path`` unless ``data`` (a case record or run.json) has this xval's schema version."""
    version = data.get("schema_version") if isinstance(data, dict) else None
    if version != SCHEMA_VERSION:
        raise RecordError(
            f"{path}: results schema version {version!r}, but this xval reads version {SCHEMA_VERSION}; "
            f"re-run the suite with this xval (xval run SUITE --output NEW_DIR)"
        )


#: A metric's value as stored: a number, a flag (``complete``), or None (not measured, or not finite).
MetricValue = Union[float, int, bool, None]


class RunInfoFields(TypedDict, total=False):
    """A record's ``run_info``: engines.scene.trajectory.RunInfo.to_dict() as stored (JSON values)."""

    engine: str
    variant: str
    engine_version: str
    dt: float
    steps: int
    wall_time: float
    status: str
    message: str
    #: Free-form: the engine's own option names and values (and ``override.*``, what the adapter changed).
    settings: dict[str, Any]
    cpu_time: float


class ReferenceFields(TypedDict, total=False):
    """A record's ``reference``: how the scene's reference was solved, and its own error bar.

    rtol, atol : the solve's tolerances; steps : its steps; wall_time : s. With a bound (the
    tighter second solve): reference_error (m), tight_rtol, horizon_threshold (m),
    reference_horizon_interval ([low, high] s), lyapunov_exponent (1/s, the ensemble's median; None when
    the scene is not chaotic) and lyapunov_interval ([low, high] 1/s).
    """

    rtol: float
    atol: float
    steps: int
    wall_time: float
    reference_error: float
    tight_rtol: float
    horizon_threshold: float
    reference_horizon_interval: list[float] | None
    lyapunov_exponent: float | None
    lyapunov_interval: list[float] | None


@dataclass(frozen=True)
class CaseKey:
    """What identifies a case.

    id : ``scene|engine|dt=…`` (unique in a run). scene_id : the suite's id of the scene;
    scene_name : the catalog scene it builds. engine : the label shown (``mujoco/hinge``,
    ``ours/baumgarte-rk4[k_s=…]``); engine_id : what the registry resolves; variant : the
    engine's variant; options : engine options (JSON values). dt : s; tolerance : for
    error-controlled cases, else None. position : (scene, engine, dt) indices in suite order.
    """

    id: str
    scene_id: str
    scene_name: str
    engine: str
    engine_id: str
    variant: str | None
    options: Mapping[str, Any]
    dt: float
    position: tuple[int, ...] = (0, 0, 0)
    tolerance: float | None = None


@dataclass(frozen=True)
class Characteristic:
    """length : L, m (sum of rod lengths or wire radius); energy : E* = total mass · g · L, J."""

    length: float
    energy: float


@dataclass(frozen=True)
class CaseRecord:
    """One case as stored. ``metrics`` maps declared metric names to values (empty when not run).

    consistent : per scene × variant from its dt sweep (see compare.results.consistency):
        True = the error still falls towards the reference or is under the tolerance;
        False = it stopped falling above the tolerance (converges to something else);
        None = fewer than two ok dts, or not judged. consistency : the one-line reason.
    reference_horizon : s, the time the reference's own two solves part by more than the
        stated fraction of the tolerance (None: they agree over the whole run).
    cpu_times : s of CPU of the stepping loop per repeat; calibrations : s of CPU of the
        calibration kernel timed beside each repeat (what the timing gate compares). None: not
        recorded (a skipped case, or a file older than them).
    series : name -> values; a record the runner holds keeps its rounded arrays in a SeriesView.
    engine_output : what the engine's library printed during the case (engines.stdio.EngineOutput.to_dict:
        ``lines``, ``first``, ``last``), captured in its case host; None when it printed nothing.
    scene : free-form, the scene's own document (engines.scene.scene.Scene.to_dict()), kept for the report.
    extra : free-form, fields of the file this xval does not know (kept, written back as they were).
    """

    case: CaseKey
    status: Status
    message: str
    metrics: Mapping[str, MetricValue]
    run_info: RunInfoFields | None
    wall_times: tuple[float, ...]
    elapsed: float
    scene: Mapping[str, Any]
    scene_hash: str
    characteristic: Characteristic
    series: Mapping[str, Any] | None
    reference: ReferenceFields | None
    finished: str
    consistent: bool | None = None
    consistency: str = ""
    reference_horizon: float | None = None
    cpu_times: tuple[float | None, ...] | None = None
    calibrations: tuple[float | None, ...] | None = None
    engine_output: Mapping[str, Any] | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    # -- views ------------------------------------------------------------------------------

    @property
    def ok(self) -> bool:
        return self.status is Status.OK

    @property
    def dt(self) -> float:
        return self.case.dt

    @property
    def engine(self) -> str:
        return self.case.engine

    @property
    def scene_id(self) -> str:
        return self.case.scene_id

    @property
    def engine_version(self) -> str | None:
        return (self.run_info or {}).get("engine_version")

    @property
    def has_metrics(self) -> bool:
        return bool(self.metrics)

    def metric(self, name: str) -> Any:
        """The value of declared metric ``name`` (None when this case has none); KeyError for an undeclared name."""
        if name not in METRICS and name not in ("n_samples", "complete"):
            raise KeyError(f"{name!r} is not a declared metric (compare/results/declared.py)")
        return self.metrics.get(name)

    # -- JSON -------------------------------------------------------------------------------

    def to_json(self, *, arrays: bool = False) -> dict[str, Any]:
        """The JSON document: what the runner writes, schema_version included.

        arrays : a SeriesView's series as its float arrays (for a writer that serialises numpy,
            as ResultsDir.write_case does), not as lists of Python floats.
        """
        if isinstance(self.series, SeriesView):
            series: Any = self.series.arrays if arrays else {name: self.series[name] for name in self.series}
        else:
            series = None if self.series is None else dict(self.series)
        case = {
            "id": self.case.id, "scene_id": self.case.scene_id, "scene_name": self.case.scene_name,
            "engine": self.case.engine, "engine_id": self.case.engine_id, "variant": self.case.variant,
            "options": dict(self.case.options), "dt": self.case.dt, "position": list(self.case.position),
        }
        if self.case.tolerance is not None:
            case["tolerance"] = self.case.tolerance
        document = {
            "schema_version": SCHEMA_VERSION,
            "case": case,
            "status": self.status.value,
            "message": self.message,
            "metrics": dict(self.metrics) if self.metrics else None,
            "run_info": None if self.run_info is None else dict(self.run_info),
            "wall_times": list(self.wall_times),
            "elapsed": self.elapsed,
            "scene": dict(self.scene),
            "scene_hash": self.scene_hash,
            "characteristic": {"length": self.characteristic.length, "energy": self.characteristic.energy},
            "series": series,
            "reference": None if self.reference is None else dict(self.reference),
            "finished": self.finished,
            **dict(self.extra),
        }
        if self.consistent is not None or self.consistency:
            document["consistent"] = self.consistent
            document["consistency"] = self.consistency
        if self.reference_horizon is not None:
            document["reference_horizon"] = self.reference_horizon
        if self.cpu_times is not None:
            document["cpu_times"] = list(self.cpu_times)
        if self.calibrations is not None:
            document["calibrations"] = list(self.calibrations)
        if self.engine_output is not None:
            document["engine_output"] = dict(self.engine_output)
        return document

    @classmethod
    def from_json(cls, data: Any, path: str | Path = "<record>") -> "CaseRecord":
        """Validate and type one case document; RecordError naming ``path`` and the field otherwise."""
        where = str(path)
        if not isinstance(data, dict):
            raise RecordError(f"{where}: not a case record (a JSON object expected, got {type(data).__name__})")
        check_schema(data, where)
        reader = _FieldReader(where)
        case = reader.mapping(data, "case")
        key = CaseKey(
            id=reader.text(case, "case.id"),
            scene_id=reader.text(case, "case.scene_id"),
            scene_name=reader.text(case, "case.scene_name"),
            engine=reader.text(case, "case.engine"),
            engine_id=reader.text(case, "case.engine_id"),
            variant=reader.optional_text(case, "case.variant"),
            options=reader.mapping(case, "case.options"),
            dt=reader.number(case, "case.dt"),
            position=tuple(int(i) for i in reader.sequence(case, "case.position", default=(0, 0, 0))),
            tolerance=reader.optional_number(case, "case.tolerance"),
        )
        raw_status = data.get("status")
        try:
            status = Status(raw_status)
        except ValueError:
            choices = ", ".join(s.value for s in Status)
            raise RecordError(f"{where}: field status is {raw_status!r}; expected one of {choices}") from None
        metrics = data.get("metrics") or {}
        if not isinstance(metrics, dict):
            raise RecordError(f"{where}: field metrics must be an object or null, got {type(metrics).__name__}")
        for name, value in metrics.items():
            if value is not None and not isinstance(value, (int, float, bool)):
                raise RecordError(f"{where}: metric {name} must be a number or null, got {value!r}")
        characteristic = reader.mapping(data, "characteristic")
        known = set(_KNOWN_FIELDS)
        consistent = data.get("consistent")
        if consistent is not None and not isinstance(consistent, bool):
            raise RecordError(f"{where}: field consistent must be true, false or null, got {consistent!r}")
        return cls(
            case=key,
            status=status,
            message=str(data.get("message") or ""),
            metrics=current_names(metrics),  # the names an earlier release wrote read as today's
            run_info=reader.optional_mapping(data, "run_info"),  # type: ignore[arg-type]
            wall_times=tuple(float(w) for w in reader.sequence(data, "wall_times", default=())),
            elapsed=float(data.get("elapsed") or 0.0),
            scene=reader.mapping(data, "scene"),
            scene_hash=reader.text(data, "scene_hash"),
            characteristic=Characteristic(
                reader.number(characteristic, "characteristic.length"),
                reader.number(characteristic, "characteristic.energy"),
            ),
            series=reader.optional_mapping(data, "series"),
            reference=reader.optional_mapping(data, "reference"),  # type: ignore[arg-type]
            finished=str(data.get("finished") or ""),
            consistent=consistent,
            consistency=str(data.get("consistency") or ""),
            reference_horizon=reader.optional_number(data, "reference_horizon"),
            cpu_times=reader.optional_numbers(data, "cpu_times"),
            calibrations=reader.optional_numbers(data, "calibrations"),
            engine_output=reader.optional_mapping(data, "engine_output"),
            extra={k: v for k, v in data.items() if k not in known},
        )


def engine_output_lines(record: CaseRecord) -> list[str]:
    """What ``record``'s engine printed, as kept (``engine printed N lines:``, first lines, … , last lines); []
    when it printed nothing."""
    output = EngineOutput.of(record.engine_output)
    if not output:
        return []
    return [f"engine printed {output.lines} line{'s' if output.lines != 1 else ''}:", *output.describe()]


_KNOWN_FIELDS = (
    "schema_version", "case", "status", "message", "metrics", "run_info", "wall_times", "elapsed", "scene",
    "scene_hash", "characteristic", "series", "reference", "finished", "consistent", "consistency",
    "reference_horizon", "cpu_times", "calibrations", "engine_output",
)


class _FieldReader:
    """Typed access to a record's fields; every mistake is a RecordError naming the file and the field."""

    def __init__(self, where: str) -> None:
        self.where = where

    def _get(self, data: Mapping[str, Any], dotted: str) -> Any:
        key = dotted.rsplit(".", 1)[-1]
        if key not in data:
            raise RecordError(f"{self.where}: missing field {dotted}; the file is damaged or not an xval case record")
        return data[key]

    def _wrong(self, dotted: str, want: str, value: Any) -> RecordError:
        return RecordError(f"{self.where}: field {dotted} must be {want}, got {value!r}"[:300])

    def _of_type(self, data: Mapping[str, Any], dotted: str, kind: type, want: str, optional: bool) -> Any:
        """The field, checked to be a ``kind`` (``want`` names it in the error); None when ``optional`` and null."""
        if not optional:
            value = self._get(data, dotted)
        elif (value := data.get(dotted.rsplit(".", 1)[-1])) is None:
            return None
        if not isinstance(value, kind):
            raise self._wrong(dotted, want + (" or null" if optional else ""), value)
        return value

    def mapping(self, data: Mapping[str, Any], dotted: str) -> dict[str, Any]:
        return self._of_type(data, dotted, dict, "an object", optional=False)

    def optional_mapping(self, data: Mapping[str, Any], dotted: str) -> dict[str, Any] | None:
        return self._of_type(data, dotted, dict, "an object", optional=True)

    def text(self, data: Mapping[str, Any], dotted: str) -> str:
        return self._of_type(data, dotted, str, "a string", optional=False)

    def optional_text(self, data: Mapping[str, Any], dotted: str) -> str | None:
        return self._of_type(data, dotted, str, "a string", optional=True)

    def number(self, data: Mapping[str, Any], dotted: str) -> float:
        value = self._get(data, dotted)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self._wrong(dotted, "a finite number", value)
        return float(value)

    def optional_number(self, data: Mapping[str, Any], dotted: str) -> float | None:
        value = data.get(dotted.rsplit(".", 1)[-1])
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._wrong(dotted, "a number or null", value)
        return float(value)

    def optional_numbers(self, data: Mapping[str, Any], dotted: str) -> tuple[float | None, ...] | None:
        """A list of numbers (null where one was not finite), kept as written; None when absent."""
        value = data.get(dotted.rsplit(".", 1)[-1])
        if value is None:
            return None
        if not isinstance(value, list) or any(v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)))
                                              for v in value):
            raise self._wrong(dotted, "a list of numbers or null", value)
        return tuple(value)

    def sequence(self, data: Mapping[str, Any], dotted: str, default: Any) -> list[Any]:
        value = data.get(dotted.rsplit(".", 1)[-1], default)
        if not isinstance(value, (list, tuple)):
            raise self._wrong(dotted, "a list", value)
        return list(value)
