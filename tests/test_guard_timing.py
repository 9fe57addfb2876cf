"""The statistical timing rule (compare/gate/gate.py: cpu_timing_change) on set numbers, and the CPU
time and calibration every real run records beside its wall time (what the rule is fed)."""

from __future__ import annotations

import pytest

from dataclasses import replace

from compare.gate.entry import Timing
from compare.gate.gate import best_spread, calibrated, cpu_timing_change, timing_change
from compare.run.isolation import CaseTask, calibration_cpu_time, simulate
from engines.scene import catalog


def timing(cpu: list[float], calibration: list[float]) -> Timing:
    return Timing(sorted(cpu)[len(cpu) // 2], tuple(cpu), (min(cpu), max(cpu)), tuple(cpu), tuple(calibration))


BASE = timing([1.00, 1.02, 1.30], [0.5, 0.5, 0.5])


def test_the_best_of_the_repeats_per_calibration_is_compared():
    assert calibrated(BASE) == [2.0, 2.04, 2.6]
    assert best_spread([2.0, 2.04, 2.6]) == pytest.approx(0.02)  # the outlier 2.6 does not widen the limit
    assert best_spread([5.0]) == 0.0


def test_a_machine_that_is_slower_for_everyone_is_not_a_regression():
    # Every repeat and the calibration kernel 1.8x slower: a shared core, a lower clock.
    slow_machine = timing([1.8, 1.84, 2.3], [0.9, 0.9, 0.9])
    change = cpu_timing_change(BASE, slow_machine, factor=1.5, gated=True)
    assert change.outcome == "unchanged" and change.gated


def test_a_2x_slowdown_is_worse_and_the_limit_widens_with_the_measured_spread():
    doubled = timing([2.0, 2.06, 2.1], [0.5, 0.5, 0.5])
    change = cpu_timing_change(BASE, doubled, factor=1.5, gated=True)
    assert change.outcome == "worse"
    # limit 1.5 x (1 + 0.02 + 0.03) = 1.575, printed 1.58
    assert change.note == ("2.00× slower (CPU time per calibration, best of 3/3 repeats; "
                           "limit 1.5 × 1.05 = 1.58)")
    assert (change.baseline, change.current) == (1.0, 2.0)
    # The same 2x, but neither side could reproduce its best within 40%: the limit passes 2x, so no verdict.
    noisy_base = timing([1.0, 1.4, 1.5], [0.5, 0.5, 0.5])
    noisy = timing([2.0, 2.8, 2.9], [0.5, 0.5, 0.5])
    assert cpu_timing_change(noisy_base, noisy, factor=1.5, gated=True).outcome == "unchanged"


def test_faster_is_better_and_the_cpu_rule_is_used_only_when_both_sides_have_it():
    halved = timing([0.5, 0.51, 0.52], [0.5, 0.5, 0.5])
    assert cpu_timing_change(BASE, halved, factor=1.5, gated=True).outcome == "better"
    wall_only = replace(halved, cpu=None, calibration=None)
    change = timing_change(BASE, wall_only, 1.5, gated=True)
    assert change.note.startswith("2.00× faster") and "calibration" not in change.note


def test_one_repeat_a_side_is_shown_but_not_gated():
    change = timing_change(timing([1.0], [0.5]), timing([3.0], [0.5]), 1.5, gated=True)
    assert change.outcome == "worse" and not change.gated
    assert change.note.endswith("not gated: fewer than 2 timing repeats, so the noise is unknown (set repeats in the suite)")


def test_a_real_case_records_cpu_time_and_calibration_beside_wall_time_per_repeat():
    scene = catalog.build("bead", {"duration": 0.5})
    outcome = simulate(CaseTask("x", "mujoco/hinge", "hinge", {}, scene, 1e-3, 0.01, repeats=3))
    assert len(outcome.wall_times) == len(outcome.cpu_times) == len(outcome.calibrations) == 3
    # CPU time of a single-threaded run cannot exceed the wall time of the call around it by much,
    # and is more than nothing: 500 MuJoCo steps.
    assert all(0 < c for c in outcome.cpu_times)
    assert all(1e-4 < k < 1.0 for k in outcome.calibrations)
    assert outcome.trajectory.info.cpu_time == outcome.cpu_times[0]
    assert 1e-4 < calibration_cpu_time() < 1.0
