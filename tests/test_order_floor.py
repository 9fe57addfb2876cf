"""The observed order's asymptotic range starts at a multiple of the reference's own measured error
(compare.results.metrics.order_floor), not at a fixed 1e-8 · L, so a fourth-order method whose errors
fall below 1e-8 · L still gets its order."""

from __future__ import annotations

from pathlib import Path

import pytest

from compare.results.metrics import ORDER_FLOOR, observed_order, order_floor

ROOT = Path(__file__).resolve().parent.parent


def test_the_floor_is_ten_reference_errors_and_at_least_round_off():
    assert order_floor(1.4, 9.3e-13) == pytest.approx(9.3e-12)
    assert order_floor(1.0, 1e-15) == pytest.approx(1e-12)  # round-off of ~1e4 double-precision steps
    # Unknown (or not a number): today's floor, 1e-8 · L.
    assert order_floor(2.0, None) == order_floor(2.0, float("nan")) == order_floor(2.0, 0.0) == ORDER_FLOOR * 2.0


def test_rk4_errors_below_1e_8_L_give_their_order_with_the_reference_error_known():
    # The issue's compound double pendulum: RK4's errors fall 16× per halving, all below 1e-8 · L.
    dts, errors = [4e-3, 2e-3, 1e-3], [8.2e-9, 5.1e-10, 3.2e-11]
    assert observed_order(dts, errors, length=1.4).order is None  # the fixed floor leaves none
    fit = observed_order(dts, errors, length=1.4, reference_error=9.3e-13)
    assert fit.order == pytest.approx(4.0, abs=0.05) and fit.n_points == 3 and fit.floor == pytest.approx(9.3e-12)


def test_a_level_below_1e_8_L_is_an_engines_floor_not_convergence():
    # Second order down to 1e-9 m, then a level (an added inertia): the level is not in the fit.
    dts = [8e-3, 4e-3, 2e-3, 1e-3, 5e-4]
    errors = [6.4e-8, 1.6e-8, 4e-9, 1e-9, 0.98e-9]
    fit = observed_order(dts, errors, length=1.0, reference_error=1e-13)
    assert fit.order == pytest.approx(2.0, abs=1e-9) and fit.dt_min == 1e-3


def test_ours_rk4_variants_on_the_compound_double_pendulum_have_order_4(tmp_path):
    """The rigid two-link pendulum of models/double_pendulum.urdf: the reference's error is ~1e-12 m, ours'
    RK4 errors 2.7e-8, 1.7e-9 and 1.1e-10 m at dt 4, 2 and 1 ms (baumgarte-rk4, measured): order ≥ 3.5."""
    from compare.run.results import load_results
    from compare.results.sweep import sweeps
    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite
    from engines.ours.adapter import ENGINE as OURS

    rk4 = [name for name in OURS.variants if name.endswith("-rk4")]
    suite = parse_suite(
        'name = "order"\nduration = 2.0\ndt = [4e-3, 2e-3, 1e-3]\n'
        '[[scenes]]\nid = "cdp"\nmodel = "../models/double_pendulum.urdf"\nq0 = { shoulder = 30, elbow = -20 }\n'
        + "".join(f'[[engines]]\nid = "ours/{name}"\n' for name in rk4),
        str(ROOT / "suites" / "inline.toml"))
    run_suite(suite, tmp_path / "run", jobs=1, isolate=False)
    found = {s.engine: s for s in sweeps(load_results(tmp_path / "run").records) if not s.all_skipped}
    assert {"ours/baumgarte-rk4", "ours/projection-rk4"} <= set(found)  # the variants that take a rigid model
    for engine, sweep in found.items():
        bar = sweep.records[0].reference["reference_error"]
        assert bar < 1e-11, (engine, bar)  # the reference's own error, measured 1.1e-12 m
        length = sweep.records[0].characteristic.length
        # The old floor (1e-8 · L) would leave fewer than the three points an order needs.
        assert sum(r.metric("position_error_linf") < ORDER_FLOOR * length for r in sweep.records) >= 2
        assert sweep.order is not None and sweep.order.order >= 3.5, (engine, sweep.order)
