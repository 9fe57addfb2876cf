"""Stability search: per scene × engine variant, the largest time step at which a run stays ``ok``.

Criterion (the same one ``xval run`` applies to every case, see
:func:`compare.results.metrics.apply_bounds`): a probe at time step dt is *stable*
when the engine delivers every scheduled sample over the scene's duration
with a finite state, its energy drift stays ≤ ``bounds.energy_drift`` · E*
and its constraint error ≤ ``bounds.constraint_error`` · L. Anything else
(non-finite state, a bound exceeded, the engine raised, died or timed out)
is not stable.

Search (per pair, :func:`search`): probe ``dt_max``; if it is stable the
pair is ``stable-at-largest``. Otherwise step down by ``bracket_factor``
(√10: two probes per decade) until a probe is stable (then bisect on a log
scale between the stable and the unstable dt until their ratio is ≤
``resolution``, 1.1 = 10 % in dt) or ``dt_min`` is reached unstable
(``unstable-at-smallest``). The search assumes one boundary: a variant
stable at dt but not at some dt' < dt (a chaotic scene whose drift crosses
a bound by chance) is reported at the first boundary found, and every
probe is kept so the report can show it.

Every probe runs through :func:`compare.run.isolation.execute` (a forked case
host per thread), so a crash or a hang costs that probe only. Pairs run in
parallel on ``jobs`` threads; each pair's probes are sequential (each one
depends on the last). Results go to ``DIR/stability.json`` (versioned,
rewritten atomically after each pair, so a stopped search keeps what it
found).
"""

from __future__ import annotations

import concurrent.futures as cf
import fnmatch
import json
import math
import time
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from engines.adapter import Schedule
from engines.errors import UserError

from compare.results.files import atomic_write_text
from compare.run.isolation import CaseOutcome, CaseTask, execute
from compare.results.metrics import Bounds, apply_bounds, case_metrics
from compare.results.store import jsonable, now
from compare.run.runner import compare_version, default_jobs, skip_reason
from compare.suite.reader import EngineSpec, SceneSpec, Suite, _Reader

#: File the search writes in its output directory, and its format.
FILE_NAME = "stability.json"
SCHEMA = "xval-stability"
SCHEMA_VERSION = 1
#: Verdicts of one pair.
BOUNDED, STABLE_AT_LARGEST, UNSTABLE_AT_SMALLEST, SKIPPED = (
    "bounded", "stable-at-largest", "unstable-at-smallest", "skipped",
)
#: Keys of a suite's optional ``[stability]`` table.
STABILITY_KEYS = ("scenes", "engines", "dt_max", "dt_min", "bracket_factor", "resolution", "sample_interval")


def criterion_text(bounds: Bounds) -> str:
    """The stability criterion in words, stored with the results and shown in the report."""
    return (
        "stable at dt = every scheduled sample delivered over the scene's duration with a finite state, "
        f"energy drift ≤ {bounds.energy_drift:g} E* and constraint error ≤ {bounds.constraint_error:g} L; "
        "unstable = a non-finite state, a bound exceeded, or the engine failed or timed out"
    )


@dataclass(frozen=True)
class SearchSettings:
    """Where and how finely to search.

    dt_max, dt_min : s, the largest and smallest time step probed.
    bracket_factor : ratio between successive probes while stepping down (> 1).
    resolution : the search stops when (smallest unstable dt) / (largest stable dt) ≤ resolution (> 1).
    sample_interval : s between the samples the bounds are checked on (None: the suite's).
    """

    dt_max: float
    dt_min: float
    bracket_factor: float = math.sqrt(10.0)
    resolution: float = 1.1
    sample_interval: float | None = None


@dataclass(frozen=True)
class Probe:
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


@dataclass(frozen=True)
class PairResult:
    """The search's answer for one scene × engine variant.

    verdict : bounded, stable-at-largest, unstable-at-smallest or skipped.
    largest_stable_dt : s, the largest dt found stable (None when none was).
    smallest_unstable_dt : s, the smallest dt found unstable above it (None when none was).
    analytic_dt : s, the linear theory's limit where one exists (ours/baumgarte), else None.
    probes : in the order they ran.
    """

    scene_id: str
    engine: str
    verdict: str
    largest_stable_dt: float | None = None
    smallest_unstable_dt: float | None = None
    reason: str = ""
    analytic_dt: float | None = None
    probes: tuple[Probe, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return jsonable(asdict(self))


# -- the search itself (pure: the probe is a function of dt) ---------------------------------


def search(probe: Callable[[float], Probe], settings: SearchSettings) -> tuple[str, float | None, float | None, list[Probe]]:
    """(verdict, largest stable dt, smallest unstable dt, probes) for one pair; see the module docstring."""
    probes: list[Probe] = []

    def stable(dt: float) -> bool:
        result = probe(dt)
        probes.append(result)
        return result.stable

    if stable(settings.dt_max):
        return STABLE_AT_LARGEST, settings.dt_max, None, probes
    hi, lo = settings.dt_max, None
    while lo is None:
        if hi <= settings.dt_min * (1 + 1e-12):
            return UNSTABLE_AT_SMALLEST, None, hi, probes
        dt = max(hi / settings.bracket_factor, settings.dt_min)
        if stable(dt):
            lo = dt
        else:
            hi = dt
    while hi / lo > settings.resolution * (1 + 1e-12):
        mid = math.sqrt(lo * hi)
        if stable(mid):
            lo = mid
        else:
            hi = mid
    return BOUNDED, lo, hi, probes


# -- one probe through the runner's isolation -------------------------------------------------


def run_probe(scene_spec: SceneSpec, engine: EngineSpec, dt: float, suite: Suite, timeout: float,
              sample_interval: float | None = None) -> Probe:
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
    )
    outcome: CaseOutcome = execute(task)
    return classify(scene, outcome, dt, sample_interval, suite.bounds)


def classify(scene, outcome: CaseOutcome, dt: float, sample_interval: float, bounds: Bounds) -> Probe:
    """The Probe of a finished case: the engine's status, then the suite's bounds (as ``xval run`` does)."""
    trajectory = outcome.trajectory
    if trajectory is None:
        return Probe(dt, outcome.status, outcome.message, elapsed=outcome.elapsed)
    status, message = trajectory.info.status, trajectory.info.message
    scheduled = Schedule.make(scene.duration, dt, sample_interval).times
    # Position metrics need the reference, which the criterion does not use: compare against NaN.
    no_reference = np.full((len(scheduled), len(scene.particles), 3), np.nan)
    metrics, _ = case_metrics(scene, trajectory, no_reference, None, scheduled_times=scheduled,
                              wall_times=outcome.wall_times)
    status, message = apply_bounds(status, message, metrics, bounds, scene)
    return Probe(dt, status, message, _finite_or_none(metrics.energy_drift),
                 _finite_or_none(metrics.constraint_error), outcome.elapsed)


def _finite_or_none(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


# -- configuration from the suite ----------------------------------------------------------------


@dataclass(frozen=True)
class StabilityPlan:
    """Which pairs to search and the settings; built from the suite and its optional ``[stability]`` table."""

    scenes: tuple[SceneSpec, ...]
    engines: tuple[EngineSpec, ...]
    settings: SearchSettings


def suite_table(suite: Suite, name: str, allowed: tuple[str, ...]) -> tuple[dict[str, Any] | None, _Reader]:
    """The suite file's optional table ``name`` (validated keys; None when absent) and a reader for line-numbered errors."""
    reader = _Reader(suite.path, suite.source)
    value = tomllib.loads(suite.source).get(name)
    return (None if value is None else reader.table(name, value, allowed)), reader


def plan_stability(suite: Suite) -> StabilityPlan:
    """Scenes, engine variants and dt range of the search.

    ``[stability]`` keys: ``scenes`` (ids, default all), ``engines`` (labels
    or shell patterns such as ``"ours/*"``, default all), ``dt_max`` and
    ``dt_min`` (s, default the suite's largest and smallest dt),
    ``bracket_factor`` (default √10), ``resolution`` (default 1.1),
    ``sample_interval`` (s, default the suite's: the samples the bounds are checked on).
    """
    table, reader = suite_table(suite, "stability", STABILITY_KEYS)
    table = table or {}
    scene_ids = table.get("scenes")
    scenes = suite.scenes
    if scene_ids is not None:
        known = {s.id: s for s in suite.scenes}
        if not isinstance(scene_ids, list) or not scene_ids:
            raise reader.error("stability.scenes", "must be a non-empty list of scene ids of this suite")
        for sid in scene_ids:
            if sid not in known:
                raise reader.error("stability.scenes", f"unknown scene id {sid!r}; this suite's are: {', '.join(known)}")
        scenes = tuple(known[sid] for sid in scene_ids)
    engines = suite.engines
    patterns = table.get("engines")
    if patterns is not None:
        if not isinstance(patterns, list) or not patterns or not all(isinstance(p, str) for p in patterns):
            raise reader.error("stability.engines", 'must be a non-empty list of labels or patterns, e.g. ["ours/*"]')
        for pattern in patterns:
            if not any(fnmatch.fnmatchcase(e.label, pattern) for e in suite.engines):
                raise reader.error("stability.engines", f"{pattern!r} matches no engine variant of this suite")
        engines = tuple(e for e in suite.engines if any(fnmatch.fnmatchcase(e.label, p) for p in patterns))
    dt_max = reader.number("stability.dt_max", table.get("dt_max", max(suite.dts)))
    dt_min = reader.number("stability.dt_min", table.get("dt_min", min(suite.dts)))
    if dt_min > dt_max:
        raise reader.error("stability.dt_min", f"{dt_min:g} s is larger than dt_max {dt_max:g} s; swap them")
    factor = reader.number("stability.bracket_factor", table.get("bracket_factor", math.sqrt(10.0)))
    resolution = reader.number("stability.resolution", table.get("resolution", 1.1))
    for key, value in (("bracket_factor", factor), ("resolution", resolution)):
        if value <= 1:
            raise reader.error(f"stability.{key}", f"must be larger than 1, got {value!r}")
    for spec in scenes:
        if dt_max > spec.scene.duration:
            raise reader.error("stability.dt_max", f"{dt_max:g} s is longer than scene {spec.id!r}'s duration "
                               f"{spec.scene.duration:g} s; lower dt_max or leave the scene out")
    interval = table.get("sample_interval")
    interval = None if interval is None else reader.number("stability.sample_interval", interval)
    return StabilityPlan(scenes, engines, SearchSettings(dt_max, dt_min, factor, resolution, interval))


# -- the analytic limit where the theory covers the variant ---------------------------------------


def analytic_dt(engine: EngineSpec) -> float | None:
    """s: the largest dt the linearized Baumgarte constraint dynamics allow, for ours/baumgarte-*; else None."""
    if engine.engine is None or engine.engine.name != "ours":
        return None
    settings = engine.engine.resolve(engine.variant, engine.options)
    if settings["method"] != "baumgarte":
        return None
    from compare.stability.gainmap import largest_stable_dt  # here: gainmap imports this module's helpers

    k_s = float(settings["k_s"])
    k_d = settings["k_d"]
    k_d = 2.0 * math.sqrt(k_s) if k_d is None else float(k_d)
    return largest_stable_dt(settings["integrator"], k_s, k_d)


# -- the output files (stability.json here, gainmap.json in compare.stability.gainmap) ----------------------

#: The command that rewrites either file, named in every error about one.
RERUN = "xval stability SUITE --output DIR --force"


def document_head(suite: Suite, schema: str, version: int) -> dict[str, Any]:
    """The fields both output files open with: format, suite, xval version and the bounds the probes were judged by."""
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


def load_document(directory: str | Path, name: str, schema: str, version: int) -> dict[str, Any] | None:
    """``directory/name`` as written by this module or gainmap; None when absent, UserError naming RERUN when unreadable."""
    file = Path(directory) / name
    if not file.exists():
        return None
    try:
        data = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"{file}: cannot read it ({exc}); rerun {RERUN}") from None
    if not isinstance(data, dict) or data.get("schema") != schema or data.get("schema_version") != version:
        found = data.get("schema_version") if isinstance(data, dict) else None
        raise UserError(f"{file}: {schema} version {found!r}, but this xval reads version {version}; rerun {RERUN}")
    return data


# -- running it -------------------------------------------------------------------------------


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


def run_stability(
    suite: Suite,
    output: str | Path,
    *,
    jobs: int | None = None,
    timeout: float | None = None,
    force: bool = False,
    on_pair: Callable[[PairResult], None] | None = None,
) -> Path:
    """Search every planned pair; write ``output/stability.json`` (after each pair) and return its path."""
    target = check_output(output, FILE_NAME, force)
    stability = plan_stability(suite)
    timeout = timeout or suite.timeout
    document: dict[str, Any] = {
        **document_head(suite, SCHEMA, SCHEMA_VERSION),
        "criterion": criterion_text(suite.bounds),
        "settings": asdict(stability.settings),
        "scenes": {s.id: {"name": s.name, "duration": s.scene.duration, "length": s.scene.characteristic_length}
                   for s in stability.scenes},
        "engines": [e.label for e in stability.engines],
        "started": now(),
        "finished": None,
        "results": [],
    }
    order = {(s.id, e.label): k for k, (s, e) in enumerate(
        (s, e) for s in stability.scenes for e in stability.engines)}

    def save() -> None:
        document["results"].sort(key=lambda r: order[(r["scene_id"], r["engine"])])
        write_document(target, document, indent=1)

    def one(scene: SceneSpec, engine: EngineSpec) -> PairResult:
        reason = skip_reason(scene.scene, engine)
        if reason is not None:
            return PairResult(scene.id, engine.label, SKIPPED, reason=reason)
        verdict, lo, hi, probes = search(
            lambda dt: run_probe(scene, engine, dt, suite, timeout, stability.settings.sample_interval),
            stability.settings,
        )
        last_unstable = next((p for p in reversed(probes) if not p.stable), None)
        why = "" if last_unstable is None else f"at dt = {last_unstable.dt:.4g} s: {last_unstable.status} ({last_unstable.message})"
        return PairResult(scene.id, engine.label, verdict, lo, hi, why, analytic_dt(engine), tuple(probes))

    save()
    pairs = [(s, e) for s in stability.scenes for e in stability.engines]
    # Threads, not processes: each thread only waits on its own case host (a forked child).
    with cf.ThreadPoolExecutor(max_workers=jobs or default_jobs()) as pool:
        futures = [pool.submit(one, s, e) for s, e in pairs]
        try:
            for future in cf.as_completed(futures):
                result = future.result()
                document["results"].append(result.to_dict())
                save()
                if on_pair is not None:
                    on_pair(result)
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    document["finished"] = now()
    save()
    return target


def load_stability(path: str | Path) -> dict[str, Any] | None:
    """The stability document in results directory ``path`` (None when it has none); UserError for another version."""
    return load_document(path, FILE_NAME, SCHEMA, SCHEMA_VERSION)
