"""Stored series are rounded to SERIES_DIGITS significant digits with array arithmetic
(compare.results.series.round_significant); they must be the numbers string formatting gives."""

from __future__ import annotations

import math

import numpy as np
import pytest

from compare.results.series import SERIES_DIGITS, SeriesView, as_json_list, round_significant


def formatted(x: float, digits: int = SERIES_DIGITS) -> float:
    return float(format(x, f".{digits}g"))


def test_random_values_over_forty_decades_round_as_formatting_does():
    rng = np.random.default_rng(20261201)
    values = rng.standard_normal(200_000) * 10.0 ** rng.uniform(-20, 20, 200_000)
    got = round_significant(values)
    expected = np.array([formatted(x) for x in values.tolist()])
    np.testing.assert_array_equal(got, expected)


def test_short_decimals_full_of_ties_round_as_formatting_does():
    # Seven-digit decimals: a tenth of them end in 5, a tie at six digits (half to even on the binary value).
    rng = np.random.default_rng(7)
    values = rng.integers(1_000_000, 10_000_000, 100_000) / 10.0 ** rng.integers(-5, 12, 100_000)
    got = round_significant(values)
    np.testing.assert_array_equal(got, [formatted(x) for x in values.tolist()])


@pytest.mark.parametrize("digits", [1, 3, 6, 9])
def test_values_next_to_powers_of_ten_and_at_the_ends_of_the_range(digits):
    powers = 10.0 ** np.arange(-30, 31)
    values = np.concatenate([
        powers, np.nextafter(powers, 0), np.nextafter(powers, np.inf), -powers,
        9.999995 * powers, 1.000005 * powers, [5e-324, 2.2250738585072014e-308, 1.7976931348623157e308],
        [0.35, 0.125, 2.5, 1234565.0, 0.1 + 0.2, 1 / 3, 1.0000050, 99999.95],  # decimal ties
    ])
    got = round_significant(values, digits)
    expected = np.array([formatted(x, digits) for x in values.tolist()])
    np.testing.assert_array_equal(got, expected)


def test_zeros_keep_their_sign_and_non_finite_values_become_none():
    assert math.copysign(1.0, round_significant(np.array([-0.0]))[0]) == -1.0
    listed = as_json_list(round_significant(np.array([[1.23456789, np.nan], [np.inf, -0.0]])))
    assert listed == [[1.23457, None], [None, -0.0]]


def test_shapes_are_kept_as_nested_lists_of_python_floats():
    out = as_json_list(round_significant(np.arange(12.0).reshape(2, 3, 2) / 7))
    assert len(out) == 2 and len(out[0]) == 3 and len(out[0][0]) == 2
    assert type(out[1][2][1]) is float and out[1][2][1] == formatted(11 / 7)
    assert as_json_list(round_significant(np.zeros((0, 2, 3)))) == []


def test_a_run_keeps_in_memory_the_series_its_files_hold(tmp_path):
    """The runner keeps the records it wrote, their series as arrays read as lists on demand
    (series.SeriesView): what a reader of the run's summary sees must be what the file says."""
    import json

    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite

    suite = parse_suite('duration = 0.3\ndt = [1e-2]\n[[scenes]]\nscene = "double-pendulum"\n'
                        '[[engines]]\nid = "mujoco/connect"\n[[engines]]\nid = "pymunk/pin"\n')
    summary = run_suite(suite, tmp_path / "out", jobs=1)
    stored = {d["case"]["id"]: d for d in
              (json.loads(p.read_text()) for p in (tmp_path / "out" / "cases").glob("*.json"))}
    assert len(summary.records) == len(stored) == 2
    for record in summary.records:
        assert "constraint_forces" in record.series
        assert dict(record.series) == stored[record.case.id]["series"]
        # One shape: the record the runner built is the file it wrote, field for field.
        assert record.to_json() == stored[record.case.id]


def test_a_series_view_reads_non_finite_values_as_none():
    view = SeriesView({"reference_positions": np.array([[[np.nan, 0.0, 1.5]]]), "t": np.array([0.0, 0.01])})
    assert list(view) == ["reference_positions", "t"] and len(view) == 2
    assert view["reference_positions"] == [[[None, 0.0, 1.5]]] and view["t"] == [0.0, 0.01]
