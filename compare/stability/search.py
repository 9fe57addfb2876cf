"""Stability search: per scene × engine variant, the largest time step at which a run stays ``ok``.

Criterion (the same one ``xval run`` applies to every case, see
:func:`compare.results.measure.decide_status`): a trial at time step dt is *stable*
when the engine delivers every scheduled sample over the scene's duration
with a finite state, its energy drift stays ≤ ``bounds.energy_drift`` · E*
and its constraint error ≤ ``bounds.constraint_error`` · L. Anything else
(non-finite state, a bound exceeded, the engine raised or died) is not
stable. A trial that runs past its time limit decides nothing: it is run
once more with RETRY_FACTOR times the limit (a loaded machine only made it
slow), and a second timeout leaves the pair *undecided* between the dts
known so far, never unstable there.

Details: docs/running.md, "Module notes", ``compare/stability/search.py``.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable



from compare.results.metrics import Bounds
from compare.results.store import jsonable, now
from compare.run.plan import skip_reason
from compare.run.runner import default_jobs
from compare.stability.trial import (
    RETRY_FACTOR, Trial, check_output, document_head, load_document, run_trial, timed_retry, write_document,
)
from compare.suite.plans import SearchSettings, StabilityPlan
from compare.suite.reader import EngineSpec, SceneSpec, Suite

#: File the search writes in its output directory, and its format.
FILE_NAME = "stability.json"
SCHEMA = "xval-stability"
SCHEMA_VERSION = 2
#: Verdicts of one pair.
BOUNDED, STABLE_AT_LARGEST, UNSTABLE_AT_SMALLEST, SKIPPED, UNDECIDED = (
    "bounded", "stable-at-largest", "unstable-at-smallest", "skipped", "undecided",
)



def criterion_text(bounds: Bounds) -> str:
    """The stability criterion in words, stored with the results and shown in the report."""
    return (
        "stable at dt = every scheduled sample delivered over the scene's duration with a finite state, "
        f"energy drift ≤ {bounds.energy_drift:g} E* and constraint error ≤ {bounds.constraint_error:g} L; "
        "unstable = a non-finite state, a bound exceeded, or the engine failed; a trial past its time limit "
        f"(twice: the limit, then {RETRY_FACTOR:g}× it) decides nothing, and the pair is undecided"
    )


@dataclass(frozen=True)
class PairResult:
    """The search's answer for one scene × engine variant.

    verdict : bounded, stable-at-largest, unstable-at-smallest, undecided or skipped.
    largest_stable_dt : s, the largest dt found stable (None when none was).
    smallest_unstable_dt : s, the smallest dt found unstable above it (None when none was).
    undecided_dt : s, the dt whose trial timed out twice (verdict undecided: the boundary lies between
        largest_stable_dt, or below, and smallest_unstable_dt, or above), else None.
    analytic_dt : s, the linear theory's limit where one exists (ours/baumgarte), else None.
    trials : the runs it made, in the order they ran.
    """

    scene_id: str
    engine: str
    verdict: str
    largest_stable_dt: float | None = None
    smallest_unstable_dt: float | None = None
    reason: str = ""
    analytic_dt: float | None = None
    trials: tuple[Trial, ...] = ()
    undecided_dt: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return jsonable(asdict(self))


# -- the search itself (pure: the trial is a function of dt) ---------------------------------


class _Undecided(Exception):
    """A trial timed out: the search stops where it stands."""


def search(trial: Callable[[float], Trial], settings: SearchSettings) -> tuple[str, float | None, float | None, list[Trial]]:
    """(verdict, largest stable dt, smallest unstable dt, trials) for one pair; the search:
    docs/running.md, "Module notes". A trial with status ``timeout`` ends it ``undecided``, with the
    bracket known so far (:func:`timed_retry` gives the trial its second chance first)."""
    trials: list[Trial] = []
    known: list[float | None] = [None, None]  # largest stable, smallest unstable so far

    def stable(dt: float) -> bool:
        result = trial(dt)
        trials.append(result)
        if result.status == "timeout":
            raise _Undecided
        if result.stable:
            known[0] = max(dt, known[0] or dt)
        else:
            known[1] = min(dt, known[1] or dt)
        return result.stable

    try:
        return _bisect(stable, settings, trials)
    except _Undecided:
        return UNDECIDED, known[0], known[1], trials


def _bisect(stable: Callable[[float], bool], settings: SearchSettings,
            trials: list[Trial]) -> tuple[str, float | None, float | None, list[Trial]]:
    """The bracketing and bisection of :func:`search` on the predicate ``stable`` (which records the trials)."""
    if stable(settings.dt_max):
        return STABLE_AT_LARGEST, settings.dt_max, None, trials
    hi, lo = settings.dt_max, None
    while lo is None:
        if hi <= settings.dt_min * (1 + 1e-12):
            return UNSTABLE_AT_SMALLEST, None, hi, trials
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
    return BOUNDED, lo, hi, trials


# -- the analytic limit where the theory covers the variant ---------------------------------------


def analytic_dt(engine: EngineSpec) -> float | None:
    """s: the largest dt the engine's own linear theory calls stable for this variant (None: it has none)."""
    if engine.engine is None:
        return None
    return engine.engine.largest_stable_dt(engine.variant, engine.options)


# -- running it -------------------------------------------------------------------------------


def plan_stability(suite: Suite) -> StabilityPlan:
    """The suite's typed ``[stability]`` plan (every scene and variant when it has no table)."""
    if suite.stability is not None:
        return suite.stability
    return StabilityPlan(suite.scenes, suite.engines, SearchSettings(max(suite.dts), min(suite.dts)))


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
        verdict, lo, hi, trials = search(
            timed_retry(lambda dt, limit: run_trial(scene, engine, dt, suite, limit, stability.settings.sample_interval),
                        timeout),
            stability.settings,
        )
        last_unstable = next((t for t in reversed(trials) if not t.stable), None)
        why = "" if last_unstable is None else f"at dt = {last_unstable.dt:.4g} s: {last_unstable.status} ({last_unstable.message})"
        undecided = trials[-1].dt if verdict == UNDECIDED else None
        return PairResult(scene.id, engine.label, verdict, lo, hi, why, analytic_dt(engine), tuple(trials), undecided)

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
    return load_document(path, FILE_NAME, SCHEMA, SCHEMA_VERSION, {1: _from_version_1})


def _from_version_1(document: dict[str, Any]) -> dict[str, Any]:
    """Version 1 named each pair's runs ``probes`` (a word ``xval probe`` uses for something else); 2 ``trials``."""
    results = [{("trials" if key == "probes" else key): value for key, value in result.items()}
               for result in document.get("results") or []]
    return {**document, "schema_version": 2, "results": results}
