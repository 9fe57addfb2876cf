"""The protocol's example solvers, built and run as a user would: the C++ bead and double pendulum
(examples/cpp, built with g++ here) and the standard-library Python bead (examples/python). Each agrees with
the reference and shows its order; a suite naming them by relative paths runs from another directory;
``xval simulate --command`` writes what ``xval score`` grades, and a failing command is one line, exit 1.
"""

from __future__ import annotations

import ast
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from engines.scene import catalog

from engines.external import command
from engines.reference.reference import solve
from conftest import ROOT, run_xval

CPP = ROOT / "examples" / "cpp"
PYTHON_BEAD = ROOT / "examples" / "python" / "bead.py"


@pytest.fixture(scope="session")
def cpp_build(tmp_path_factory) -> Path:
    """examples/cpp built with g++ (make), into a temporary directory."""
    if shutil.which("g++") is None:
        pytest.skip("g++ is not installed (CI installs it: .ci/run); the C++ examples cannot be built")
    build = tmp_path_factory.mktemp("cpp-build")
    made = subprocess.run(["make", "-C", str(CPP), f"BUILD={build}"], capture_output=True, text=True)
    assert made.returncode == 0, made.stdout + made.stderr
    return build


def max_error(engine: command.CommandEngine, scene, dt: float, reference):
    trajectory = engine.simulate(scene, dt)
    assert trajectory.info.status == "ok", trajectory.info.message
    q, _, f = reference.at(trajectory.t)
    force_error = None if trajectory.constraint_forces is None else np.abs(trajectory.constraint_forces - f).max()
    return np.linalg.norm(trajectory.positions - q, axis=2).max(), force_error, trajectory


def test_the_python_example_is_standard_library_only_in_at_most_40_lines():
    source = PYTHON_BEAD.read_text()
    assert len(source.splitlines()) <= 40
    imported = {alias.name.split(".")[0] for node in ast.walk(ast.parse(source))
                if isinstance(node, ast.Import) for alias in node.names}
    assert imported and imported <= set(sys.stdlib_module_names)


# (label, program (None: the Python example), scene, error bound at dt = 2.5e-3 (m), force error bound (N))
ROUND_TRIPS = [
    ("py-bead", None, "bead", 1e-9, None),
    ("cpp-bead", "bead", "bead", 1e-8, 1e-7),
    ("cpp-bead-3d", "bead", "spherical-pendulum", 1e-8, 1e-7),
    ("cpp-double-pendulum", "double_pendulum", "double-pendulum", 1e-7, 1e-4),
]


@pytest.mark.parametrize("label, program, scene_name, bound, force_bound", ROUND_TRIPS, ids=[r[0] for r in ROUND_TRIPS])
def test_round_trip_agrees_with_the_reference_at_fourth_order(label, program, scene_name, bound, force_bound,
                                                              request):
    """RK4 (all three examples): halving dt divides the error by ~16 (observed order 4 ± 0.9), forces included."""
    if program is None:
        argv = [sys.executable, str(PYTHON_BEAD)]
    else:
        argv = [str(request.getfixturevalue("cpp_build") / program)]
    engine = command.command_engine(label, argv, ROOT, version="1.0", capabilities=["3d", "constraint-forces"]
                                    if program else ["3d"])
    scene = catalog.build(scene_name, {"duration": 2.0})
    reference = solve(scene)
    coarse, coarse_force, _ = max_error(engine, scene, 5e-3, reference)
    fine, fine_force, trajectory = max_error(engine, scene, 2.5e-3, reference)
    order = np.log2(coarse / fine)
    assert 3.5 < order < 4.9, order
    assert fine < bound
    info = trajectory.info
    assert info.engine_version == "1.0" and info.settings["wall_time_source"] == "program ('# wall_time')"
    if force_bound is not None:
        assert fine_force < force_bound and 3.5 < np.log2(coarse_force / fine_force) < 4.9
        assert info.settings["program_version"] in ("bead 1.0", "double_pendulum 1.0")
    else:
        assert trajectory.constraint_forces is None


def test_options_reach_the_program(cpp_build):
    """The C++ bead's `method = "euler"` (symplectic Euler) is first order; a bad value is its one stderr line."""
    scene = catalog.build("bead", {"duration": 2.0})
    reference = solve(scene)
    euler = command.command_engine("cpp-bead-euler", [str(cpp_build / "bead")], ROOT, options={"method": "euler"})
    order = np.log2(max_error(euler, scene, 5e-3, reference)[0] / max_error(euler, scene, 2.5e-3, reference)[0])
    assert 0.8 < order < 1.2
    bad = command.command_engine("cpp-bead-bad", [str(cpp_build / "bead")], ROOT, options={"method": "verlet"})
    failed = bad.simulate(scene, 1e-2)
    assert failed.info.status == "failed"
    assert failed.info.message.endswith('exited with code 1; last stderr line: bead: options.method must be "rk4" '
                                        'or "euler"')
    refused = euler.simulate(catalog.build("double-pendulum", {"duration": 0.1}), 1e-2)
    assert refused.info.status == "skipped" and refused.info.message == (
        "command/cpp-bead-euler cannot express 'double-pendulum': bead: expects one particle on one pin; scene "
        "'double-pendulum' is not that")


def test_a_suite_with_relative_command_paths_runs_from_another_directory(cpp_build, tmp_path):
    project = tmp_path / "project"
    (project / "solvers").mkdir(parents=True)
    (project / "build").mkdir()
    shutil.copy(PYTHON_BEAD, project / "solvers" / "bead.py")
    shutil.copy(cpp_build / "double_pendulum", project / "build" / "double_pendulum")
    (project / "suite.toml").write_text(f"""
name = "relative"
duration = 0.5
dt = [1e-2, 5e-3]

[[scenes]]
scene = "bead"

[[scenes]]
scene = "double-pendulum"

[[engines]]
command = [{json.dumps(sys.executable)}, "solvers/bead.py"]   # an argument relative to the suite's folder
label = "py-bead"
version = "1.0"

[[engines]]
command = ["build/double_pendulum"]                            # the program itself, relative
label = "cpp-dp"
version = "2.0"
capabilities = ["constraint-forces"]
""")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    ran = run_xval("run", "../project/suite.toml", "--output", "results", "--jobs", "1", cwd=elsewhere,
                   timeout=300)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    shown = run_xval("show", "results", "--format", "json", cwd=elsewhere)
    rows = {(r["scene"], r["engine"], r["dt"]): r for r in json.loads(shown.stdout)}
    assert len(rows) == 8
    for dt in (1e-2, 5e-3):
        bead = rows[("bead", "command/py-bead", dt)]
        pendulum = rows[("double-pendulum", "command/cpp-dp", dt)]
        assert bead["status"] == "ok" and bead["engine_version"] == "1.0" and bead["position_error_linf"] < 1e-6
        assert pendulum["status"] == "ok" and pendulum["engine_version"] == "2.0"
        assert pendulum["position_error_linf"] < 1e-4 and pendulum["constraint_force_error"] < 1e-2
        # A scene the program cannot express (exit 77) is skipped, its stderr line the reason:
        refused = rows[("double-pendulum", "command/py-bead", dt)]
        assert refused["status"] == "skipped" and refused["message"] == (
            "command/py-bead cannot express 'double-pendulum': bead.py: expects one particle on one pin, not the "
            "scene 'double-pendulum'")


def test_simulate_command_writes_what_score_grades(cpp_build, tmp_path):
    shutil.copy(cpp_build / "double_pendulum", tmp_path / "double_pendulum")
    made = run_xval("simulate", "double-pendulum", "--command", "./double_pendulum", "--dt", "2.5e-3", "--duration", "2",
                "--forces", "--output", "dp.csv", cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    assert made.stdout.startswith("command/double_pendulum on double-pendulum: ok, 201 samples to ")
    scored = run_xval("score", "double-pendulum", "dp.csv", "--param", "duration=2", "--format", "json", cwd=tmp_path)
    (row,) = json.loads(scored.stdout)
    assert row["status"] == "ok" and 1e-10 < row["position_error_linf"] < 1e-7
    assert row["constraint_force_error"] < 1e-4


@pytest.mark.parametrize("program, message", [
    ("python3 -c 'import sys; sys.exit(\"solver: singular matrix at step 12\")'",
     "python3 -c 'import sys; sys.exit(\"solver: singular matrix at step 12\")' exited with code 1; last stderr "
     "line: solver: singular matrix at step 12"),
    ("./nosuch --fast", "cannot start {cwd}/nosuch --fast: '{cwd}/nosuch' not found in {cwd}"),
])
def test_simulate_command_that_fails_is_one_line_and_exit_1(program, message, tmp_path):
    ran = run_xval("simulate", "bead", "--command", program, "--dt", "1e-2", "--output", "out.csv", cwd=tmp_path)
    assert ran.returncode == 1 and ran.stdout.count("\n") == 1 and "Traceback" not in ran.stdout + ran.stderr
    assert ": failed, 0 samples to " in ran.stdout and message.format(cwd=tmp_path) in ran.stdout


def test_a_version_bump_makes_the_gate_say_not_comparable(tmp_path):
    """The suite's `version` is recorded; the gate calls a case of another version "not comparable", not worse."""
    from compare.gate.baseline import build_baseline
    from compare.gate.gate import gate_results
    from compare.run.results import load_results
    from compare.run.runner import run_suite
    from compare.suite.reader import load_suite

    def run(version: str, name: str):
        (tmp_path / f"{name}.toml").write_text(f"""
name = "versions"
duration = 0.5
dt = [1e-2]

[[scenes]]
scene = "bead"

[[engines]]
command = [{json.dumps(sys.executable)}, {json.dumps(str(PYTHON_BEAD))}]
label = "py-bead"
version = "{version}"
""")
        suite = load_suite(tmp_path / f"{name}.toml")
        run_suite(suite, tmp_path / name, jobs=1)
        return build_baseline(load_results(tmp_path / name)), suite

    before, _ = run("1.0", "before")
    same, _ = run("1.0", "same")
    after, suite = run("1.1", "after")
    settings = suite.gate
    (unchanged,) = gate_results(before, same, settings, "before.json", timing="report").cases
    (bumped,) = gate_results(before, after, settings, "before.json", timing="report").cases
    assert unchanged.outcome == "unchanged"
    assert bumped.outcome == "not comparable" and "1.0" in bumped.reason and "1.1" in bumped.reason


def test_the_example_suite_names_the_built_programs_by_paths_relative_to_it(tmp_path, monkeypatch):
    from compare.suite.reader import load_suite

    monkeypatch.chdir(tmp_path)  # anywhere: paths resolve against the suite's folder
    suite = load_suite(CPP / "suite.toml")
    commands = {spec.label: spec.engine.spec for spec in suite.engines if spec.id.startswith("command/")}
    assert set(commands) == {"command/cpp-bead", "command/cpp-bead-euler", "command/cpp-double-pendulum"}
    assert commands["command/cpp-bead"].argv == (str(CPP / "build" / "bead"),)
    assert commands["command/cpp-double-pendulum"].cwd == str(CPP)
    euler = next(spec for spec in suite.engines if spec.label == "command/cpp-bead-euler")
    assert dict(euler.options) == {"method": "euler"}
