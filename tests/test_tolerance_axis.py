"""The tolerance axis: a suite's tolerance sweep runs error-controlled variants (Drake's) per tolerance.

Reading and planning need no Drake (without it Drake's cases are skipped, on their dt
sweep); the run at the end uses the real Drake and skips, with the pip line, without it.
"""

from __future__ import annotations

import concurrent.futures as cf
import sys
from pathlib import Path
import importlib.util

import numpy as np
import pytest

from compare.run.results import load_results
from compare.results.sweep import sweeps
from compare.run.runner import plan, run_suite
from compare.suite.reader import parse_suite
from engines.errors import UserError

HAVE_DRAKE = importlib.util.find_spec("pydrake") is not None

SUITE = """
duration = 0.5
dt = [1e-2, 1e-3]
tolerance = { from = 1e-4, to = 1e-8, per_decade = 1 }
scenes = [{ scene = "double-pendulum" }]
engines = ["drake/rk3", "drake/semi-explicit-euler", "mujoco/hinge-rk4"]
"""


def test_a_tolerance_sweep_is_read_tightest_last():
    suite = parse_suite(SUITE)
    assert suite.tolerances == (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
    assert parse_suite(SUITE.replace("tolerance = { from = 1e-4, to = 1e-8, per_decade = 1 }",
                                     "tolerance = [1e-6, 1e-4]")).tolerances == (1e-4, 1e-6)


@pytest.mark.parametrize("line, words", [
    ("tolerance = []", "is empty; list at least one tolerance"),
    ("tolerance = [1e-4, 1e-4]", "lists the same tolerance twice"),
    ("tolerance = { from = 1e-4, to = 1e-8 }", "the sweep needs per_decade"),
    ("tolerance = -1", "must be a list of tolerances or a table"),
])
def test_a_bad_tolerance_names_the_key_and_the_fix(line, words):
    with pytest.raises(UserError, match=words):
        parse_suite(SUITE.replace("tolerance = { from = 1e-4, to = 1e-8, per_decade = 1 }", line))


def test_without_a_tolerance_key_nothing_changes():
    text = SUITE.replace("tolerance = { from = 1e-4, to = 1e-8, per_decade = 1 }\n", "")
    suite = parse_suite(text)
    assert suite.tolerances == ()
    assert all(case.tolerance is None for case in plan(suite))
    assert len(plan(suite)) == 3 * 2


@pytest.mark.skipif(not HAVE_DRAKE, reason="Drake is not installed: pip install 'xval[drake]'")
def test_error_controlled_variants_get_one_case_per_tolerance_instead_of_per_dt():
    suite = parse_suite(SUITE)
    cases = plan(suite)
    by_engine: dict[str, list] = {}
    for case in cases:
        by_engine.setdefault(case.engine.label, []).append(case)
    rk3 = by_engine["drake/rk3"]
    assert [c.tolerance for c in rk3] == [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    assert all(c.dt == suite.sample_interval and c.engine.options == {"accuracy": c.tolerance} for c in rk3)
    assert rk3[2].id == "double-pendulum|drake/rk3|dt=0.01|tol=1e-06"
    # A fixed-step variant of the same engine, and other engines, keep the dt sweep.
    for label in ("drake/semi-explicit-euler", "mujoco/hinge-rk4"):
        assert [(c.dt, c.tolerance) for c in by_engine[label]] == [(1e-2, None), (1e-3, None)]


@pytest.mark.skipif(not HAVE_DRAKE, reason="Drake is not installed: pip install 'xval[drake]'")
def test_a_tolerance_sweep_runs_and_its_error_falls_with_the_tolerance(tmp_path):
    with cf.ThreadPoolExecutor(2) as executor:
        run_suite(parse_suite(SUITE), tmp_path / "r", executor=executor)
    records = load_results(tmp_path / "r").records
    rk3 = sorted((r for r in records if r.case.engine == "drake/rk3"), key=lambda r: -r.case.tolerance)
    assert [r.case.tolerance for r in rk3] == [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    assert all(r.status.value == "ok" and r.run_info["settings"]["accuracy"] == r.case.tolerance for r in rk3)
    errors = np.array([r.metric("position_error_linf") for r in rk3])
    # RK3's error follows its accuracy (tests/test_engine_drake.py): tenfold per decade, here at least 5×.
    assert (errors[:-1] / errors[1:] > 5).all()
    sweep = next(s for s in sweeps(records) if s.engine == "drake/rk3")
    assert sweep.order is None and sweep.consistency.consistent is True
    assert sweep.finest_ok.case.tolerance == 1e-8
    fixed = next(s for s in sweeps(records) if s.engine == "drake/semi-explicit-euler")
    assert fixed.order is not None  # a dt sweep still gets its order
    # Exports carry the tolerance; the short table shows it where a dt sweep shows its finest dt.
    from compare.results.table import case_rows, scene_tables

    assert sorted(r["tolerance"] for r in case_rows(records) if r["engine"] == "drake/rk3") == [1e-8, 1e-7, 1e-6,
                                                                                               1e-5, 1e-4]
    assert "tol 1e-08" in scene_tables(sweeps(records))
    # The verdict lines name a tolerance point by its tolerance.
    from compare.results.verdict import points

    rk3_sweep = next(s for s in sweeps(records) if s.engine == "drake/rk3")
    assert [p.tolerance for p in points(rk3_sweep)] == [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    assert points(rk3_sweep)[-1].step.strip() == "tol 1e-08"


def test_the_reference_sweeps_both_of_its_tolerances():
    suite = parse_suite(SUITE.replace('"drake/rk3"', '"reference/dop853"'))
    cases = [c for c in plan(suite) if c.engine.label == "reference/dop853"]
    assert [c.engine.options for c in cases][:2] == [{"rtol": 1e-4, "atol": 1e-4}, {"rtol": 1e-5, "atol": 1e-5}]


def test_a_command_engine_that_declares_tolerance_joins_the_tolerance_axis(tmp_path):
    """Protocol 1 unchanged: the tolerance reaches the program as options.tolerance."""
    suite = tmp_path / "suite.toml"
    suite.write_text(f"""
name = "command-tolerance"
duration = 1.0
dt = [1e-2]
tolerance = [1e-8, 1e-10, 1e-12]
[[scenes]]
scene = "bead"
[[engines]]
command = ["{sys.executable}", "{Path(__file__).parent / "tolerance_program.py"}"]
label = "adaptive"
capabilities = ["tolerance"]
""")
    run_suite(parse_suite(suite.read_text(), str(suite)), tmp_path / "r", jobs=1)
    records = sorted(load_results(tmp_path / "r").records, key=lambda r: -r.case.tolerance)
    assert [(r.case.engine, r.case.tolerance, r.status.value) for r in records] == [
        ("command/adaptive", 1e-8, "ok"), ("command/adaptive", 1e-10, "ok"), ("command/adaptive", 1e-12, "ok")]
    errors = [r.metric("position_error_linf") for r in records]
    # h = tolerance^(1/4) (10, 3.2 and 1 ms) and RK4's error ~ h⁴: about 100× less per step of the sweep.
    assert errors[0] > 10 * errors[1] > 100 * errors[2]
    sweep = next(s for s in sweeps(load_results(tmp_path / "r").records))
    assert sweep.order is None and sweep.consistency.consistent is True
