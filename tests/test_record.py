"""The typed spine: case records read and checked once, old run directories still readable, one metric
declaration flowing to show, report, baseline and gate."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from compare.gate.baseline import build_baseline
from compare.results import declared
from compare.results.declared import Metric, Tolerance
from compare.results.record import CaseRecord, Status
from engines.errors import UserError
from compare.results.store import ResultsDir
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from gate_support import edit_case, xval

FIXTURE = Path(__file__).parent / "fixtures" / "run-v1-smoke"


def test_a_run_written_by_the_previous_release_reads_whole_and_round_trips():
    """tests/fixtures/run-v1-smoke was written by main at cf334d7 (dict records, schema 1)."""
    results = load_results(FIXTURE)
    assert len(results.records) == 42
    assert results.counts() == {"ok": 42}
    for file in sorted((FIXTURE / "cases").glob("*.json")):
        raw = json.loads(file.read_text())
        record = CaseRecord.from_json(raw, file)
        assert record.status is Status.OK
        # Nothing lost, nothing added; position_error_l2 (that release's name) is read as position_error_rms.
        assert record.metrics["position_error_rms"] == raw["metrics"]["position_error_l2"]
        assert record.to_json() == {**raw, "metrics": declared.current_names(raw["metrics"])}
    by_variant = results.by_variant()
    assert [r.case.dt for r in by_variant[("bead", "mujoco/hinge")]] == [1e-2, 3e-3, 1e-3]
    sweeps = {(s.scene_id, s.engine): s for s in results.sweeps()}
    hinge = sweeps[("bead", "mujoco/hinge")]
    assert hinge.order is not None and hinge.order.order == pytest.approx(1.0, abs=0.1)  # semi-implicit Euler
    assert hinge.consistency.consistent is True


def test_show_report_and_gate_read_the_old_run(tmp_path, capsys):
    code, out, err = xval(capsys, "show", FIXTURE, "--format", "json")
    assert code == 0, err
    rows = json.loads(out)
    assert len(rows) == 42 and {r["status"] for r in rows} == {"ok"}
    assert all(r["consistent"] is not False for r in rows)
    code, out, err = xval(capsys, "report", FIXTURE, "--output", tmp_path / "old.html")
    assert code == 0, err
    assert "double-pendulum" in (tmp_path / "old.html").read_text()
    # The old run against a baseline made from it: the smoke suite (and baselines/smoke.json) moved on since.
    code, out, err = xval(capsys, "baseline", FIXTURE, "--output", tmp_path / "old-baseline.json")
    assert code == 0, err
    code, out, err = xval(capsys, "gate", FIXTURE, "--baseline", tmp_path / "old-baseline.json", "--timing", "report")
    assert code == 0, out + err
    assert "0 worse" in out + err and "42 unchanged" in out + err


def test_an_old_baseline_gates_a_new_run_on_the_renamed_metric(tmp_path, capsys):
    """A baseline and a run of the release that called position_error_rms position_error_l2 still gate
    today's runs on it: a doubled RMS error in a new run is worse against the old baseline."""
    code, _, err = xval(capsys, "baseline", FIXTURE, "--output", tmp_path / "baseline.json")
    assert code == 0, err
    old = tmp_path / "baseline.json"
    old.write_text(old.read_text().replace('"position_error_rms"', '"position_error_l2"'))
    assert old.read_text().count('"position_error_l2"') == 42
    run = tmp_path / "run"
    shutil.copytree(FIXTURE, run)
    for file in (run / "cases").glob("*.json"):  # written as today's runner writes them
        ResultsDir(run).write_case(CaseRecord.from_json(json.loads(file.read_text()), file))
    assert all('"position_error_rms"' in f.read_text() for f in (run / "cases").glob("*.json"))
    case = "bead|mujoco/hinge|dt=0.01"
    edit_case(run, case, lambda r: r["metrics"].update(position_error_rms=2 * r["metrics"]["position_error_rms"]))
    code, out, err = xval(capsys, "gate", run, "--baseline", old, "--timing", "report")
    assert code == 1, out + err
    worse = [line.split() for line in out.splitlines() if line.startswith("worse ")]
    assert [row[:5] for row in worse] == [["worse", "bead", "mujoco/hinge", "0.01", "position_error_rms"]]


@pytest.mark.parametrize("damage, message", [
    (lambda text: text[: len(text) // 2], r"case\.json: not valid JSON \(.* at line 1\); delete it and run with --resume"),
    (lambda text: json.dumps({"hello": 1}), r"case\.json: results schema version None, but this xval reads version 1"),
    (lambda text: text.replace('"status": "ok"', '"status": "fine"'),
     r"case\.json: field status is 'fine'; expected one of ok, unstable, failed, timeout, skipped"),
    (lambda text: text.replace('"scene_hash"', '"scene_hush"'),
     r"case\.json: missing field scene_hash; the file is damaged or not an xval case record"),
    (lambda text: text.replace('"dt": 0.01', '"dt": "fast"'), r"case\.json: field case\.dt must be a finite number, got 'fast'"),
    (lambda text: b"\xff\xfe".decode("latin-1") + text, r"case\.json: not valid JSON"),
])
def test_a_damaged_or_foreign_case_file_is_one_error_naming_the_file(tmp_path, damage, message, capsys):
    run = tmp_path / "run"
    shutil.copytree(FIXTURE, run)
    victim = sorted((run / "cases").glob("bead_mujoco_hinge_dt=0.01-*.json"))[0]
    damaged = run / "cases" / "case.json"
    damaged.write_text(damage(victim.read_text()))
    victim.unlink()
    with pytest.raises(UserError, match=message):  # RecordError (a UserError) for the record checks
        load_results(run)
    code, out, err = xval(capsys, "show", run)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert str(damaged) in err


def test_a_case_file_that_is_not_utf8_names_the_file(tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(FIXTURE, run)
    victim = sorted((run / "cases").glob("*.json"))[0]
    victim.write_bytes(b"\xff\xfe\x00garbage")
    code, out, err = xval(capsys, "show", run)
    assert code == 2 and err == f"xval: error: {victim}: not UTF-8 text; it is not an xval results file\n"


def test_an_undeclared_metric_name_is_an_error_not_a_silent_none():
    record = load_results(FIXTURE).records[0]
    assert record.metric("energy_drift") == record.metrics["energy_drift"]
    with pytest.raises(KeyError, match="'energy_drfit' is not a declared metric"):
        record.metric("energy_drfit")


# -- one declaration, everywhere -------------------------------------------------------------------

DUMMY = "peak_speed"
SUITE = """
name = "dummy-metric"
duration = 0.6
dt = [1e-2, 3e-3]
repeats = 1
[[scenes]]
id = "bead"
scene = "bead"
[[engines]]
id = "mujoco/hinge"
"""


@pytest.fixture
def dummy_metric():
    metric = declared.register(Metric(
        DUMMY, "m/s", "lower", gated=True, tolerance=Tolerance(0.1, 0.0), shown=True, label="vmax",
        report=True, title="peak speed",
        compute=lambda inputs: float(np.linalg.norm(inputs.trajectory.velocities, axis=2).max()),
        description="largest particle speed over the run",
    ))
    yield metric
    declared.unregister(DUMMY)


def test_a_metric_declared_once_appears_in_show_report_baseline_and_gate(dummy_metric, tmp_path, capsys):
    run = tmp_path / "run"
    run_suite(parse_suite(SUITE, str(tmp_path / "s.toml")), run, jobs=1)
    (run / "suite.toml").write_text(SUITE)
    results = load_results(run)
    speeds = [r.metric(DUMMY) for r in results.records]
    # The bead released at 60° from rest, radius 1 m, passes the bottom at t ≈ 0.54 s (a quarter of its 2.15 s
    # period) at √(2 g r (1 − cos 60°)) = √g m/s.
    assert all(s == pytest.approx(np.sqrt(9.81), rel=0.02) for s in speeds), speeds

    code, out, _ = xval(capsys, "show", run, "--format", "json")
    assert sorted(row[DUMMY] for row in json.loads(out)) == sorted(speeds)
    code, out, _ = xval(capsys, "show", run)
    assert "vmax" in out.splitlines()[3]
    code, out, _ = xval(capsys, "show", run, "--format", "csv")
    assert DUMMY in out.splitlines()[0].split(",")

    code, _, err = xval(capsys, "report", run, "--output", tmp_path / "r.html")
    assert code == 0, err
    assert "peak speed" in (tmp_path / "r.html").read_text()

    baseline = tmp_path / "baseline.json"
    code, _, err = xval(capsys, "baseline", run, "--output", baseline)
    assert code == 0, err
    entries = json.loads(baseline.read_text())["cases"].values()
    assert sorted(e["metrics"][DUMMY] for e in entries) == sorted(speeds)
    assert build_baseline(results).cases  # the in-process path agrees

    code, out, err = xval(capsys, "gate", run, "--baseline", baseline, "--timing", "report")
    assert code == 0, out + err
    case_id = results.records[0].case.id
    edit_case(run, case_id, lambda r: r["metrics"].__setitem__(DUMMY, 3 * r["metrics"][DUMMY]))
    code, out, err = xval(capsys, "gate", run, "--baseline", baseline, "--timing", "report")
    assert code == 1
    assert DUMMY in out


def test_status_counts_follow_the_status_order_and_leave_out_absent_statuses():
    from types import SimpleNamespace

    from compare.results.record import status_counts

    records = [SimpleNamespace(status=Status(s)) for s in ("timeout", "ok", "failed", "ok", "skipped")]
    assert list(status_counts(records).items()) == [("ok", 2), ("failed", 1), ("timeout", 1), ("skipped", 1)]
