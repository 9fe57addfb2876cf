"""The history store (SQLite), ``xval history add | show``, ``xval run --history`` and ``xval gate --history``.

One real run of tests/gate_suite.toml per session (the ``base`` fixture);
every other run in these tests is that run with its start time moved and
chosen metrics scaled (tests/history_support.py), except the two runs of
the concurrency test, which are real ``xval run --history`` processes.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import re
import shutil
import sqlite3
import subprocess
from pathlib import Path

import pytest

from compare.gate.baseline import build_baseline
from compare.gate.entry import record_key
from compare.gate.gate import gate
from compare.suite.gate_rules import GateSettings
from compare.history import store as store_module
from compare.history.store import History, HistoryError, SCHEMA_VERSION
from compare.history.window import window_baseline

from history_support import ENGINE, add_in_process, SUITE, add, origin, real_run, synthetic, write_results, xval, xval_process


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return real_run(tmp_path_factory.mktemp("history-base") / "run")


def rows(out: str, verdict: str) -> list[list[str]]:
    return [re.split(r"\s{2,}", line) for line in out.splitlines() if line.startswith(verdict + " ")]


def dump(path: Path, run_id: int) -> tuple[list, list]:
    """Every stored column of run ``run_id`` and of its cases, read with plain sqlite3."""
    with sqlite3.connect(path) as connection:
        run = connection.execute("SELECT * FROM xval_runs WHERE id = ?", (run_id,)).fetchall()
        cases = connection.execute("SELECT * FROM xval_cases WHERE run_id = ? ORDER BY case_key", (run_id,)).fetchall()
    return run, cases


# -- the store ------------------------------------------------------------------------------------


def test_a_stored_run_reads_back_whole(base, tmp_path):
    with History.open(tmp_path / "h.sqlite", create=True) as history:
        run = add(history, base, 0)
        assert (run.id, run.suite_name, run.origin) == (1, "gate-test", origin(0))
        assert run.machine.fields["cpu_count"] == base.header["environment"]["cpu_count"]
        assert run.engines == base.header["environment"]["engines"]
        stored = {c.case_key: c for c in history.cases([run.id])}
        document = build_baseline(base)
        assert set(stored) == set(document.cases) and len(stored) == len(base.records) == 6
        for record in base.records:
            key = record_key(record)
            assert stored[key].entry == document.cases[key]
            assert history.record(run.id, key).to_json() == record.to_json()  # series and all
            assert stored[key].metrics["position_error_linf"] == record.metrics["position_error_linf"]
        stored_baseline = history.baseline_document(run)
        assert stored_baseline.cases == document.cases
        # Where it came from, as the baseline of the directory says it (only when it was made differs).
        assert dataclasses.replace(stored_baseline, created=None) == dataclasses.replace(document, created=None)


def test_a_history_of_the_old_metric_name_reads_it_as_the_new_one_and_gates_on_it(base, tmp_path, capsys):
    """Rows stored when position_error_rms was called position_error_l2 (made here by editing a stored run's
    text past its append-only triggers, as an older xval wrote it) read and gate under today's name."""
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        add(history, base, 0)
    with sqlite3.connect(path) as connection:
        connection.execute("DROP TRIGGER xval_cases_keep_update")
        connection.execute("UPDATE xval_cases SET entry = replace(entry, 'position_error_rms', 'position_error_l2'), "
                           "metrics = replace(metrics, 'position_error_rms', 'position_error_l2')")
        stored = connection.execute("SELECT entry || metrics FROM xval_cases").fetchall()
    assert all("position_error_l2" in row[0] and "position_error_rms" not in row[0] for row in stored)
    with History.open(path) as history:
        cases = {c.case_key: c for c in history.cases()}
    for record in base.records:
        case = cases[record_key(record)]
        assert "position_error_l2" not in case.metrics and "position_error_l2" not in (case.entry.metrics or {})
        assert case.metrics.get("position_error_rms") == record.metrics.get("position_error_rms")
        assert case.entry.metric("position_error_rms") == record.metrics.get("position_error_rms")
    worse = write_results(synthetic(base, 1, error=3.0), tmp_path / "worse")
    code, out, err = xval(capsys, "gate", worse, "--history", path, "--timing", "report")
    assert code == 1 and any(row[4:5] == ["position_error_rms"] for row in rows(out, "worse")), out + err


def test_appending_never_changes_an_earlier_run_and_stored_rows_refuse_updates(base, tmp_path):
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        add(history, base, 0)
    before = dump(path, 1)
    with History.open(path, create=True) as history:
        for index in (1, 2):
            add(history, synthetic(base, index, error=3.0), index)
        assert [r.id for r in history.runs()] == [1, 2, 3]
    assert dump(path, 1) == before
    with sqlite3.connect(path) as connection:
        for statement in ("UPDATE xval_runs SET commit_sha = 'x' WHERE id = 1", "DELETE FROM xval_runs WHERE id = 1",
                          "UPDATE xval_cases SET status = 'failed' WHERE run_id = 1", "DELETE FROM xval_cases"):
            with pytest.raises(sqlite3.IntegrityError, match="append-only"):
                connection.execute(statement)
    assert dump(path, 1) == before


def test_a_run_directory_added_twice_is_recorded_once(base, tmp_path, capsys):
    history = tmp_path / "h.sqlite"
    code, out, err = xval(capsys, "history", "add", base.path, "--history", history)
    assert code == 0 and err == ""
    assert re.match(rf"history {re.escape(str(history))}: run 1 added: suite gate-test, 6 cases, commit \S+", out)
    copy = shutil.copytree(base.path, tmp_path / "copy")
    resumed = shutil.copytree(base.path, tmp_path / "resumed")  # as a --resume with nothing left to run leaves it
    header = json.loads((resumed / "run.json").read_text())
    (resumed / "run.json").write_text(json.dumps({**header, "resumed": ["2026-12-01T20:00:00+00:00"],
                                                  "finished": "2026-12-01T20:00:01+00:00"}))
    for directory in (base.path, copy, resumed):
        code, out, err = xval(capsys, "history", "add", directory, "--history", history)
        assert code == 2 and out == ""
        assert err.count("\n") == 1
        assert re.fullmatch(
            rf"xval: error: {re.escape(str(directory))}: already in the history {re.escape(str(history))} as run 1 "
            rf"\(added [^)]+\); not added again\n", err)
    # Several directories: the one already there is refused, the new one still added.
    other = write_results(synthetic(base, 5), tmp_path / "other")
    code, out, err = xval(capsys, "history", "add", base.path, other, "--history", history)
    assert code == 2 and "as run 1" in err and err.count("\n") == 1
    assert re.match(rf"history {re.escape(str(history))}: run 2 added", out)
    with History.open(history) as opened:
        assert len(opened.runs()) == 2 and len(opened.cases()) == 12


def test_a_run_added_by_run_history_is_stored_as_history_add_stores_its_directory(tmp_path, capsys):
    """``xval run --history`` and ``xval history add DIR`` store the same run the same way: the same run key
    (so either refuses the other's run as a duplicate), header and source, and per case the same entry,
    metrics and whole record. Only when it was added, and its origin (the suite's git tree for ``run``,
    run.json's for ``add``), may differ."""
    directory, by_run, by_add = tmp_path / "run", tmp_path / "run.sqlite", tmp_path / "add.sqlite"
    code, out, err = xval(capsys, "run", SUITE, "--output", directory, "--jobs", "1", "--quiet", "--history", by_run)
    assert code == 0 and "run 1 added: suite gate-test, 6 cases" in out, out + err
    code, out, err = xval(capsys, "history", "add", directory, "--history", by_add)
    assert code == 0 and "run 1 added: suite gate-test, 6 cases" in out, out + err
    (run_row,), cases = dump(by_run, 1)
    (add_row,), added_cases = dump(by_add, 1)
    origin_and_added = {4, 5, 6, 9}  # commit_sha, dirty, commit_date, added (columns of xval_runs)
    assert [v for i, v in enumerate(run_row) if i not in origin_and_added] == \
        [v for i, v in enumerate(add_row) if i not in origin_and_added]
    assert len(cases) == 6 and cases == added_cases  # entry, metrics and the compressed record, byte for byte
    code, _, err = xval(capsys, "history", "add", directory, "--history", by_run)
    assert code == 2 and "already in the history" in err


def test_an_unfinished_run_is_refused(base, tmp_path, capsys):
    directory = shutil.copytree(base.path, tmp_path / "unfinished")
    header = json.loads((directory / "run.json").read_text())
    (directory / "run.json").write_text(json.dumps({**header, "finished": None}))
    code, _, err = xval(capsys, "history", "add", directory, "--history", tmp_path / "h.sqlite")
    assert code == 2
    assert "the run is unfinished; finish it first" in err and err.rstrip().endswith("then add it to the history")
    assert not (tmp_path / "h.sqlite").exists()  # refused before the history was made


@pytest.mark.parametrize("content, message", [
    (b"this is not a database, just text\n" * 50, r"not a readable xval history \(file is not a database\)"),
    (None, r"not an xval history \(a SQLite database with other tables: results\)"),
])
def test_a_damaged_or_foreign_file_is_one_clear_error(tmp_path, capsys, content, message):
    path = tmp_path / "history.sqlite"
    if content is None:
        with sqlite3.connect(path) as connection:
            connection.execute("CREATE TABLE results (x)")
    else:
        path.write_bytes(content)
    for argv in (("history", "show"), ("history", "report", "--output", tmp_path / "trend.html")):
        code, out, err = xval(capsys, *argv, "--history", path)
        assert code == 2 and out == "" and err.count("\n") == 1
        assert re.fullmatch(rf"xval: error: {re.escape(str(path))}: {message}; .*\n", err)


def test_a_truncated_history_is_one_clear_error(base, tmp_path, capsys):
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        for index in range(3):
            add(history, synthetic(base, index), index)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])
    code, out, err = xval(capsys, "history", "show", "--history", path)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert re.fullmatch(rf"xval: error: {re.escape(str(path))}: not a readable xval history \(database disk image is malformed\); "
                        r"restore it from a copy, or give --history a new file\n", err)


def test_missing_history_and_bad_locations_name_the_fix(tmp_path, capsys):
    code, _, err = xval(capsys, "history", "show", "--history", tmp_path / "none.sqlite")
    assert code == 2 and "no such history; make one with 'xval history add DIR --history" in err
    code, _, err = xval(capsys, "history", "show", "--history", tmp_path)
    assert code == 2 and err == f"xval: error: --history: {tmp_path} is a directory; give a file, e.g. {tmp_path / 'history.sqlite'}\n"
    code, _, err = xval(capsys, "run", SUITE, "--output", tmp_path / "never", "--history", "mysql://x/y")
    assert code == 2 and "mysql:// is not supported" in err
    assert not (tmp_path / "never").exists()  # refused before the run


def test_an_older_store_is_migrated_and_a_newer_one_refused(base, tmp_path, monkeypatch):
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        add(history, base, 0)
    before = dump(path, 1)
    later = lambda dialect: ["ALTER TABLE xval_runs ADD COLUMN note TEXT"]  # noqa: E731 (a made-up version 2)
    monkeypatch.setattr(store_module, "MIGRATIONS", [*store_module.MIGRATIONS, later])
    monkeypatch.setattr(store_module, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    with History.open(path) as history:
        assert history.schema_version() == SCHEMA_VERSION + 1
        assert [r.id for r in history.runs()] == [1]
    assert dump(path, 1)[0] == [before[0][0] + (None,)] and dump(path, 1)[1] == before[1]
    monkeypatch.undo()
    with pytest.raises(HistoryError, match=rf"history schema version {SCHEMA_VERSION + 1}, but this xval reads up to "
                                           rf"{SCHEMA_VERSION}; upgrade xval"):
        History.open(path)


def test_writers_at_once_all_land_even_when_creating_the_file(base, tmp_path):
    path = tmp_path / "h.sqlite"
    context = multiprocessing.get_context("fork")
    barrier = context.Manager().Barrier(4)
    with context.Pool(4) as pool:
        ids = pool.starmap(add_in_process, [(str(path), str(base.path), i, barrier) for i in range(4)])
    assert sorted(ids) == [1, 2, 3, 4]
    with History.open(path) as history:
        assert len(history.runs()) == 4 and len(history.cases()) == 24


def test_two_xval_runs_with_history_at_once_both_land_with_the_suites_commit(tmp_path):
    # The suite lives in a git repository of its own: the runs record its commit, not xval's.
    repository = tmp_path / "project"
    repository.mkdir()
    shutil.copy(SUITE, repository / "suite.toml")
    for command in (["init", "-q"], ["add", "suite.toml"],
                    ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "suite"]):
        subprocess.run(["git", *command], cwd=repository, check=True)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repository, capture_output=True, text=True).stdout.strip()
    history = tmp_path / "h.sqlite"
    processes = [xval_process("run", repository / "suite.toml", "--output", tmp_path / name, "--jobs", "1",
                              "--history", history) for name in ("a", "b")]
    outputs = [p.communicate(timeout=240) for p in processes]
    for process, (out, err) in zip(processes, outputs):
        assert process.returncode == 0, err
        assert re.search(rf"run [12] added: suite gate-test, 6 cases, commit {head[:10]}, ", out)
    with History.open(history) as opened:
        runs = opened.runs()
        assert sorted(r.id for r in runs) == [1, 2]
        assert {r.origin.commit for r in runs} == {head} and not any(r.origin.dirty for r in runs)
        assert {Path(r.source).name for r in runs} == {"a", "b"}
        assert len(opened.cases()) == 12
    # An unchanged rerun passes the windowed gate (the window of b is a: b itself is left out). Timing is
    # shown, not gated: the two ran at once on a shared machine (the timing rule is tested on set numbers).
    gated = xval_process("gate", tmp_path / "b", "--history", history, "--timing", "report")
    out, err = gated.communicate(timeout=120)
    assert gated.returncode == 0, out + err
    assert "window of the last 1 runs of suite 'gate-test'" in out and "\nworse " not in out


# -- show --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def three_runs(base, tmp_path_factory):
    path = tmp_path_factory.mktemp("history-three") / "h.sqlite"
    with History.open(path, create=True) as history:
        for index, error in enumerate((1.0, 2.0, 4.0)):
            add(history, synthetic(base, index, error=error), index)
    return path


def test_show_json_has_one_object_per_run_and_case_with_the_metrics(base, three_runs, capsys):
    code, out, _ = xval(capsys, "history", "show", "--history", three_runs, "--engine", ENGINE,
                        "--metric", "position_error_linf", "--last", "2", "--format", "json")
    assert code == 0
    table = json.loads(out)
    assert [(r["run"], r["dt"]) for r in table] == [(run, dt) for run in (2, 3) for dt in (1e-2, 5e-3, 2.5e-3)]
    assert set(table[0]) == {"run", "commit", "dirty", "commit_date", "date", "machine", "machine_name", "suite", "scene",
                             "engine", "dt", "status", "position_error_linf"}
    original = {r.case.dt: r.metrics["position_error_linf"] for r in base.records if r.case.engine == ENGINE}
    for row in table:
        factor = {2: 2.0, 3: 4.0}[row["run"]]
        assert row["position_error_linf"] == pytest.approx(factor * original[row["dt"]], rel=1e-15)
        assert row["commit"] == origin(row["run"] - 1).commit and row["scene"] == "bead" and row["status"] == "ok"


def test_show_table_lists_runs_cases_and_the_short_metrics(three_runs, capsys):
    code, out, _ = xval(capsys, "history", "show", "--history", three_runs, "--engine", "reference/*", "--scene", "bead")
    assert code == 0
    lines = out.splitlines()
    assert re.split(r"\s{2,}", lines[0]) == ["run", "commit", "date", "machine", "scene", "engine", "dt", "status",
                                             "error/m", "drift/E*", "c.err/m", "wall s/s", "order"]
    body = [line for line in lines[1:] if re.match(r"\d+  ", line)]
    assert len(body) == 3 * 6
    assert re.split(r"\s{2,}", body[0])[:8] == ["1", "0000000000", "2026-11-01 12:00", body[0].split()[4], "bead",
                                                "reference/loose", "0.01", "ok"]
    assert "18 cases of 3 runs from" in out


def test_show_an_unknown_metric_lists_the_declared_ones(three_runs, capsys):
    code, _, err = xval(capsys, "history", "show", "--history", three_runs, "--metric", "speed")
    assert code == 2 and err.startswith("xval: error: --metric: unknown metric 'speed'; declared metrics are: position_error_linf, ")


def test_show_reads_a_metric_by_its_name_before_the_rename(three_runs, capsys):
    code, out, _ = xval(capsys, "history", "show", "--history", three_runs, "--metric", "position_error_l2", "--format", "json")
    table = json.loads(out)
    assert code == 0 and len(table) == 3 * 6
    assert all(isinstance(row["position_error_rms"], float) for row in table if row["status"] == "ok")


# -- the windowed gate --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def window(base, tmp_path_factory):
    """Five runs of unchanged accuracy whose timings wander by ±40 % from run to run (repeats within ±1 %)."""
    path = tmp_path_factory.mktemp("history-window") / "h.sqlite"
    with History.open(path, create=True) as history:
        for index in range(5):
            add(history, synthetic(base, index, timing=0.6 + 0.2 * index, tight=True), index)
    return path


def test_window_gate_catches_a_doubled_error_and_passes_an_unchanged_rerun(base, window, tmp_path, capsys):
    code, out, _ = xval(capsys, "gate", base.path, "--history", window, "--window", "5", "--timing", "report")
    assert code == 0, out
    assert out.startswith(f"history {window}: window of the last 5 runs of suite 'gate-test' on this machine")
    assert rows(out, "worse") == [] and ": 0 worse, " in out
    regressed = write_results(synthetic(base, 9, error=2.0), tmp_path / "regressed")
    code, out, _ = xval(capsys, "gate", regressed, "--history", window, "--timing", "report")
    assert code == 1
    worse = rows(out, "worse")
    assert {(r[1], r[2], r[4]) for r in worse} == {
        ("bead", ENGINE, metric) for metric in ("position_error_linf", "position_error_rms", "position_error_final")}


def test_gate_takes_a_baseline_or_a_history(base, window, capsys):
    for argv in ((), ("--baseline", "b.json", "--history", window)):
        code, out, err = xval(capsys, "gate", base.path, *argv)
        assert (code, out) == (2, "")
        assert err == ("xval: error: give either --baseline BASELINE.json or --history FILE (the last runs in a history), "
                       "not both or neither\n")
    code, _, err = xval(capsys, "gate", base.path, "--baseline", "b.json", "--window", "3")
    assert code == 2 and err == "xval: error: --window: only with --history FILE\n"


def test_a_history_without_this_suite_on_this_machine_gates_every_case_as_new(base, tmp_path, capsys):
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        add(history, synthetic(base, 0, machine={"cpu": "another CPU"}), 0)
    code, out, _ = xval(capsys, "gate", base.path, "--history", path)
    assert code == 0
    assert out.startswith(f"history {path}: no earlier run of suite 'gate-test' on this machine")
    assert len(rows(out, "new")) == 6


def test_window_gate_holds_accuracy_to_the_best_run_of_the_window(base, tmp_path):
    # Each run 5 % worse than the one before: inside the 10 % tolerance run to run, 22 % past the best.
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        for index in range(5):
            add(history, synthetic(base, index, error=1.05 ** index), index)
        current = build_baseline(synthetic(base, 5, error=1.05 ** 5))
        creep = window_baseline(history, synthetic(base, 5, error=1.05 ** 5), 5)
        latest_only = window_baseline(history, synthetic(base, 5, error=1.05 ** 5), 1)
    verdicts = lambda report: {c.outcome for c in report.cases if c.engine == ENGINE}  # noqa: E731
    assert verdicts(gate(creep.document, current, GateSettings(), timing="report")) == {"worse"}
    assert verdicts(gate(latest_only.document, current, GateSettings(), timing="report")) == {"unchanged"}


def test_window_gate_times_against_the_windows_spread(base, window):
    with History.open(window) as history:
        def verdicts(factor: float) -> set[str]:
            current = synthetic(base, 9, timing=factor, tight=True)
            document = window_baseline(history, current, 5).document
            report = gate(document, build_baseline(current), GateSettings())
            return {c.outcome for c in report.cases}

        # The window's runs cost 0.6 … 1.4 × the base: 1.6 × is past the 1.5 factor of their median (1.0)
        # but not past it by more than the window's spread (0.8 × the base, plus the repeats'); 2.5 × is past both.
        assert verdicts(1.6) == {"unchanged"}
        assert verdicts(2.5) == {"worse"}


def test_window_leaves_out_other_machines_and_the_run_itself(base, tmp_path):
    path = tmp_path / "h.sqlite"
    with History.open(path, create=True) as history:
        add(history, synthetic(base, 0, error=0.5, machine={"cpu": "another CPU"}), 0)
        add(history, synthetic(base, 1), 1)
        add(history, base, 2)
        window = window_baseline(history, base, 5)
    assert [r.id for r in window.runs] == [2]
    own = build_baseline(base).cases
    assert {k: e.metrics for k, e in window.document.cases.items()} == {k: e.metrics for k, e in own.items()}
