"""``xval score``: grading CSV files against the reference. The reference's own CSV scores ~0, a CSV
perturbed by a known amount reports that amount, any sample times work, and a file that does not fit the
scene is exit 2 naming the line and column.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare.cli import main
from compare.results.score import SCORE_METRICS, score
from compare.results.table import row_fields
from engines.scene import catalog
from engines.external import protocol
from engines.reference.reference import solve
from cli_support import run_cli as run

SCENE = catalog.build("double-pendulum", {"duration": 2.0, "theta1": 60})




@pytest.fixture(scope="module")
def reference_csv(tmp_path_factory):
    """The reference's own CSV, as `xval simulate --forces` writes it (dt 1e-3, samples every 0.01 s)."""
    path = tmp_path_factory.mktemp("score") / "reference.csv"
    try:
        main(["simulate", "double-pendulum", "--param", "duration=2", "--param", "theta1=60", "--dt", "1e-3",
              "--forces", "--output", str(path)])
    except SystemExit as stop:
        assert stop.code in (0, None)
    return path


def rewrite(source, target, change):
    """Copy protocol CSV ``source`` to ``target`` with ``change(header, values)`` applied to its table."""
    table = protocol.read_csv(source.read_text())
    header, values = list(table.header), table.values.copy()
    header, values = change(header, values) or (header, values)
    target.write_text(protocol.write_csv(header, values))
    return target


def test_the_reference_scores_zero_against_itself(reference_csv, capsys):
    code, out, err = run(capsys, "score", "double-pendulum", str(reference_csv), "--param", "duration=2",
                         "--param", "theta1=60", "--format", "json")
    assert code == 0, err
    (row,) = json.loads(out)
    assert row["status"] == "ok" and row["n_samples"] == 201 and row["t_end"] == 2.0
    for name in ("position_error_final", "position_error_rms", "position_error_linf"):
        assert row[name] <= 1e-12
    assert row["divergence_time"] is None
    assert row["energy_drift"] < 1e-10 and row["constraint_error"] < 1e-12
    assert row["constraint_force_error"] < 1e-9


def test_a_known_perturbation_is_reported_as_that_amount(reference_csv, tmp_path):
    t = protocol.read_csv(reference_csv.read_text()).column("t")
    later = t >= 1.0 - 1e-12

    def shift(amount):
        def change(header, values):
            values[later, header.index("p1_x")] += amount
        return change

    small = rewrite(reference_csv, tmp_path / "small.csv", shift(1e-3))      # below δ·L = 0.02 m
    large = rewrite(reference_csv, tmp_path / "large.csv", shift(0.05))      # above it, from t = 1 s
    rows = score([small, large], SCENE)
    for row, amount in zip(rows, (1e-3, 0.05)):
        assert row["position_error_linf"] == pytest.approx(amount, rel=1e-9)
        assert row["position_error_final"] == pytest.approx(amount, rel=1e-9)
        assert row["position_error_rms"] == pytest.approx(amount * np.sqrt(later.mean()), rel=1e-9)
    assert rows[0]["divergence_time"] is None
    assert rows[1]["divergence_time"] == pytest.approx(1.0, abs=1e-12)


def test_any_sample_times_and_a_time_step_of_its_own_are_graded(tmp_path):
    """A file sampled at irregular times (a variable-step program) is compared at those times."""
    rng = np.random.default_rng(7)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0, 2.0, 57))])
    q, v, f = solve(SCENE).at(t)
    values = np.column_stack([t, np.concatenate([q, v], axis=2).reshape(len(t), -1), f.reshape(len(t), -1)])
    header = protocol.columns(SCENE, forces=True)
    path = tmp_path / "irregular.csv"
    path.write_text(protocol.write_csv(header, values, {"version": "variable-step 0.1"}))
    (row,) = score([path], SCENE)
    assert row["n_samples"] == 58 and row["position_error_linf"] < 1e-12 and row["constraint_force_error"] < 1e-9


def test_a_file_that_blows_up_is_unstable_and_diverges_where_it_stops(reference_csv, tmp_path):
    t = protocol.read_csv(reference_csv.read_text()).column("t")

    def blow_up(header, values):
        values[150:, header.index("v0_z")] = np.nan
    (row,) = score([rewrite(reference_csv, tmp_path / "nan.csv", blow_up)], SCENE)
    assert row["status"] == "unstable" and row["n_samples"] == 150
    assert row["message"] == "non-finite state at t = 1.5 s (line 152)"
    assert row["divergence_time"] == pytest.approx(t[150]) and row["position_error_final"] is None


def test_score_uses_the_metric_names_of_show_json():
    assert set(SCORE_METRICS) <= set(row_fields())


def test_the_table_has_one_line_per_file(reference_csv, capsys):
    code, out, _ = run(capsys, "score", "double-pendulum", str(reference_csv), str(reference_csv),
                       "--param", "duration=2", "--param", "theta1=60")
    lines = out.splitlines()
    assert code == 0 and lines[0].split() == ["file", "status", "samples", "t_end/s", "final/m", "rms/m", "linf/m",
                                              "diverged/s", "drift/E*", "c.err/m", "force/N"]
    assert len(lines) == 3 and all(line.startswith(str(reference_csv)) for line in lines[1:])


@pytest.mark.parametrize("change, args, message", [
    (lambda h, v: (h + ["q0_x"], np.column_stack([v, v[:, 0]])), [],
     "header (line 1), extra column 'q0_x' (column 22)"),
    (lambda h, v: ([c for c in h if c != "v1_y"], np.delete(v, h.index("v1_y"), axis=1)), [],
     "header (line 1), missing column 'v1_y'"),
    (lambda h, v: (h, v[1:]), [], "line 2 (sample 0), column 't': the first row is at t = 0.01 s"),
    (lambda h, v: (h, v[[0, 2, 1]]), [], "line 4 (sample 2), column 't': 0.01 s does not follow 0.02 s"),
    (None, ["--param", "theta1=90"], "line 2 (sample 0), column 'p0_z': -0.5000000000000001 m is not the initial "
                                     "state of 'double-pendulum' (-6.123233995736766e-17 m); pass the scene "
                                     "parameters the file was made with (--param NAME=VALUE)"),
])
def test_a_file_that_does_not_fit_the_scene_is_exit_2_naming_the_column(reference_csv, tmp_path, capsys, change,
                                                                         args, message):
    path = reference_csv if change is None else rewrite(reference_csv, tmp_path / "bad.csv", change)
    code, out, err = run(capsys, "score", "double-pendulum", str(path), "--param", "duration=2",
                         *(args or ["--param", "theta1=60"]))
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"xval: error: {path}: ") and message in err


def test_a_missing_file_is_exit_2(tmp_path, capsys):
    code, _, err = run(capsys, "score", "bead", str(tmp_path / "nosuch.csv"))
    assert code == 2 and "nosuch.csv: no such file" in err
