"""``xval scenes`` / ``xval simulate``: the CSV it writes and its one-line errors (exit 2, no traceback)."""

import csv

import numpy as np
import pytest

from compare.cli import main
from engines.scene import catalog
from conftest import run_xval


def run(capsys, *argv):
    with pytest.raises(SystemExit) as stop:
        main(list(argv))
    out, err = capsys.readouterr()
    return stop.value.code, out, err


def run_ok(capsys, *argv):
    try:
        main(list(argv))
    except SystemExit as stop:
        assert stop.code in (0, None), capsys.readouterr()
    return capsys.readouterr()


@pytest.mark.parametrize("scene_name", catalog.scene_names())
def test_simulate_writes_the_documented_columns_for_every_catalog_scene(scene_name, tmp_path, capsys):
    output = tmp_path / "out.csv"
    out, _ = run_ok(capsys, "simulate", scene_name, "--dt", "1e-2", "--duration", "0.5", "--output", str(output))
    assert "reference/dop853" in out and "ok" in out
    rows = list(csv.reader(output.open()))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    n = len(catalog.build(scene_name).particles)
    expected = ["t"] + [f"{kind}{i}_{axis}" for i in range(n) for kind in "pv" for axis in "xyz"]
    expected += ["energy", "constraint_error"]
    assert header == expected
    np.testing.assert_allclose(data[:, 0], np.linspace(0, 0.5, 51), atol=1e-12)
    energy = data[:, -2]
    assert np.ptp(energy) < 1e-9 * catalog.build(scene_name).characteristic_energy
    assert data[:, -1].max() < 1e-12


def test_simulate_applies_parameters(tmp_path, capsys):
    output = tmp_path / "bead.csv"
    run_ok(capsys, "simulate", "bead", "--dt", "1e-2", "--duration", "0.1",
           "--param", "theta0=90", "--param", "radius=2", "--output", str(output))
    first = next(csv.DictReader(output.open()))
    assert float(first["p0_x"]) == pytest.approx(2.0)
    assert float(first["p0_z"]) == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize(
    "args, message",
    [
        (["nosuch"], "unknown scene 'nosuch'; choose one of: bead, double-pendulum"),
        (["bead", "--param", "theta0=abc"], "bead: parameter theta0 must be a number, got 'abc'"),
        (["bead", "--param", "nosuch=1"], "bead: unknown parameter 'nosuch'; its parameters are: m, radius"),
        (["bead", "--param", "theta0"], "--param: expected NAME=VALUE, got 'theta0'"),
        (["bead", "--dt", "0"], "dt must be positive, got '0'"),
        (["bead", "--dt", "-1e-3"], "dt must be positive, got '-1e-3'"),
        (["bead", "--duration", "0"], "bead: parameter duration must be positive, got '0'"),
        (["bead", "--dt", "0.5", "--duration", "0.1"], r"dt (0.5 s) is larger than the duration (0.1 s)"),
        (["bead", "--engine", "nosuch"], "unknown engine 'nosuch'; choose one of: reference"),
        (["bead", "--engine", "reference/rk4"], "unknown variant 'reference/rk4'; reference has: reference/dop853"),
        (["bead", "--option", "rtol=big"], "reference: option rtol must be a finite number, got 'big'"),
        (["bead", "--option", "nosuch=1"], "reference: unknown option 'nosuch'; its options are: rtol, atol"),
    ],
)
def test_simulate_bad_input_is_one_line_and_exit_2(args, message, tmp_path, capsys):
    argv = ["simulate", *args]
    if "--dt" not in args:
        argv += ["--dt", "1e-2"]
    code, out, err = run(capsys, *argv, "--output", str(tmp_path / "x.csv"))
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("xval: error: ")
    assert message in err
    assert not (tmp_path / "x.csv").exists()


def test_unwritable_output_is_refused_before_simulating(tmp_path, capsys):
    code, _, err = run(capsys, "simulate", "bead", "--dt", "1e-2", "--output", str(tmp_path / "missing" / "x.csv"))
    assert code == 2
    assert f"--output: directory {tmp_path / 'missing'} does not exist" in err
    code, _, err = run(capsys, "simulate", "bead", "--dt", "1e-2", "--output", str(tmp_path))
    assert code == 2 and "is a directory; give a file name" in err


def test_scenes_lists_parameters_with_defaults_and_units(capsys):
    out = run_ok(capsys, "scenes")[0]
    assert "double-pendulum:" in out
    assert "theta1     = 120      deg" in out
    assert "phi_dot0" in out and "rad/s" in out


def test_console_script_errors_without_traceback(tmp_path):
    result = run_xval("simulate", "bead", "--dt", "abc", "--output", tmp_path / "x.csv")
    assert result.returncode == 2
    assert result.stderr == "xval: error: dt must be a number of seconds, got 'abc'\n"
    assert "Traceback" not in result.stderr


def test_simulate_without_engine_says_it_ran_the_reference(tmp_path, capsys):
    out, err = run_ok(capsys, "simulate", "bead", "--dt", "1e-2", "--param", "duration=0.1",
                      "--output", str(tmp_path / "o.csv"))
    assert out.startswith("no --engine given: ran the reference (reference/dop853). reference/dop853 on bead: ok")


def test_an_angle_under_two_pi_warns_that_angles_are_degrees(tmp_path, capsys):
    out, err = run_ok(capsys, "simulate", "double-pendulum", "--engine", "mujoco/hinge", "--dt", "1e-2",
                      "--param", "theta1=1.5708", "--param", "duration=0.1", "--output", str(tmp_path / "o.csv"))
    assert err.splitlines() == ["xval: warning: double-pendulum: theta1 = 1.5708 is in degrees (1.5708°); "
                                "if you meant radians, give 90.0002 (degrees)"]
    assert out.startswith("mujoco/hinge on double-pendulum: ok")
    # 0 and angles of 2π or more say nothing.
    out, err = run_ok(capsys, "simulate", "double-pendulum", "--engine", "mujoco/hinge", "--dt", "1e-2",
                      "--param", "theta1=90", "--param", "theta2=0", "--param", "duration=0.1",
                      "--output", str(tmp_path / "p.csv"))
    assert err == ""
