"""`xval model check` runs reading the file, the reference and each engine in a child process of its own: a
crash, an abort or a hang is that engine's row, the others report, stdout holds only the table or the JSON,
and nothing is left in the working directory. The stand-in importers really segfault, abort, hang and print
(tests/stand_in_importers.py); DART's MJCF parser really segfaults on a dm-control-style acrobot."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import stand_in_importers as stand_in
from compare.model import isolation, parity
from engines.model.importers import ENGINES, importer
from cli_support import run_cli

MODELS = Path(__file__).resolve().parents[1] / "models"
FIXTURES = Path(__file__).resolve().parent / "fixtures" / "models"


@pytest.fixture
def stand_ins(monkeypatch):
    """The stand-in importers as engines named ``segfault``, ``abort``, ``hang`` and ``printing``."""
    extra = {name: stand_in.stand_in(getattr(stand_in, name)) for name in ("segfault", "abort", "hang", "printing")}
    monkeypatch.setattr(parity, "ENGINES", (*ENGINES, *extra))
    monkeypatch.setattr(parity, "importer", lambda name: extra[name] if name in extra else importer(name))
    return tuple(extra)


@pytest.fixture
def clean_folder(tmp_path, monkeypatch):
    """The working directory: an empty folder, checked empty afterwards."""
    folder = tmp_path / "cwd"
    folder.mkdir()
    monkeypatch.chdir(folder)
    yield folder
    assert sorted(p.name for p in folder.iterdir()) == []


def test_an_engine_that_segfaults_is_its_row_and_the_others_report(stand_ins, clean_folder):
    report = parity.check(str(MODELS / "double_pendulum.urdf"), engines=("mujoco", "segfault", "pybullet"), states=5)
    rows = {e.engine: e for e in report.engines}
    assert rows["segfault"].failure == "crashed (SIGSEGV)"
    assert rows["segfault"].message == "crashed (SIGSEGV) while loading"
    assert (rows["segfault"].loaded, rows["segfault"].agrees, rows["segfault"].version) == (False, False, "0-stand-in")
    assert rows["mujoco"].agrees and rows["pybullet"].agrees
    assert report.exit_code == 1


def test_an_abort_and_a_hang_are_rows_too(stand_ins, clean_folder):
    report = parity.check(str(MODELS / "double_pendulum.urdf"), engines=("abort", "hang", "mujoco"), states=5,
                          timeout=3)
    rows = {e.engine: e for e in report.engines}
    assert rows["abort"].message == "crashed (SIGABRT) while loading"
    assert rows["hang"].message == "timed out after 3 s while loading"
    assert rows["hang"].failure == "timed out after 3 s"
    assert rows["mujoco"].agrees


def test_what_an_engine_prints_is_its_notes_never_on_our_file_descriptors(stand_ins, clean_folder, capfd):
    report = parity.check(str(MODELS / "double_pendulum.urdf"), engines=("printing",), states=5)
    (row,) = report.engines
    assert row.agrees
    printed = [n for n in row.notes if n.startswith("printing printed: ")]
    assert sorted(printed) == sorted([
        "printing printed: b3Warning[examples/Importers/ImportMJCFDemo/BulletMJCFImporter.cpp,1220]: stand-in on fd 1",
        "printing printed: stand-in on fd 2", "printing printed: stand-in through printf"])
    assert capfd.readouterr() == ("", "")  # fd 1 and 2 of this process: nothing came through


def test_the_segfault_through_the_command_line_is_json_on_stdout_and_exit_1(stand_ins, clean_folder, capsys,
                                                                           monkeypatch):
    from compare.commands import model as command

    monkeypatch.setattr(command, "check", lambda *a, **k: parity.check(
        str(MODELS / "double_pendulum.urdf"), engines=("segfault", "mujoco"), states=5))
    code, out, err = run_cli(capsys, "model", "check", MODELS / "double_pendulum.urdf", "--format", "json")
    report = json.loads(out)
    assert (code, err) == (1, "")
    assert [(e["engine"], e["message"]) for e in report["engines"]] == [
        ("segfault", "crashed (SIGSEGV) while loading"), ("mujoco", "")]


def test_dart_segfaults_on_a_dm_control_acrobot_and_the_other_engines_report(clean_folder, capsys):
    """Measured with dartpy 6.20: MjcfParser.readWorld dies of SIGSEGV on this file. If a later DART reads it,
    this test says so (the assertion on DART's row fails) rather than passing on a crash that no longer happens."""
    code, out, err = run_cli(capsys, "model", "check", FIXTURES / "acrobot.xml", "--states", "10", "--format", "json")
    report = json.loads(out)  # stdout is the JSON alone, whatever the engines printed
    rows = {e["engine"]: e for e in report["engines"]}
    assert (code, err) == (1, "")
    assert rows["dart"]["message"] == "crashed (SIGSEGV) while loading" and not rows["dart"]["loaded"]
    assert [name for name, row in rows.items() if row["failure"]] == ["dart"]
    assert rows["mujoco"]["loaded"] and rows["drake"]["loaded"]  # they report their differences
    assert rows["pybullet"]["loaded"] or rows["pybullet"]["message"]  # its loadMJCF's answer, whatever it is


def test_a_child_s_answer_its_exception_and_its_working_folder(tmp_path):
    assert isolation.run(sum, (1, 2, 3)).value == 6
    outcome = isolation.run(int, "seven")
    assert isinstance(outcome.error, ValueError) and outcome.failure == ""
    outcome = isolation.run(lambda: (Path("left.txt").write_text("x"), str(Path.cwd()))[1])
    assert outcome.value != str(Path.cwd()) and not Path(outcome.value).exists()  # its folder is gone


def test_pybullet_s_warnings_on_file_descriptor_1_are_its_notes_and_stdout_stays_json(capfd):
    """spirit40newer.urdf has links without <inertial>: PyBullet's C code prints b3Warning lines on fd 1.
    capfd reads this process's file descriptors, so a line that leaked would break the JSON."""
    code, out, err = run_cli(capfd, "model", "check", "pybullet_data:quadruped/spirit40newer.urdf", "--engine",
                             "pybullet", "--states", "3", "--format", "json")
    report = json.loads(out)
    (row,) = report["engines"]
    assert err == "" and code == 1  # it gives those links 1 kg: it disagrees
    assert any(n.startswith("pybullet printed: b3Warning[examples/Importers/ImportURDFDemo/BulletUrdfImporter.cpp")
               for n in row["notes"])


def test_a_reference_that_segfaults_leaves_nothing_to_compare_one_line_and_exit_1(monkeypatch, clean_folder, capsys):
    real = parity.importer
    monkeypatch.setattr(parity, "importer", lambda name: stand_in.stand_in(stand_in.segfault) if name == "pinocchio"
                        else real(name))
    code, out, err = run_cli(capsys, "model", "check", MODELS / "double_pendulum.urdf", "--states", "3")
    assert (code, out) == (1, "")
    assert err.startswith(f"xval: model {MODELS / 'double_pendulum.urdf'}: the model reference (pinocchio) crashed (SIGSEGV)")
    assert err.endswith("; nothing was compared\n") and err.count("\n") == 1
