"""Quiet means quiet: what an engine's library prints is caught in the case's process, kept with the case
record (count, first and last lines) and shown only with --verbose. The engines are real: DART's C++ prints a
warning per joint per step once its 32-link chain blows up at dt 0.02 s (thousands of lines in 0.5 s), and
MuJoCo's hinge model of the same chain hits its bad-acceleration check."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import run_xval

SUITE = """
name = "engines-that-print"
duration = 0.5
sample_interval = 0.01
repeats = 1
timeout = 120
dt = [2e-2]

[[scenes]]
id = "chain-32"
scene = "chain"
parameters = { n = 32, length = 0.03125, mass = 0.03125 }

[[engines]]
id = "dart/rk4"

[[engines]]
id = "mujoco/hinge"
"""

#: What DART prints when a state goes non-finite ("Non-finite relative transform detected in 'j21'", …).
DART_WORDS = "Non-finite"


def _records(output: Path) -> dict[str, dict]:
    return {json.loads(f.read_text())["case"]["engine"]: json.loads(f.read_text())
            for f in (output / "cases").glob("*.json")}


def test_quiet_run_prints_only_xvals_lines_and_the_records_keep_the_engines(tmp_path):
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE)
    done = run_xval("run", suite, "--output", tmp_path / "out", "--quiet", "--jobs", 1, timeout=240)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert DART_WORDS not in done.stdout and "Warning" not in done.stdout
    # xval's own lines: the verdict of one scene, its problems, the counts and the results path.
    assert len(done.stdout.splitlines()) < 15, done.stdout
    assert "2 cases run" in done.stdout
    records = _records(tmp_path / "out")
    dart = records["dart/rk4"]
    assert dart["status"] == "unstable"
    printed = dart["engine_output"]
    assert printed["lines"] > 100  # one warning per joint per step past the blow-up
    assert len(printed["first"]) == 5 and len(printed["last"]) == 5
    assert any(DART_WORDS in line for line in printed["first"] + printed["last"])
    assert not any("\x1b" in line for line in printed["first"] + printed["last"])  # its colour codes dropped
    assert records["mujoco/hinge"]["status"] == "unstable"
    assert "Nan, Inf or huge value in QACC" in records["mujoco/hinge"]["message"]


def test_verbose_run_shows_what_the_engine_printed(tmp_path):
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE.replace('[[engines]]\nid = "mujoco/hinge"\n', ""))
    done = run_xval("run", suite, "--output", tmp_path / "out", "--verbose", "--jobs", 1, timeout=240)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    at = next(k for k, line in enumerate(lines) if "dart/rk4" in line and "unstable" in line)
    assert lines[at + 1].strip().startswith("engine printed ") and DART_WORDS in "".join(lines[at + 2:at + 13])
    assert "more lines …" in done.stderr
    assert DART_WORDS not in done.stdout


def test_simulate_keeps_the_csv_clean_and_counts_what_the_engine_printed(tmp_path):
    args = ["simulate", "chain", "--param", "n=32", "--param", "length=0.03125", "--param", "mass=0.03125",
            "--param", "duration=0.5", "--engine", "dart/rk4", "--dt", "2e-2", "--output", "-"]
    done = run_xval(*args, timeout=240)
    assert done.returncode == 1  # unstable
    assert DART_WORDS not in done.stdout
    assert done.stdout.startswith("t,") and len(done.stdout.splitlines()) == 27  # header + 26 samples
    assert "the engine printed" in done.stderr and "(--verbose shows them)" in done.stderr
    assert DART_WORDS not in done.stderr
    verbose = run_xval(*args, "--verbose", timeout=240)
    assert DART_WORDS in verbose.stderr and DART_WORDS not in verbose.stdout
