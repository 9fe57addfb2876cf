"""Metrics on synthetic trajectories with known answers, and the status rules for `unstable`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from compare.results.measure import apply_bounds
from compare.results.metrics import (
    Bounds,
    case_metrics,
    constraint_error,
    constraint_force_error,
    divergence_time,
    energy_drift,
    observed_order,
    position_error,
    stepping_cost,
    summarize_error,
)
from engines.scene import catalog
from engines.reference.reference import solve
from engines.scene.trajectory import RunInfo, Trajectory

BEAD = catalog.build("bead", {"duration": 1.0})  # m = 1 kg, L = 1 m, g = 9.81: E* = 9.81 J


def trajectory(t, positions, velocities, forces=None, steps=100, dt=0.01) -> Trajectory:
    info = RunInfo("synthetic", "synthetic/x", "0", dt, steps=steps, wall_time=0.5)
    return Trajectory(np.asarray(t, float), positions, velocities, info, forces)


@pytest.fixture(scope="module")
def exact():
    t = np.linspace(0.0, 1.0, 101)
    positions, velocities, forces = solve(BEAD).at(t)
    return t, positions, velocities, forces


def test_constant_offset_gives_that_error_everywhere(exact):
    t, p, v, _ = exact
    e = position_error(p + np.array([0.3, 0.0, 0.4]), p)
    np.testing.assert_allclose(e, 0.5, rtol=1e-12)
    summary = summarize_error(e)
    assert summary.final == pytest.approx(0.5) and summary.rms == pytest.approx(0.5) and summary.linf == pytest.approx(0.5)


def test_error_is_max_over_particles_and_rms_is_the_root_mean_square():
    reference = np.zeros((2, 2, 3))
    moved = reference.copy()
    moved[0, 1] = [0.0, 0.0, 3.0]  # sample 0: particle 1 off by 3 m
    moved[1, 0] = [4.0, 0.0, 0.0]  # sample 1: particle 0 off by 4 m
    e = position_error(moved, reference)
    np.testing.assert_allclose(e, [3.0, 4.0])
    summary = summarize_error(e)
    assert (summary.final, summary.linf) == (4.0, 4.0)
    assert summary.rms == pytest.approx(math.sqrt((9 + 16) / 2))


def test_divergence_time_is_the_first_sample_strictly_above_delta_L():
    t = np.arange(9) / 8.0  # exact binary fractions
    e = 2.0 * t  # e(1/8) = 0.25 exactly: not above a 0.25 threshold
    assert divergence_time(t, e, 0.25) == 0.25
    assert divergence_time(t, e, 10.0) is None
    # An unstable run cut at its first non-finite sample diverges there at the latest.
    assert divergence_time(t[:3], e[:3], 10.0, end_of_data=0.375) == 0.375


def test_energy_ramp_and_constraint_error_of_a_sinking_bead():
    # Bead at rest sinking through its wire at a = 0.02 m/s: E(t) − E(0) = −m g a t,
    # so the drift is a·t_end = 0.02 (in E* = m g L with L = 1 m), and the
    # particle is a·t metres inside the wire.
    t = np.linspace(0.0, 1.0, 11)
    p = np.zeros((11, 1, 3))
    p[:, 0, 2] = -1.0 + 0.02 * t
    v = np.zeros_like(p)
    assert energy_drift(BEAD, p, v) == pytest.approx(0.02, rel=1e-12)
    assert constraint_error(BEAD, p) == pytest.approx(0.02, rel=1e-12)


def test_the_exact_solution_conserves_energy_and_holds_the_constraint(exact):
    _, p, v, _ = exact
    assert energy_drift(BEAD, p, v) < 1e-10
    assert constraint_error(BEAD, p) < 1e-12


def test_constraint_force_error(exact):
    _, _, _, f = exact
    assert constraint_force_error(f + np.array([0.0, 0.0, 2.0]), f) == pytest.approx(2.0)


def test_cost_is_the_median_per_simulated_second():
    cost = stepping_cost([0.3, 0.1, 0.2], simulated_time=2.0, steps=2000)
    assert cost.wall_time == 0.2
    assert cost.per_simulated_second == pytest.approx(0.1)
    assert cost.steps_per_second == pytest.approx(10000.0)


def test_case_metrics_of_an_offset_run(exact):
    t, p, v, f = exact
    run = trajectory(t, p + np.array([0.0, 0.0, 0.02]), v, f + np.array([1.0, 0.0, 0.0]))
    metrics, series = case_metrics(BEAD, run, p, f, scheduled_times=t, wall_times=[0.5], delta=1e-2)
    assert metrics.position_error_final == pytest.approx(0.02)
    assert metrics.divergence_time == 0.0  # 0.02 m > δ·L = 0.01 m from the start
    assert metrics.constraint_force_error == pytest.approx(1.0)
    assert metrics.constraint_force_error_relative == pytest.approx(1.0 / 9.81)
    assert metrics.cost_per_simulated_second == pytest.approx(0.5)  # 100 steps of 0.01 s in 0.5 s
    assert metrics.complete and metrics.n_samples == 101
    assert len(series.t) == 101 and series.position_error.max() == pytest.approx(0.02)


def test_case_metrics_of_a_truncated_run(exact):
    t, p, v, f = exact
    run = trajectory(t[:40], p[:40], v[:40])  # stopped at sample 40 of 101, no forces
    metrics, _ = case_metrics(BEAD, run, p[:40], f[:40], scheduled_times=t, wall_times=[0.5])
    assert not metrics.complete
    assert math.isnan(metrics.position_error_final)
    assert metrics.divergence_time == pytest.approx(t[40])
    assert metrics.constraint_force_error is None
    assert metrics.to_dict()["position_error_final"] is None  # JSON has no NaN


def _metrics(drift: float, c_err: float):
    t = np.zeros(1)
    p = np.zeros((1, 1, 3))
    p[0, 0, 2] = -1.0
    m, _ = case_metrics(BEAD, trajectory(t, p, np.zeros_like(p)), p, None, scheduled_times=t, wall_times=[1.0])
    from dataclasses import replace

    return replace(m, energy_drift=drift, constraint_error=c_err)


def test_unstable_when_energy_drift_passes_its_bound():
    status, message = apply_bounds("ok", "", _metrics(1.5, 0.0), Bounds(1.0, 0.1), BEAD)
    assert status == "unstable"
    assert message == "energy drift 1.5 E* exceeds the bound 1 E*"


def test_unstable_when_constraint_error_passes_its_bound_in_units_of_L():
    status, message = apply_bounds("ok", "", _metrics(0.0, 0.25), Bounds(1.0, 0.2), BEAD)
    assert status == "unstable"
    assert message == "constraint error 0.25 m exceeds the bound 0.2 L = 0.2 m"


def test_at_the_bound_is_still_ok_and_nan_is_past_it():
    assert apply_bounds("ok", "", _metrics(1.0, 0.1), Bounds(1.0, 0.1), BEAD) == ("ok", "")
    assert apply_bounds("ok", "", _metrics(math.nan, 0.0), Bounds(1.0, 0.1), BEAD)[0] == "unstable"


def test_other_statuses_are_kept():
    for status in ("failed", "timeout", "unstable"):
        assert apply_bounds(status, "why", _metrics(9.0, 9.0), Bounds(), BEAD) == (status, "why")


def test_observed_order_of_a_clean_power_law():
    dts = [1e-1, 3e-2, 1e-2, 3e-3, 1e-3]
    fit = observed_order(dts, [3.0 * dt**2 for dt in dts])
    assert fit.order == pytest.approx(2.0, abs=1e-9)
    assert (fit.dt_min, fit.dt_max, fit.n_points) == (1e-3, 1e-1, 5)


def test_observed_order_leaves_out_saturation_and_round_off():
    dts = [1.0, 0.3, 1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4]
    errors = [min(2.0, 50.0 * dt**4) for dt in dts]  # saturated at 2 m for the largest dts
    errors[-2:] = [1e-13, 3e-14]  # round-off
    errors[0] = None  # an unstable run
    fit = observed_order(dts, errors)
    assert fit.order == pytest.approx(4.0, abs=1e-9)
    assert (fit.dt_min, fit.dt_max, fit.n_points) == (1e-2, 1e-1, 3)  # 50·(3e-3)⁴ = 4e-9 m is under the floor


def test_observed_order_needs_three_points():
    fit = observed_order([1e-1, 1e-2], [1e-2, 1e-4])
    assert fit.order is None
    assert fit.reason == "only 2 consecutive dt with error in [1e-08, 0.1] m; need 3"


def test_a_value_just_past_its_bound_is_printed_with_the_digits_that_show_the_excess():
    status, message = apply_bounds("ok", "", _metrics(1.0000004, 0.1000021), Bounds(1.0, 0.1), BEAD)
    assert status == "unstable"
    assert message == ("energy drift 1.0000004 E* exceeds the bound 1 E*; "
                       "constraint error 0.100002 m exceeds the bound 0.1 L = 0.1 m")
