"""Guard rails around stored results: wrong answers that used to pass the gate, outputs that would replace
inputs, damaged files (one line naming the file, exit 2), and --resume re-running a damaged case."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from compare.cli import main
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from cli_support import run_cli as xval

SUITE = ('name = "guard"\ndt = [2e-2, 1e-2]\nduration = 0.2\nengines = ["mujoco/hinge", "pymunk/pin"]\n'
         '[[scenes]]\nscene = "bead"\n')




@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A finished run of SUITE and its baseline (4 cases, all ok)."""
    root = tmp_path_factory.mktemp("guard")
    (root / "s.toml").write_text(SUITE)
    run_suite(parse_suite(SUITE, str(root / "s.toml")), root / "r", jobs=1)
    main_args = ["baseline", str(root / "r"), "--output", str(root / "baseline.json")]
    try:
        main(main_args)
    except SystemExit as stop:
        assert not stop.code
    return root


@pytest.fixture
def copy(run, tmp_path):
    shutil.copytree(run / "r", tmp_path / "r")
    return tmp_path / "r"


def one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("xval: error: "), err
    return lines[0][len("xval: error: "):]


def test_a_run_with_every_case_missing_fails_the_gate_naming_them(run, copy, capsys):
    for case in (copy / "cases").glob("*.json"):
        case.unlink()
    code, out, _ = xval(capsys, "gate", copy, "--baseline", run / "baseline.json", "--timing", "report")
    assert code == 1
    assert "note: 4 of the baseline's 4 cases are missing from the results (bead · mujoco/hinge · dt=0.02" in out
    assert "gate FAILED" in out


def test_metrics_null_where_the_baseline_had_numbers_fail_the_gate(run, copy, capsys):
    # What a case whose reference timed out records: ok, but no position metrics.
    case = next((copy / "cases").glob("bead_mujoco_hinge_dt=0.01-*.json"))
    record = json.loads(case.read_text())
    for name in ("position_error_final", "position_error_rms", "position_error_linf"):
        record["metrics"][name] = None
    record["message"] = "no reference solution (the reference of scene 'bead' ran past the timeout of 2 s)"
    case.write_text(json.dumps(record))
    code, out, _ = xval(capsys, "gate", copy, "--baseline", run / "baseline.json", "--timing", "report")
    assert code == 1, out
    worse = [line for line in out.splitlines() if line.startswith("worse")]
    assert any("position_error_linf" in line and "no value now, the baseline had one: no reference solution" in line
               for line in worse), out


@pytest.mark.parametrize("argv, message", [
    (["gate", "{r}", "--baseline", "{b}", "--junit", "{b}"], "--junit: {b} is the input {b}; writing it would replace what this command reads"),
    (["gate", "{r}", "--baseline", "{b}", "--summary", "{r}/run.json"], "--summary: {r}/run.json is the input {r}/run.json"),
    (["baseline", "{r}", "--output", "{r}/run.json"], "--output: {r}/run.json is the input {r}/run.json"),
    (["baseline", "{r}", "--output", "{r}/suite.toml"], "--output: {r}/suite.toml is the input {r}/suite.toml"),
    (["report", "{r}", "--output", "{case}"], "--output: {case} is inside the input directory {r}/cases"),
    (["show", "{r}", "--output", "{case}"], "--output: {case} is inside the input directory {r}/cases"),
])
def test_an_output_never_replaces_an_input(run, copy, capsys, argv, message):
    case = next((copy / "cases").glob("*.json"))
    baseline = copy.parent / "baseline.json"
    shutil.copy(run / "baseline.json", baseline)
    before = {p: p.read_bytes() for p in [baseline, *copy.rglob("*") ] if p.is_file()}
    fill = {"{r}": str(copy), "{b}": str(baseline), "{case}": str(case)}

    def filled(text: str) -> str:
        for k, v in fill.items():
            text = text.replace(k, v)
        return text

    code, _, err = xval(capsys, *[filled(a) for a in argv])
    assert code == 2
    assert one_error_line(err).startswith(filled(message))
    assert {p: p.read_bytes() for p in before} == before


def test_show_writes_to_standard_output_or_a_file(run, tmp_path, capsys):
    code, out, _ = xval(capsys, "show", run / "r", "--format", "csv", "--output", "-")
    assert code == 0 and out.startswith("scene")
    code, quiet, _ = xval(capsys, "show", run / "r", "--format", "csv", "--output", tmp_path / "cases.csv")
    assert code == 0 and quiet == "" and (tmp_path / "cases.csv").read_text() == out


def damage(path: Path, how: str) -> None:
    if how == "truncated":
        path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    elif how == "not UTF-8":
        path.write_bytes(b"\xff\xfe\x00garbage")
    elif how == "not an object":
        path.write_text("[1, 2, 3]")
    elif how == "empty":
        path.write_text("")


@pytest.mark.parametrize("how", ["truncated", "not UTF-8", "not an object", "empty"])
@pytest.mark.parametrize("which", ["case", "run.json"])
def test_a_damaged_results_file_is_one_line_naming_it(copy, capsys, which, how):
    target = copy / "run.json" if which == "run.json" else next((copy / "cases").glob("*.json"))
    damage(target, how)
    code, _, err = xval(capsys, "show", copy)
    assert code == 2
    assert one_error_line(err).startswith(f"{target}: ")


@pytest.mark.parametrize("how", ["truncated", "not UTF-8", "not an object", "empty"])
def test_a_damaged_baseline_is_one_line_naming_it(run, copy, tmp_path, capsys, how):
    baseline = tmp_path / "baseline.json"
    shutil.copy(run / "baseline.json", baseline)
    damage(baseline, how)
    code, _, err = xval(capsys, "gate", copy, "--baseline", baseline)
    assert code == 2
    assert one_error_line(err).startswith(f"--baseline: {baseline}")


def test_resume_reruns_a_damaged_case_and_only_it(run, copy, capsys):
    cases = sorted((copy / "cases").glob("*.json"))
    damaged = cases[0]
    damage(damaged, "truncated")
    kept = {p: p.stat().st_mtime_ns for p in cases[1:]}
    code, out, err = xval(capsys, "run", run / "s.toml", "--output", copy, "--resume", "--jobs", "1")
    assert code == 0, err
    assert "1 cases run" in out and "3 already done" in out
    assert json.loads(damaged.read_text())["status"] == "ok"
    assert {p: p.stat().st_mtime_ns for p in kept} == kept
