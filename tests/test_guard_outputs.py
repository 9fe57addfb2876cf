"""Outputs: never replacing an input, '-' for standard output, symlinks written through, devices written
in place, directories refused, modes from the umask, and simulate's bounds (exit 1 past them)."""

from __future__ import annotations

import csv
import io
import os
import stat

import pytest

from engines.files import atomic_write_text, check_writable
from engines.errors import UserError
from cli_support import run_cli as run




@pytest.fixture
def umask_027():
    previous = os.umask(0o027)
    yield
    os.umask(previous)


def test_a_new_file_gets_the_mode_of_the_umask_and_an_existing_one_keeps_its_mode(tmp_path, umask_027):
    atomic_write_text(tmp_path / "new.txt", "a")
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o640  # 0666 & ~027, not mkstemp's 0600
    kept = tmp_path / "kept.txt"
    kept.write_text("old")
    kept.chmod(0o604)
    atomic_write_text(kept, "new")
    assert kept.read_text() == "new" and stat.S_IMODE(kept.stat().st_mode) == 0o604


def test_a_symlinked_output_is_written_through_and_stays_a_symlink(tmp_path):
    target = tmp_path / "real.csv"
    target.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    atomic_write_text(check_writable(link), "new")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new"


def test_a_device_is_written_in_place_and_a_directory_refused(tmp_path):
    assert check_writable("/dev/null") == __import__("pathlib").Path("/dev/null")
    atomic_write_text("/dev/null", "discarded")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)  # still the device, not a regular file
    with pytest.raises(UserError, match=r"^--output: .* is a directory; give a file name$"):
        check_writable(tmp_path)
    with pytest.raises(IsADirectoryError):
        atomic_write_text(tmp_path, "x")
    assert not any(tmp_path.iterdir())  # no temporary left behind


def test_an_output_that_is_an_input_or_inside_an_input_directory_is_refused(tmp_path):
    baseline = tmp_path / "baseline.json"
    baseline.write_text("{}")
    with pytest.raises(UserError, match=r"^--junit: .*baseline.json is the input .*baseline.json; writing it would "
                                        r"replace what this command reads; choose another path$"):
        check_writable(baseline, "--junit", inputs=[baseline])
    results = tmp_path / "results"
    (results / "cases").mkdir(parents=True)
    with pytest.raises(UserError, match=r"is inside the input directory .*results; writing it would replace"):
        check_writable(results / "run.json", inputs=[results])
    link = tmp_path / "sneaky.json"
    link.symlink_to(baseline)
    with pytest.raises(UserError, match="is the input"):
        check_writable(link, inputs=[baseline])
    assert baseline.read_text() == "{}"


def test_simulate_to_standard_output_writes_only_csv_there_and_the_summary_to_stderr(capsys):
    code, out, err = run(capsys, "simulate", "bead", "--engine", "mujoco", "--dt", "1e-2", "--duration", "0.05",
                         "--output", "-")
    assert code == 0
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0][:2] == ["t", "p0_x"] and len(rows) == 1 + 6
    assert err.startswith("mujoco/hinge on bead: ok, 6 samples to standard output;")


def test_simulate_applies_the_default_bounds_and_a_run_past_them_is_unstable_exit_1(tmp_path, capsys):
    # Plain Euler drifts 1 m off the rods of a double pendulum in 10 s at dt = 1e-2 (the audit's case).
    argv = ["simulate", "double-pendulum", "--engine", "ours/plain-euler", "--dt", "1e-2",
            "--output", str(tmp_path / "o.csv")]
    code, out, _ = run(capsys, *argv)
    assert code == 1
    assert out.strip().endswith("(energy drift 11.8 E* exceeds the bound 1 E*; constraint error 1 m exceeds the "
                                "bound 0.1 L = 0.2 m)")
    assert ": unstable, 1001 samples to " in out
    code, out, _ = run(capsys, *argv, "--bounds", "energy_drift=20", "--bounds", "constraint_error=1")
    assert code == 0 and ": ok, 1001 samples" in out


def test_a_simulate_that_blows_up_at_once_is_one_line_and_the_csv_keeps_its_header(tmp_path, capsys):
    # Stiffness this high makes ours' Baumgarte step blow up at once; the CSV still gets its header.
    output = tmp_path / "o.csv"
    code, out, err = run(capsys, "simulate", "bead", "--engine", "ours/baumgarte-euler", "--option", "k_s=1e12",
                         "--dt", "1e-1", "--output", str(output))
    assert code == 1 and err == ""
    assert len(out.strip().splitlines()) == 1 and ": unstable" in out
    assert output.read_text().startswith("t,p0_x,p0_y,p0_z")


def test_labels_with_ansi_escapes_print_inert(tmp_path, capsys):
    # A label that would clear the screen and turn the text red, in a suite file.
    (tmp_path / "s.toml").write_text(
        'dt = [1e-2]\nduration = 0.2\n[[scenes]]\nscene = "bead"\n'
        '[[engines]]\nid = "mujoco/hinge"\nlabel = "\\u001b[2J\\u001b[31mred\\u0007"\n'
    )
    code, out, err = run(capsys, "run", str(tmp_path / "s.toml"), "--output", str(tmp_path / "r"), "--jobs", "1")
    assert code == 0, err
    code, shown, _ = run(capsys, "show", str(tmp_path / "r"))
    assert code == 0
    for text in (out, shown):
        # Escapes the table formatter did not strip itself are shown as visible \xNN text.
        assert "\x1b" not in text and "\x07" not in text
        assert "red\\x07" in text


def test_gate_md_escapes_html_in_labels():
    from gate_support import GOLDEN

    from dataclasses import replace

    from compare.gate.baseline import load_baseline
    from compare.gate.gate import gate_results
    from compare.gate.report import to_markdown
    from compare.suite.gate_rules import GateSettings

    def labelled(baseline):
        return replace(baseline, cases={key: replace(entry, engine="<img src=x onerror=alert(1)>|" + entry.engine)
                                        for key, entry in baseline.cases.items()})

    baseline, current = labelled(load_baseline(GOLDEN / "baseline.json")), labelled(load_baseline(GOLDEN / "current.json"))
    text = to_markdown(gate_results(baseline, current, GateSettings(), "baseline.json"))
    assert "<img" not in text
    assert "&lt;img src=x onerror=alert(1)&gt;\\|ours/" in text


def test_score_writes_to_standard_output_or_a_file_and_never_over_a_file_it_grades(tmp_path, capsys):
    trajectory = tmp_path / "bead.csv"
    code, _, _ = run(capsys, "simulate", "bead", "--dt", "1e-2", "--duration", "0.1", "--output", str(trajectory))
    assert code == 0
    before = trajectory.read_bytes()
    code, _, err = run(capsys, "score", "bead", str(trajectory), "--output", str(trajectory))
    assert code == 2 and err.strip() == (f"xval: error: --output: {trajectory} is the input {trajectory}; writing it "
                                         f"would replace what this command reads; choose another path")
    assert trajectory.read_bytes() == before
    code, out, _ = run(capsys, "score", "bead", str(trajectory), "--output", "-")
    assert code == 0 and out.startswith("file") and str(trajectory) in out
    code, quiet, _ = run(capsys, "score", "bead", str(trajectory), "--output", str(tmp_path / "score.txt"))
    assert code == 0 and quiet == "" and (tmp_path / "score.txt").read_text() == out
