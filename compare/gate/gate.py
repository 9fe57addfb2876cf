"""The gate: compare a results directory with a baseline and decide, per case, better / worse / unchanged / ….

Rules (asv's ``continuous``: fail only on a change larger than the noise): a metric is worse or
better past its ``rtol``/``atol``; a status that leaves ``ok``, a case skipped now, a missing case of
the same suite or a number that became null is worse; timing is judged by ``timing_factor`` widened
by the noise measured in both runs; a changed scene, option set or engine version is not comparable.
Everything here is a pure function of two :class:`~compare.gate.baseline.Baseline` documents, so the
rules are tested without running anything.

Details: docs/gate.md, "Module notes", ``compare/gate/gate.py``.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

from engines.errors import UserError

from compare.gate.baseline import MACHINE_FIELDS, Baseline
from compare.gate.entry import BaselineEntry, Timing, case_name
from compare.results.declared import Metric
from compare.suite.gate_rules import RULES, TIMING_METRIC, GateSettings
from compare.results.record import PROBLEMS, Status

#: Case outcomes, in the order a table lists them (most urgent first).
OUTCOMES = ("worse", "not comparable", "missing", "new", "better", "unchanged")
#: How timing is treated: "gate" (a real slowdown fails) or "report" (shown, never fails).
TIMING_MODES = ("gate", "report")
#: Fewest timing repeats on each side for a timing change to be gated (the spread needs two).
MIN_TIMING_REPEATS = 2


@dataclass(frozen=True)
class Change:
    """One compared quantity of one case.

    metric : a metric name, ``"status"``, or ``TIMING_METRIC``.
    baseline, current : the two values (a status is a string; None: absent).
    limit : the value past which ``current`` counts as worse (None when not numeric).
    outcome : "worse", "better" or "unchanged".
    gated : False for a timing change that is shown but cannot fail the gate.
    note : why, in words (the bound exceeded, the timing rule, …).
    """

    metric: str
    unit: str
    baseline: Any
    current: Any
    limit: float | None
    outcome: str
    gated: bool = True
    note: str = ""


@dataclass(frozen=True)
class CaseResult:
    """The gate's outcome for one case (scene × engine × dt) with every change it compared."""

    scene_id: str
    engine: str
    dt: float
    position: tuple
    outcome: str
    reason: str = ""
    changes: tuple[Change, ...] = ()
    baseline_status: str | None = None
    current_status: str | None = None

    @property
    def name(self) -> str:
        return case_name(self.scene_id, self.engine, self.dt)

    def decisive(self) -> list[Change]:
        """The gated changes that made the outcome (all worse ones for ``worse``, better ones for ``better``)."""
        return [c for c in self.changes if c.gated and c.outcome == self.outcome]


@dataclass(frozen=True)
class GateReport:
    """Every case's outcome, in table order, plus what the comparison was made under."""

    suite: str
    cases: tuple[CaseResult, ...]
    settings: GateSettings
    timing: str
    timing_note: str = ""
    notes: tuple[str, ...] = ()
    #: True when the missing cases fail the gate (the rule: docs/gate.md, "Module notes").
    missing_fails: bool = False

    @property
    def counts(self) -> dict[str, int]:
        counts = {v: 0 for v in OUTCOMES}
        for case in self.cases:
            counts[case.outcome] += 1
        return counts

    @property
    def passed(self) -> bool:
        counts = self.counts
        return counts["worse"] == 0 and not (self.missing_fails and counts["missing"])


# -- one metric -------------------------------------------------------------------------


def accuracy_change(rule: Metric, baseline: float | None, current: float | None, settings: GateSettings) -> Change | None:
    """Compare one accuracy metric; None when either side has no value to compare."""
    tol = settings.tolerance(rule.name)
    infinite = rule.none_means == "infinite"
    if baseline is None or current is None:
        if not infinite:
            return None
        # Divergence time: null = never diverged.
        if baseline is None and current is None:
            return Change(rule.name, rule.unit, None, None, None, "unchanged")
        if baseline is None:
            return Change(rule.name, rule.unit, None, current, None, "worse", note="diverges now, never did before")
        return Change(rule.name, rule.unit, baseline, None, None, "better", note="no longer diverges")

    def exceeds(a: float, b: float) -> bool:
        """a is past b's allowance: a > b·(1 + rtol) + atol."""
        return a > b * (1 + tol.rtol) + tol.atol

    if rule.higher_is_better:
        worse, better = exceeds(baseline, current), exceeds(current, baseline)
        limit = (baseline - tol.atol) / (1 + tol.rtol)  # lowest current that still passes
    else:
        worse, better = exceeds(current, baseline), exceeds(baseline, current)
        limit = baseline * (1 + tol.rtol) + tol.atol
    outcome = "worse" if worse else "better" if better else "unchanged"
    return Change(rule.name, rule.unit, baseline, current, limit, outcome)


def timing_change(baseline: Timing | None, current: Timing | None, factor: float, gated: bool, why_not: str = "",
                  variant: VariantTiming | None = None) -> Change | None:
    """Compare timings; a change must beat the factor and the noise.

    With a single repeat on either side the noise is unknown (a spread of
    zero would let one disturbed run fail the gate), so the change is shown
    but not gated; suites that gate timing set ``repeats`` ≥ MIN_TIMING_REPEATS.
    A case whose stepping lasted less than CASE_RESOLUTION is judged by its
    ``variant``'s per-step cost over all its cases (:func:`variant_timings`), not on its own.
    """
    if not baseline or not current:
        return None
    b, c = baseline.cost, current.cost
    if gated and min(len(baseline.repeats), len(current.repeats)) < MIN_TIMING_REPEATS:
        gated, why_not = False, f"fewer than {MIN_TIMING_REPEATS} timing repeats, so the noise is unknown (set repeats in the suite)"
    if baseline.cpu and current.cpu and baseline.calibration and current.calibration:
        if _below_resolution(baseline, current):
            return _by_variant(baseline, current, variant, gated, why_not)
        return cpu_timing_change(baseline, current, factor, gated, why_not)
    noise = (baseline.spread[1] - baseline.spread[0]) + (current.spread[1] - current.spread[0])
    if c > factor * b and c - b > noise:
        outcome, note = "worse", f"{c / b:.2f}× slower (factor {factor:g}, repeat spread {noise:.2g} s/s)"
    elif b > factor * c and b - c > noise:
        outcome, note = "better", f"{b / c:.2f}× faster"
    else:
        outcome, note = "unchanged", ""
    return _timing(b, c, factor * b, outcome, note, gated, why_not)


#: s of CPU a case's fastest repeat must step for its own timing to be gated. Below it a case is a few of
#: the scheduler's time slices (4 ms at 250 Hz): on a shared machine one case of 30–60 µs per simulated
#: second read 1.55–1.67× slower between unchanged runs. Such cases are judged by their variant's per-step
#: cost over all its cases (:func:`variant_timings`), when those stepped this long together; below that
#: too their timing is shown, not gated (ours' smoke cases, ~1.5 ms a variant, moved together by up to
#: 1.6× between unchanged runs on a loaded machine: scripts/gate_window_rates.py).
CASE_RESOLUTION = 0.02


def _below_resolution(baseline: Timing, current: Timing) -> bool:
    """Whether either side's stepping lasted less than CASE_RESOLUTION (unknown durations: not below)."""
    return any(t.seconds is not None and t.seconds < CASE_RESOLUTION for t in (baseline, current))


def _by_variant(baseline: Timing, current: Timing, variant: VariantTiming | None, gated: bool,
                why_not: str) -> Change:
    """The timing Change of a case below the resolution: its variant's outcome, or shown and not gated."""
    b, c = min(baseline.cpu or ()), min(current.cpu or ())
    short = min(t.seconds for t in (baseline, current) if t.seconds is not None)
    below = f"its stepping lasted {short * 1e3:.2g} ms < {CASE_RESOLUTION * 1e3:g} ms"
    if variant is None:
        change = Change(TIMING_METRIC, "s/s", b, c, None, "unchanged", gated=False,
                        note=f"not gated: {below}, and its variant has no fitted cost on both sides")
        return change
    if variant.seconds < CASE_RESOLUTION:
        outcome = variant.outcome
        note = (f"{variant.note}; " if outcome != "unchanged" else "") + (
            f"not gated: {below}, and its variant's cases {variant.seconds * 1e3:.2g} ms together")
        return Change(TIMING_METRIC, "s/s", b, c, variant.limit * b, outcome, gated=False, note=note)
    note = f"{variant.note}; judged by its variant ({below})" if variant.outcome != "unchanged" else ""
    return _timing(b, c, variant.limit * b, variant.outcome, note, gated, why_not)


def _timing(b: float, c: float, limit: float, outcome: str, note: str, gated: bool, why_not: str) -> Change:
    """The timing Change (s/s), saying why a change that is not gated is not."""
    if outcome != "unchanged" and not gated:
        note += f"; not gated: {why_not}"
    return Change(TIMING_METRIC, "s/s", b, c, limit, outcome, gated=gated, note=note)


def best_spread(values: list[float]) -> float:
    """(second best − best) / best of one side's repeats: how far its best is from being reproduced (0 for one)."""
    ordered = sorted(values)
    if len(ordered) < 2 or ordered[0] <= 0:
        return 0.0
    return (ordered[1] - ordered[0]) / ordered[0]


def calibrated(timing: Timing) -> list[float]:
    """Each repeat's CPU cost (s/s) in units of the run's fastest calibration kernel (s)."""
    unit = min(timing.calibration or ())
    return [c / unit for c in timing.cpu or ()]


def _window_noise(runs: Sequence[float], median: float) -> float:
    """The window's own spread: its runs' largest excursion from their median, as a factor ≥ 1."""
    return max(max(v / median, median / v) for v in runs)


def _limit(factor: float, base_runs: Sequence[float], median: float, base_spread: float, current_spread: float,
           ) -> tuple[float, str]:
    """(ratio limit, how) of a timing rule: one baseline run, factor · (1 + s_b + s_c); a window of runs,
    the factor or the window's own spread over its runs times the current run's, whichever is larger."""
    if len(base_runs) < 2:
        widen = 1 + base_spread + current_spread
        return factor * widen, f"limit {factor:g} × {widen:.3g} = {factor * widen:.3g}"
    spread = _window_noise(base_runs, median) * (1 + current_spread)
    limit = max(factor, spread)
    return limit, (f"median of {len(base_runs)} runs; limit max({factor:g}, window spread × repeat spread "
                   f"{spread:.3g}) = {limit:.3g}")


def cpu_timing_change(baseline: Timing, current: Timing, factor: float, gated: bool, why_not: str = "") -> Change:
    """The statistical timing rule (docs/gate.md, "Module notes") on two timing entries with "cpu"
    and "calibration".

    Against one run: worse when best(current) > best(baseline) · factor · (1 + s_b + s_c), bests of the
    calibrated costs, s = :func:`best_spread`. Against a window of runs: against the median of the runs'
    calibrated bests, worse past max(factor, the window's spread over its runs · (1 + s_c)); never against
    its best run. Better in mirror. The Change shows the best CPU costs (s/s).
    """
    b_cal, c_cal = calibrated(baseline), calibrated(current)
    runs = baseline.per_run if baseline.per_run and len(baseline.per_run) >= 2 else (min(b_cal),)
    median = statistics.median(runs)
    ratio = min(c_cal) / median
    limit, how = _limit(factor, runs, median, best_spread(b_cal), best_spread(c_cal))
    b, c = min(baseline.cpu or ()), min(current.cpu or ())
    outcome, note = _judged(ratio, limit, "", f"CPU time per calibration, best of {len(b_cal)}/{len(c_cal)} "
                                              f"repeats; {how}")
    return _timing(b, c, limit * b, outcome, note, gated, why_not)


def _judged(ratio: float, limit: float, what: str, how: str) -> tuple[str, str]:
    """(outcome, note) of a cost ``ratio`` (current / baseline) against ``limit``, either way."""
    if ratio > limit:
        return "worse", f"{what}{ratio:.2f}× slower ({how})"
    if 1 / ratio > limit:
        return "better", f"{what}{1 / ratio:.2f}× faster ({how})"
    return "unchanged", ""


# -- one variant ------------------------------------------------------------------------


@dataclass(frozen=True)
class VariantTiming:
    """A variant's (engine label's) timing judged over all its cases at once.

    ratio : the current run's per-step cost / the baseline's (a window's: the median over its runs), the
    median over the variant's cases; limit : the ratio past which it is worse (or, inverted, better);
    outcome : "worse", "better" or "unchanged".
    """

    engine: str
    ratio: float
    limit: float
    outcome: str
    note: str
    #: s of CPU its cases stepped together (the lesser side); below CASE_RESOLUTION its timing is not gated.
    seconds: float = math.inf


def variant_ratio(cases: Sequence[tuple[Sequence[float], float]]) -> tuple[float, list[float]]:
    """(the current run's per-step cost over the baseline's median, each baseline run's over the same median)
    of one variant, from its cases' (baseline runs' calibrated costs oldest first, current calibrated cost).

    A case's per-step cost is its cost per simulated second × dt, the same factor on both sides, so per case
    the ratio of costs is the ratio of per-step costs; the variant's is the median over its cases, which no
    single disturbed case moves. Each baseline run gets the same median of its own cases' ratios: the
    window's distribution the current run is judged against (its runs aligned from the latest back).
    """
    medians = [statistics.median(runs) for runs, _ in cases]
    now = statistics.median(current / m for (_, current), m in zip(cases, medians))
    depth = min(len(runs) for runs, _ in cases)
    window = [statistics.median(runs[len(runs) - depth + k] / m for (runs, _), m in zip(cases, medians))
              for k in range(depth)]
    return now, window


def _stepped(timings: Sequence[Timing | None]) -> float:
    """s of CPU the cases stepped together (their fastest repeats); infinite when none says."""
    known = [t.seconds for t in timings if t is not None and t.seconds is not None]
    return sum(known) if known else math.inf


def variant_timings(base: Mapping[str, BaselineEntry], current: Mapping[str, BaselineEntry],
                    factor: float) -> dict[str, VariantTiming]:
    """Per engine label, the variant's timing over its cases ok and calibrated on both sides: the current
    run's per-step cost against the baseline's (:func:`variant_ratio`); worse past max(factor, the window's
    spread over its runs × the current run's repeat spread), against one baseline run past factor ·
    (1 + s_b + s_c) (docs/gate.md, "Module notes", compare/gate/gate.py)."""
    pairs: dict[str, list[tuple[BaselineEntry, BaselineEntry]]] = {}
    for key, entry in current.items():
        old = base.get(key)
        if (old is None or old.status is not Status.OK or entry.status is not Status.OK or not old.timing
                or not entry.timing or not old.timing.calibrated_runs or not entry.timing.calibrated_runs
                or old.engine_version != entry.engine_version):
            continue
        pairs.setdefault(entry.engine, []).append((old, entry))
    found = {}
    for engine, matched in pairs.items():
        ratio, window = variant_ratio([(o.timing.calibrated_runs, c.timing.calibrated_runs[-1])  # type: ignore[union-attr]
                                       for o, c in matched])
        spreads = [(best_spread(calibrated(o.timing)), best_spread(calibrated(c.timing)))  # type: ignore[arg-type]
                   for o, c in matched if o.timing and o.timing.cpu and c.timing and c.timing.cpu]
        s_b = statistics.median(b for b, _ in spreads) if spreads else 0.0
        s_c = statistics.median(c for _, c in spreads) if spreads else 0.0
        limit, how = _limit(factor, window, 1.0, s_b, s_c)
        outcome, note = _judged(ratio, limit, "variant ", f"per-step cost, median over its {len(matched)} cases; {how}")
        seconds = min(_stepped([o.timing for o, _ in matched]), _stepped([c.timing for _, c in matched]))
        found[engine] = VariantTiming(engine, ratio, limit, outcome, note, seconds)
    return found


# -- one case ------------------------------------------------------------------------


def compare_case(base: BaselineEntry, current: BaselineEntry, settings: GateSettings, timing_gated: bool,
                 why_not: str, variant: VariantTiming | None = None) -> CaseResult:
    """The outcome of one case present in both the baseline and the results, under the same key."""
    b_status, c_status = base.status, current.status
    common = dict(
        scene_id=current.scene_id, engine=current.engine, dt=current.dt, position=current.position,
        baseline_status=b_status.value, current_status=c_status.value,
    )
    skipped = Status.SKIPPED
    if c_status is skipped and b_status is not skipped:
        # The engine no longer loads here (a broken plug-in, a missing library) or no longer
        # expresses the scene: a solver that stopped running must not pass the gate silently.
        lost = Change("status", "", b_status.value, c_status.value, None, "worse", note=current.message)
        return CaseResult(**common, outcome="worse", reason=f"skipped now: {current.message}", changes=(lost,))
    if b_status is skipped and c_status is not skipped:
        return CaseResult(**common, outcome="not comparable", reason=f"skipped in the baseline: {base.message}")
    if base.engine_version != current.engine_version:
        return CaseResult(
            **common, outcome="not comparable",
            reason=f"engine version changed: {base.engine_version} → {current.engine_version}",
        )
    status = Change("status", "", b_status.value, c_status.value, None, "unchanged")
    if b_status is not c_status:
        if b_status is Status.OK and c_status in PROBLEMS:
            status = replace(status, outcome="worse", note=current.message)
        elif c_status is Status.OK:
            status = replace(status, outcome="better")
        else:
            status = replace(status, note="not ok before either")
    changes = [status]
    consistency_changed = consistency_change(base, current)
    if consistency_changed is not None:
        changes.append(consistency_changed)
    if b_status is Status.OK and c_status is Status.OK:
        # A side without a position error had no reference: its null divergence time is "not measured".
        unmeasured = base.metric("position_error_linf") is None or current.metric("position_error_linf") is None
        for rule in RULES.values():
            b_value, c_value = base.metric(rule.name), current.metric(rule.name)
            if unmeasured and rule.none_means == "infinite" and None in (b_value, c_value):
                continue
            change = accuracy_change(rule, b_value, c_value, settings)
            if change is None and b_value is not None and c_value is None:
                change = Change(rule.name, rule.unit, b_value, None, None, "worse",
                                note=f"no value now, the baseline had one: {current.message or 'see the case'}")
            if change is not None:
                changes.append(change)
        timing = timing_change(base.timing, current.timing, settings.timing_factor, timing_gated, why_not, variant)
        if timing is not None:
            changes.append(timing)
    gated = [c.outcome for c in changes if c.gated]
    outcome = "worse" if "worse" in gated else "better" if "better" in gated else "unchanged"
    return CaseResult(**common, outcome=outcome, changes=tuple(changes))


def consistency_change(base: BaselineEntry, current: BaselineEntry) -> Change | None:
    """A variant that turned inconsistent (converges to something else now) is worse; the reverse is better.

    None when neither side was judged (``consistent`` null on both).
    """
    b, c = base.consistent, current.consistent
    if b is None and c is None:
        return None
    if c is False and b is not False:
        return Change("consistent", "", b, c, None, "worse", note=current.consistency)
    if b is False and c is True:
        return Change("consistent", "", b, c, None, "better", note=current.consistency)
    return Change("consistent", "", b, c, None, "unchanged")


def _identity(entry: BaselineEntry) -> tuple:
    """What names a case to a reader (scene id, engine label, dt): used to pair cases whose key changed."""
    return (entry.scene_id, entry.engine, round(entry.dt, 15))


def _key_change(base: BaselineEntry, current: BaselineEntry) -> str:
    if base.scene_hash != current.scene_hash:
        return f"scene changed (content hash {base.scene_hash} → {current.scene_hash})"
    return (
        f"engine variant or options changed ({base.variant} {dict(base.options)} → "
        f"{current.variant} {dict(current.options)})"
    )


# -- the whole gate -------------------------------------------------------------------


def check_same_suite(baseline: Baseline, suite: Mapping[str, Any], baseline_path: str) -> list[str]:
    """UserError when the baseline was made from another suite; notes when the same suite was edited."""
    name = baseline.suite.get("name")
    if name != suite.get("name"):
        raise UserError(
            f"--baseline: {baseline_path} is a baseline of suite {name!r}, but the results are of suite "
            f"{suite.get('name')!r}; pass the baseline of {suite.get('name')!r}, or make one with "
            f"'xval baseline DIR --output FILE'"
        )
    if baseline.suite.get("fingerprint") != suite.get("fingerprint"):
        return [
            f"suite {name!r} changed since the baseline (fingerprint {baseline.suite.get('fingerprint')} → "
            f"{suite.get('fingerprint')}): cases it added are new, cases it dropped are missing"
        ]
    return []


def machine_difference(baseline_machine: Mapping[str, Any], current_machine: Mapping[str, Any]) -> str:
    """Why timings of the two runs do not compare ("" when they were taken on the same kind of machine)."""
    differing = [
        f"{k} {baseline_machine.get(k)!r} → {current_machine.get(k)!r}"
        for k in MACHINE_FIELDS
        if baseline_machine.get(k) != current_machine.get(k)
    ]
    return "timed on another machine (" + ", ".join(differing) + ")" if differing else ""


def gate(baseline: Baseline, current: Baseline, settings: GateSettings, *, timing: str = "gate") -> GateReport:
    """Compare two baselines (``current`` built from the results being gated).

    timing : "gate" judges timing when both runs were timed on the same kind
        of machine (MACHINE_FIELDS); "report" shows timing changes without
        ever failing on them.
    """
    if timing not in TIMING_MODES:
        raise UserError(f"--timing: {timing!r}; choose one of: {', '.join(TIMING_MODES)}")
    why_not = "timing is reported only (--timing report)" if timing == "report" else machine_difference(
        baseline.machine, current.machine
    )
    timing_gated = not why_not
    base_cases, current_cases = baseline.cases, current.cases
    variants = variant_timings(base_cases, current_cases, settings.timing_factor)
    results: list[CaseResult] = []
    for key, entry in current_cases.items():
        if key in base_cases:
            results.append(compare_case(base_cases[key], entry, settings, timing_gated, why_not,
                                        variants.get(entry.engine)))
    # Cases whose key changed but whose name did not: the same case, made different.
    unmatched_base = {_identity(e): e for k, e in base_cases.items() if k not in current_cases}
    for key, entry in current_cases.items():
        if key in base_cases:
            continue
        base = unmatched_base.pop(_identity(entry), None)
        if base is not None:
            results.append(CaseResult(
                entry.scene_id, entry.engine, entry.dt, entry.position, "not comparable",
                reason=_key_change(base, entry), baseline_status=base.status.value, current_status=entry.status.value,
            ))
        else:
            results.append(CaseResult(
                entry.scene_id, entry.engine, entry.dt, entry.position, "new",
                reason="not in the baseline", current_status=entry.status.value,
            ))
    for base in unmatched_base.values():
        results.append(CaseResult(
            base.scene_id, base.engine, base.dt, base.position, "missing",
            reason="in the baseline, not in the results", baseline_status=base.status.value,
        ))
    results.sort(key=lambda r: (OUTCOMES.index(r.outcome), r.position, r.scene_id, r.engine, -r.dt))
    missing = [r for r in results if r.outcome == "missing"]
    same_suite = baseline.suite.get("fingerprint") == current.suite.get("fingerprint")
    missing_fails = bool(missing) and (same_suite or len(missing) == len(base_cases))
    notes: tuple[str, ...] = ()
    if missing_fails:
        names = ", ".join(r.name for r in missing[:10]) + (f" and {len(missing) - 10} more" if len(missing) > 10 else "")
        notes = (f"{len(missing)} of the baseline's {len(base_cases)} cases are missing from the results ({names}); "
                 f"finish the run with 'xval run SUITE --output DIR --resume'",)
    return GateReport(
        suite=current.suite.get("name", ""),
        cases=tuple(results),
        settings=settings,
        timing=timing,
        timing_note=why_not,
        notes=notes,
        missing_fails=missing_fails,
    )


def gate_results(baseline: Baseline, current: Baseline, settings: GateSettings, baseline_path: str, *,
                 timing: str = "gate") -> GateReport:
    """:func:`gate` after checking both come from the same suite; the report carries the suite notes."""
    notes = check_same_suite(baseline, current.suite, baseline_path)
    report = gate(baseline, current, settings, timing=timing)
    return replace(report, notes=(*notes, *report.notes))

