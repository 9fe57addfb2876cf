"""The gate's rules as pure functions: the accuracy bound, null divergence times, the timing rule, [gate] parsing."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from engines.errors import UserError

from compare.gate.baseline import load_baseline, write_baseline
from compare.gate.entry import BaselineEntry, Timing
from compare.gate.gate import accuracy_change, compare_case, machine_difference, timing_change
from compare.results.record import Status
from compare.suite.reader import parse_suite
from compare.suite.gate_rules import RULES, GateSettings, Tolerance, gate_settings

SETTINGS = GateSettings()


def error(key: str, message: str) -> UserError:
    return UserError(f"suite.toml: {key}: {message}")


@pytest.mark.parametrize(
    "current, verdict",
    [
        (1.0e-3 * 1.1 + 1e-9, "unchanged"),        # exactly at baseline·(1 + rtol) + atol: still passes
        (1.0e-3 * 1.1 + 2e-9, "worse"),            # just past it
        (2.0e-3, "worse"),                          # doubled
        (0.5e-3, "better"),                         # halved
        (1.0e-3 / 1.05, "unchanged"),               # 5 % better: inside the tolerance
    ],
)
def test_an_error_is_worse_past_baseline_times_one_plus_rtol_plus_atol(current, verdict):
    change = accuracy_change(RULES["position_error_linf"], 1.0e-3, current, SETTINGS)
    assert change.outcome == verdict
    assert change.limit == pytest.approx(1.0e-3 * 1.1 + 1e-9)


def test_errors_below_atol_are_noise():
    # Round-off-sized constraint errors that grow 100× are still below atol = 1e-10 m.
    assert accuracy_change(RULES["constraint_error"], 1e-15, 1e-13, SETTINGS).outcome == "unchanged"


@pytest.mark.parametrize(
    "baseline, current, verdict",
    [(4.0, 3.8, "unchanged"), (4.0, 3.0, "worse"), (1.0, 2.0, "better"), (None, 2.0, None), (4.0, None, None)],
)
def test_a_lower_observed_order_is_worse_and_a_missing_fit_is_not_compared(baseline, current, verdict):
    change = accuracy_change(RULES["observed_order"], baseline, current, SETTINGS)
    assert (change.outcome if change else None) == verdict


@pytest.mark.parametrize(
    "baseline, current, verdict",
    [(None, None, "unchanged"), (None, 0.4, "worse"), (0.4, None, "better"), (0.5, 0.3, "worse"), (0.5, 0.49, "unchanged")],
)
def test_a_null_divergence_time_means_never_diverged(baseline, current, verdict):
    assert accuracy_change(RULES["divergence_time"], baseline, current, SETTINGS).outcome == verdict


def timing(*repeats: float) -> Timing:
    ordered = sorted(repeats)
    return Timing(ordered[len(ordered) // 2], repeats, (ordered[0], ordered[-1]))


@pytest.mark.parametrize(
    "baseline, current, verdict",
    [
        (timing(1.0, 1.1, 1.2), timing(1.6, 1.7, 1.8), "worse"),       # 1.55× and clear of both spreads
        (timing(1.0, 1.1, 1.2), timing(1.4, 1.5, 1.6), "unchanged"),   # 1.36×: under the factor
        (timing(1.0, 1.1, 1.2), timing(0.5, 2.0, 2.2), "unchanged"),   # 1.8× but the spreads (0.2 + 1.7) cover it
        (timing(1.0, 1.1, 1.2), timing(0.3, 0.35, 0.4), "better"),
    ],
)
def test_a_slowdown_must_exceed_the_factor_and_the_spread_of_both_sides(baseline, current, verdict):
    change = timing_change(baseline, current, 1.5, gated=True)
    assert change.outcome == verdict and change.gated


def test_single_repeats_are_shown_but_never_gated():
    change = timing_change(timing(1.0), timing(5.0), 1.5, gated=True)
    assert change.outcome == "worse" and not change.gated
    assert change.note == "5.00× slower (factor 1.5, repeat spread 0 s/s); not gated: fewer than 2 timing repeats, so the noise is unknown (set repeats in the suite)"


def entry(status: str, message: str = "", version: str | None = "1.0", metrics: dict | None = None) -> BaselineEntry:
    """A baseline entry of one case with no timing (no metrics either unless given: enough for the status rules)."""
    return BaselineEntry("bead", "h", "e/v", "e/v", "v", {}, 0.01, (0, 0, 0), version, Status(status), message,
                         metrics, None, "", None)


@pytest.mark.parametrize(
    "baseline, current, verdict, reason",
    [
        # Stopped running (a plug-in that no longer imports has no version to compare): worse, whatever else changed.
        (entry("ok"), entry("skipped", "cannot import my_solver", version=None), "worse", "skipped now: cannot import my_solver"),
        (entry("unstable"), entry("skipped", "gone"), "worse", "skipped now: gone"),
        (entry("skipped", "not installed", version=None), entry("ok"), "not comparable", "skipped in the baseline: not installed"),
        (entry("skipped", "2-D only"), entry("skipped", "2-D only"), "unchanged", ""),
        (entry("ok"), entry("ok", version="2.0"), "not comparable", "engine version changed: 1.0 → 2.0"),
        (entry("unstable"), entry("failed"), "unchanged", ""),
    ],
)
def test_status_rules_for_skipped_and_versioned_cases(baseline, current, verdict, reason):
    case = compare_case(baseline, current, SETTINGS, timing_gated=True, why_not="")
    assert (case.outcome, case.reason) == (verdict, reason)


def test_machines_differ_in_the_named_fields():
    same = {"cpu": "A", "cpu_count": 2, "machine": "x86_64"}
    assert machine_difference(same, dict(same)) == ""
    assert machine_difference(same, {**same, "cpu_count": 4}) == "timed on another machine (cpu_count 2 → 4)"


def test_gate_table_overrides_and_legacy_tolerances():
    settings = gate_settings(
        {"timing_factor": 2, "energy_drift": {"atol": 1e-6}, "position_error_rms": 0.3},
        {"position_error_linf": 0.2, "position_error_rms": 0.9},
        error,
    )
    assert settings.timing_factor == 2.0
    assert settings.tolerance("energy_drift") == Tolerance(0.1, 1e-6)
    assert settings.tolerance("position_error_linf") == Tolerance(0.2, 1e-9)
    assert settings.tolerance("position_error_rms") == Tolerance(0.3, 1e-9)  # [gate] wins over [tolerances]
    assert gate_settings(None, {"cost_per_simulated_second": 1.0}, error).timing_factor == 2.0


@pytest.mark.parametrize(
    "gate, message",
    [
        ({"nosuch": 1}, "suite.toml: gate.nosuch: unknown key; valid keys are: timing_factor, position_error_linf, "
                        "position_error_rms, position_error_final, divergence_time, energy_drift, constraint_error, "
                        "constraint_force_error, observed_order, momentum_drift, gradient_error, gradient_wrong"),
        ({"timing_factor": 1}, "suite.toml: gate.timing_factor: must be a number > 1 (a slowdown factor), got 1; write e.g. timing_factor = 1.5"),
        ({"energy_drift": -0.1}, "suite.toml: gate.energy_drift: must be a number ≥ 0, got -0.1; write e.g. energy_drift = 0.1"),
        ({"energy_drift": {"rtol": "big"}}, "suite.toml: gate.energy_drift.rtol: must be a number ≥ 0, got 'big'; write e.g. rtol = 0.1"),
        ({"energy_drift": {"reltol": 1}}, "suite.toml: gate.energy_drift.reltol: unknown key; write energy_drift = { rtol = 0.1, atol = 1e-9 }"),
    ],
)
def test_a_bad_gate_table_names_the_key_and_the_fix(gate, message):
    with pytest.raises(UserError) as raised:
        gate_settings(gate, None, error)
    assert str(raised.value) == message


def test_tolerances_and_gate_forgive_no_slowdown_alike():
    """[tolerances] cost_per_simulated_second = 0 is the timing factor 1 that [gate] refuses: refused too."""
    with pytest.raises(UserError) as raised:
        gate_settings(None, {"cost_per_simulated_second": 0}, error)
    assert str(raised.value) == ("suite.toml: tolerances.cost_per_simulated_second: must be a number > 0 (the slowdown "
                                 "forgiven: 0.5 is a factor 1.5), got 0; or write [gate] timing_factor = 1.5")
    assert gate_settings(None, {"energy_drift": 0}, error).tolerance("energy_drift").rtol == 0.0  # as [gate] allows


SUITE = """name = "s"
dt = [1e-2]
[[scenes]]
scene = "bead"
[[engines]]
id = "reference/dop853"
"""


def test_a_suite_carries_its_gate_table_and_a_mistake_names_the_line():
    suite = parse_suite(SUITE + "[gate]\ntiming_factor = 3\n", "s.toml")
    assert suite.gate.timing_factor == 3.0
    with pytest.raises(UserError, match=r"^s\.toml:8: gate\.timing_factor: must be a number > 1"):
        parse_suite(SUITE + "[gate]\ntiming_factor = 0\n", "s.toml")


def test_a_suite_written_before_the_rms_rename_still_reads_its_tolerances():
    """position_error_rms was position_error_l2: a suite (or the suite.toml kept in an older results
    directory, which xval gate reads) that names the old key sets the new metric's tolerance."""
    suite = parse_suite(SUITE + "[tolerances]\nposition_error_l2 = 0.7\n", "s.toml")
    assert suite.gate.tolerance("position_error_rms") == Tolerance(0.7, 1e-9)
    suite = parse_suite(SUITE + "[gate]\nposition_error_l2 = { rtol = 0.4, atol = 1e-6 }\n", "s.toml")
    assert suite.gate.tolerance("position_error_rms") == Tolerance(0.4, 1e-6)


def test_a_side_without_a_reference_has_its_null_divergence_time_unmeasured_not_infinite():
    # A reference that timed out leaves the position metrics null, divergence_time with them: that null
    # is "not measured", not "never diverged", so no divergence-time change is made of it either way.
    measured = entry("ok", "no reference", metrics={"position_error_linf": 1e-3, "divergence_time": 0.5})
    unmeasured = entry("ok", "no reference", metrics={"position_error_linf": None, "divergence_time": None})
    for base, current in ((measured, unmeasured), (unmeasured, measured)):
        result = compare_case(base, current, SETTINGS, timing_gated=True, why_not="")
        assert "divergence_time" not in {c.metric for c in result.changes}
    assert compare_case(measured, unmeasured, SETTINGS, timing_gated=True, why_not="").outcome == "worse"
    # With a reference on both sides a null divergence time still means never diverged.
    never = entry("ok", "no reference", metrics={"position_error_linf": 1e-3, "divergence_time": None})
    assert compare_case(never, measured, SETTINGS, timing_gated=True, why_not="").outcome == "worse"


BASELINES = Path(__file__).resolve().parents[1] / "baselines"


def test_a_committed_baseline_reads_into_typed_entries_and_writes_back_byte_for_byte(tmp_path):
    baseline = load_baseline(BASELINES / "smoke.json")
    assert all(isinstance(e, BaselineEntry) and isinstance(e.status, Status) for e in baseline.cases.values())
    assert all(key == entry.key for key, entry in baseline.cases.items())
    write_baseline(baseline, tmp_path / "again.json")
    assert (tmp_path / "again.json").read_text() == (BASELINES / "smoke.json").read_text()


def test_a_baseline_written_before_the_rms_rename_reads_as_today(tmp_path):
    """A baseline made when position_error_rms was position_error_l2 reads into the same entries."""
    old = tmp_path / "old.json"
    old.write_text((BASELINES / "smoke.json").read_text().replace('"position_error_rms"', '"position_error_l2"'))
    assert '"position_error_l2"' in old.read_text()
    assert load_baseline(old).cases == load_baseline(BASELINES / "smoke.json").cases


def test_a_directory_given_for_the_baseline_is_told_to_give_the_file(tmp_path):
    with pytest.raises(UserError) as raised:
        load_baseline(tmp_path)
    assert str(raised.value) == (f"--baseline: {tmp_path}: is a directory; give the baseline JSON file "
                                 "(xval baseline DIR --output FILE)")


@pytest.mark.parametrize("field, value, message", [
    ("status", "fine", r"field status is 'fine'; expected one of ok, unstable, failed, timeout, skipped"),
    ("dt", "0.01", r"field dt must be a finite number, got '0.01'"),
    ("metrics", {"position_error_linf": "small"}, r"field metrics must be an object of numbers or null"),
])
def test_a_damaged_baseline_entry_is_one_error_naming_the_file_the_case_and_the_field(tmp_path, field, value, message):
    document = json.loads((BASELINES / "smoke.json").read_text())
    key = next(iter(document["cases"]))
    document["cases"][key][field] = value
    (tmp_path / "b.json").write_text(json.dumps(document))
    with pytest.raises(UserError, match=rf"^--baseline: {re.escape(str(tmp_path))}/b\.json: case .*: {message}.*; make it again"):
        load_baseline(tmp_path / "b.json")


# -- timing through the variant's per-step cost, against a window's distribution ------------------------

DTS = (5e-3, 2.5e-3, 1.25e-3)
#: s of CPU per step of the made-up variant (30-60 µs cases, as ours' cheapest variants on the smoke suite).
PER_STEP = 5e-8


def timed(dt: float, runs: list[float], calibration: float = 3e-3, repeat_spread: float = 0.02,
          seconds: float = 0.01) -> BaselineEntry:
    """An ok case of variant e/v at ``dt`` whose runs cost PER_STEP/dt × each of ``runs`` per simulated second
    (oldest first; the last one's two repeats are kept as its cpu), its stepping lasting ``seconds`` (10 ms:
    under the resolution alone, three of them over it together)."""
    cost = PER_STEP / dt * runs[-1]
    cpu = (cost, cost * (1 + repeat_spread))
    per_run = tuple(PER_STEP / dt * r / calibration for r in runs)
    timing = Timing(cost, cpu, (min(cpu), max(cpu)), cpu=cpu, calibration=(calibration, calibration),
                    runs=len(runs) if len(runs) > 1 else None, seconds=seconds, per_run=per_run if len(runs) > 1 else None)
    return BaselineEntry("bead", "h", "e/v", "e/v", "v", {}, dt, (0, 0, 0), "1.0", Status.OK, "", None, None, "",
                         timing)


def gate_timing(window: list[list[float]], current: list[float], seconds: float = 0.01) -> list[str]:
    """The gated timing outcomes of the variant's cases ("shown" when not gated): each case's window runs
    against the current run."""
    from compare.gate.gate import variant_timings

    base = {f"k{k}": timed(dt, runs, seconds=seconds) for k, (dt, runs) in enumerate(zip(DTS, window))}
    now = {f"k{k}": timed(dt, [factor], seconds=seconds) for k, (dt, factor) in enumerate(zip(DTS, current))}
    variants = variant_timings(base, now, SETTINGS.timing_factor)
    changes = [timing_change(base[k].timing, now[k].timing, SETTINGS.timing_factor, True, "", variants.get("e/v"))
               for k in base]
    return [change.outcome if change.gated else "shown" for change in changes]


#: Five runs whose costs wander by up to 25 % (each case on its own), as unchanged runs on a shared machine do.
WINDOW = [[1.0, 1.2, 0.9, 1.1, 1.0], [1.1, 0.95, 1.0, 1.25, 1.0], [0.9, 1.0, 1.15, 1.0, 1.05]]


def test_cases_below_the_resolution_are_judged_by_their_variants_per_step_cost():
    # Every case 2× slower: the variant's per-step cost doubled, past max(1.5, the window's spread): worse.
    assert gate_timing(WINDOW, [2.0, 2.0, 2.0]) == ["worse"] * 3
    # One case 1.7× on its own (a disturbed case of 60 µs): the median over the variant's cases does not follow it.
    assert gate_timing(WINDOW, [1.7, 1.0, 1.0]) == ["unchanged"] * 3
    # The whole variant 1.3× slower: inside the factor.
    assert gate_timing(WINDOW, [1.3, 1.3, 1.3]) == ["unchanged"] * 3


def test_a_variant_whose_cases_step_less_than_the_resolution_together_is_shown_not_gated():
    # Three cases of 1 ms: 3 ms in all, under CASE_RESOLUTION (20 ms); even 2× slower cannot fail the gate.
    assert gate_timing(WINDOW, [2.0, 2.0, 2.0], seconds=1e-3) == ["shown"] * 3


def test_a_window_is_compared_by_its_median_and_spread_not_its_best_run():
    # The window's best run cost 0.6 of its median; 1.4× the median is 2.3× that best run, yet unchanged.
    window = [[0.6, 1.0, 1.0, 1.0, 1.4]] * 3
    assert gate_timing(window, [1.4, 1.4, 1.4]) == ["unchanged"] * 3
    # Past the window's own spread (1.67×, its cheapest run from its median) and the factor: worse.
    assert gate_timing(window, [1.9, 1.9, 1.9]) == ["worse"] * 3


def test_a_case_above_the_resolution_is_gated_on_its_own_against_the_window():
    from compare.gate.gate import CASE_RESOLUTION

    long = 10 * CASE_RESOLUTION  # s of stepping: 10× the resolution
    base = timed(DTS[0], [1.0, 1.1, 0.9, 1.0, 1.05], seconds=long)
    for factor, verdict in ((1.3, "unchanged"), (2.0, "worse"), (0.5, "better")):
        change = timing_change(base.timing, timed(DTS[0], [factor], seconds=long).timing, 1.5, True, "")
        assert change.gated
        assert change.outcome == verdict
        assert ("median of 5 runs" in change.note) == (verdict != "unchanged")
