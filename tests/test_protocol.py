"""The process protocol (docs/protocol.md): the CSV reader and writer, and the command engine against a
deliberately misbehaving program (tests/protocol_program.py): every bad-output class is ``failed`` naming
the line and column, NaN rows are ``unstable``, a timed-out program leaves no process of its group behind,
and a suite's case timeout reaches the program.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from engines.scene import catalog

from engines.external import command, protocol

from engines import registry
from engines.adapter import Schedule
from engines.errors import UserError

from conftest import wait_for

HERE = Path(__file__).resolve().parent
PROGRAM = [sys.executable, str(HERE / "protocol_program.py")]
BEAD = catalog.build("bead", {"duration": 0.2})


def engine(mode: str, **options) -> command.CommandEngine:
    return command.command_engine(f"test-{mode}", [*PROGRAM, mode], HERE, options=options)


# -- the CSV ---------------------------------------------------------------------------


def test_write_then_read_is_exact_and_keeps_comments():
    rng = np.random.default_rng(1)
    table = rng.standard_normal((50, 7)) * 10.0 ** rng.integers(-300, 300, (50, 7))
    table[3, 2], table[4, 5] = math.nan, -math.inf
    header = protocol.state_columns(1)
    text = protocol.write_csv(header, table, {"wall_time": 0.25, "version": "v 1.0"})
    read = protocol.read_csv(text)
    assert read.header == tuple(header)
    np.testing.assert_array_equal(read.values, table)  # repr round-trips every float64, nan and inf included
    assert read.comments == {"wall_time": "0.25", "version": "v 1.0"} and read.wall_time() == 0.25
    assert read.header_line == 3 and read.data_lines.tolist() == list(range(4, 54))


def test_columns_are_found_by_name_and_forces_not_written_are_nan():
    scene = catalog.build("double-pendulum")
    state = protocol.state_columns(2)
    header = ["energy", *reversed(state), "f1_x", "f1_y", "f1_z"]
    values = np.arange(3 * len(header), dtype=float).reshape(3, len(header))
    table = protocol.read_csv(protocol.write_csv(header, values))
    columns = protocol.match_columns(table, scene)
    assert columns.t.tolist() == values[:, header.index("t")].tolist()
    assert columns.positions[1, 1, 2] == values[1, header.index("p1_z")]
    assert columns.velocities[2, 0, 0] == values[2, header.index("v0_x")]
    assert np.isnan(columns.forces[:, 0]).all() and columns.forces[0, 1, 1] == values[0, header.index("f1_y")]


@pytest.mark.parametrize("text, message", [
    ("t,p0_x\n0,1\n1\n", "line 3 (sample 1) has 1 fields, the header has 2; column 'p0_x' is missing"),
    ("t,p0_x\n0,1\n1,2,3\n", "line 3 (sample 1) has 3 fields, the header has 2; there is a field after the last column"),
    ("# c\nt,p0_x\n0,1\n# mid\n1,x\n", "line 5 (sample 1), column 'p0_x': 'x' is not a number"),
    ("t,p0_x\n0,1\n\n1,2\n", "line 3 (sample 1) is empty"),
    ("t,,p0_x\n", "header (line 1), column 2 has no name"),
    ("0,1\n", "header (line 1), column 1 is the number '0', not a name"),
    ("t,t\n", "column 't' appears twice (columns 1 and 2)"),
    ("# nothing\n", "no header line"),
])
def test_bad_csv_names_the_line_and_column(text, message):
    with pytest.raises(protocol.ProtocolError) as error:
        protocol.read_csv(text, "out.csv")
    assert str(error.value).startswith("out.csv: ") and message in str(error.value)


def test_the_document_is_json_with_the_scene_as_scene_to_dict_writes_it():
    schedule = Schedule.make(0.2, 1e-3, 0.05)
    doc = protocol.document(BEAD, schedule.dt, schedule.n_steps, schedule.sample_steps, {"method": "rk4"})
    assert json.loads(json.dumps(doc, allow_nan=False)) == {
        "protocol": 1, "scene": BEAD.to_dict(), "dt": 1e-3, "steps": 200,
        "sample_steps": [0, 50, 100, 150, 200], "options": {"method": "rk4"},
    }


# -- the command engine: bad output is `failed`, naming the line and column ---------------------


@pytest.mark.parametrize("mode, message", [
    ("missing-column", "stdout: header (line 2), missing column 'v0_z'"),
    ("extra-column", "stdout: header (line 2), extra column 'q0_x' (column 8)"),
    ("short-row", "stdout: line 6 (sample 3) has 6 fields, the header has 7; column 'v0_z' is missing"),
    ("non-number", "stdout: line 6 (sample 3), column 'p0_x': 'abc' is not a number"),
    ("few-rows", "stdout: 5 rows (the last at line 7), expected 21 (one per sample_steps entry"),
    ("extra-row", "stdout: line 24 (sample 21) is one row too many: the document asked for 21 rows"),
    ("bad-time", "stdout: line 7 (sample 4), column 't': 0.045 s is not the time of sample step 4 (0.04 s"),
    ("wrong-start", "stdout: line 3 (sample 0), column 'p0_x': 0.8670254037844386 m is not the initial state"),
    ("no-header", "stdout: header (line 2), column 1 is the number '0.0', not a name"),
    ("wall-time-ms", "stdout: '# wall_time = 5000' is longer than the program ran"),
])
def test_every_bad_output_class_is_failed_naming_line_and_column(mode, message):
    trajectory = engine(mode).simulate(BEAD, 1e-2)
    assert trajectory.info.status == "failed" and trajectory.n_samples == 0
    assert trajectory.info.message.startswith(f"command/test-{mode}: ")
    assert message in trajectory.info.message


@pytest.mark.parametrize("mode, message", [
    ("exit3", "protocol_program.py exit3 exited with code 1; last stderr line: protocol_program: the solver "
              "diverged at step 17"),
    ("exit-code", "exited with code 3; last stderr line: something went wrong: code 3"),
    ("segfault", "was killed by signal SIGSEGV (exit code -11); it wrote nothing to stderr"),
])
def test_a_program_that_dies_is_failed_with_its_exit_code_and_last_stderr_line(mode, message):
    trajectory = engine(mode).simulate(BEAD, 1e-2)
    assert trajectory.info.status == "failed" and message in trajectory.info.message


def test_exit_77_is_skipped_with_the_last_stderr_line_as_the_reason():
    trajectory = engine("unsupported").simulate(BEAD, 1e-2)
    assert trajectory.info.status == "skipped" and trajectory.n_samples == 0
    assert trajectory.info.message == "command/test-unsupported cannot express 'bead': protocol_program: no rods, please"


def test_a_program_that_cannot_start_is_failed_naming_the_command(tmp_path):
    missing = command.command_engine("nosuch", ["solvers/nosuch", "--fast"], tmp_path).simulate(BEAD, 1e-2)
    assert missing.info.status == "failed"
    assert missing.info.message == (f"command/nosuch: cannot start {tmp_path}/solvers/nosuch --fast: "
                                    f"'{tmp_path}/solvers/nosuch' not found in {tmp_path}")
    script = tmp_path / "solver.py"
    script.write_text("print('hi')\n")
    denied = command.command_engine("noexec", ["./solver.py"], tmp_path).simulate(BEAD, 1e-2)
    assert "is not executable (chmod +x it, or name its interpreter first)" in denied.info.message


def test_nan_rows_are_unstable_from_that_sample_and_the_program_may_stop_there():
    trajectory = engine("nan").simulate(BEAD, 1e-2)
    assert trajectory.info.status == "unstable" and trajectory.info.message == "non-finite state at t = 0.04 s"
    assert trajectory.n_samples == 4 and trajectory.info.steps == 4
    np.testing.assert_array_equal(trajectory.positions[-1], BEAD.initial_positions)


def test_a_good_run_records_the_program_version_and_where_its_wall_time_came_from():
    trajectory = engine("ok").simulate(BEAD, 1e-2)
    info = trajectory.info
    assert info.status == "ok" and trajectory.n_samples == 21 and info.steps == 20
    assert (info.engine, info.variant, info.engine_version) == ("command", "command/test-ok", "unversioned")
    assert info.settings["program_version"] == "protocol_program 1"
    assert info.settings["wall_time_source"] == "process (the program wrote no '# wall_time' line)"
    assert 0 < info.wall_time < 10
    np.testing.assert_allclose(trajectory.t, np.arange(21) * 1e-2, rtol=0, atol=1e-15)


def test_the_registry_resolves_command_ids_and_says_how_to_declare_an_unknown_one():
    made = engine("ok")
    assert registry.load_engine("command/test-ok") == (made, "test-ok")
    assert registry.resolve("command/test-ok") == (made, "test-ok")
    with pytest.raises(UserError, match=r"no command engine labelled 'never-declared' here .*declare it in the suite as "
                                        r"\[\[engines\]\] command = \[\"prog\", \"args\"\], label = \"never-declared\""):
        registry.load_engine("command/never-declared")
    with pytest.raises(UserError, match="engine 'command' needs a label: command/<label>"):
        registry.load_engine("command")


@pytest.mark.parametrize("kwargs, message", [
    ({"label": "a/b"}, "command.label: must be a non-empty name without '/'"),
    ({"argv": []}, "command.command: must be a non-empty list of strings"),
    ({"argv": "prog 'unclosed"}, "command.command: cannot split"),
    ({"capabilities": ["4d"]}, "command.capabilities: unknown capability '4d'; use any of 3d, constraint-forces"),
    ({"version": True}, "command.version: must be a string"),
    ({"options": {"x": math.nan}}, "command.options: must be JSON values"),
])
def test_a_malformed_spec_is_a_user_error_naming_the_field(kwargs, message):
    arguments = {"label": "ok", "argv": ["prog"], **kwargs}
    with pytest.raises(UserError) as error:
        command.make_spec(arguments.pop("label"), arguments.pop("argv"), **arguments)
    assert str(error.value).startswith(message)


def test_a_3d_scene_is_refused_unless_the_command_declares_3d():
    sphere = catalog.build("spherical-pendulum")
    with pytest.raises(UserError, match="command/test-ok declares no '3d' capability and cannot express the 3-D "
                                        "scene 'spherical-pendulum'"):
        engine("ok").check(sphere)
    command.command_engine("three-d", [*PROGRAM, "ok"], HERE, capabilities=["3d"]).check(sphere)


# -- timeouts: the whole process group goes --------------------------------------------------


def live_members(pgid: int) -> list[int]:
    """Pids of processes in group ``pgid`` that are not zombies (a zombie is dead, waiting for its reaper)."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # after "pid (comm) ": state, ppid, pgrp, ...
        if int(fields[2]) == pgid and fields[0] != "Z":
            members.append(int(entry.name))
    return members


def read_pids(pidfile: Path) -> tuple[int, int, int]:
    """The three pids the hanging program writes, once it has written them."""
    def pids():
        fields = pidfile.read_text().split() if pidfile.exists() else []
        return tuple(int(x) for x in fields) if len(fields) == 3 else None
    return wait_for(pids, 5, f"the program to write {pidfile}", interval=0.01)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to list a process group's members")
def test_a_timed_out_program_and_its_children_are_killed(tmp_path):
    pidfile = tmp_path / "pids"
    hang = engine("hang", pidfile=str(pidfile))
    started = time.monotonic()
    with command.deadline(1.0):
        trajectory = hang.simulate(BEAD, 1e-2)
    elapsed = time.monotonic() - started
    # The program sleeps 600 s: ending within 60 s shows the 1 s deadline killed it (60: a loaded machine's
    # start-up and scheduling, not the deadline, is what a tighter bound would measure).
    assert trajectory.info.status == "timeout" and 1.0 <= elapsed < 60.0
    assert trajectory.info.message.endswith("hang ran past the timeout of 1 s and its process group was killed; "
                                            "raise the timeout if it is only slow")
    pid, pgid, child = read_pids(pidfile)
    assert pgid == pid and pgid != os.getpgid(0)  # its own group, not the test's
    assert live_members(pgid) == []               # the program and its `sleep 600` child are gone


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to list a process group's members")
def test_a_suite_case_timeout_reaches_the_program(tmp_path):
    from compare.run.results import load_results
    from compare.run.runner import run_suite
    from compare.suite.reader import load_suite

    pidfile = tmp_path / "pids"
    suite_file = tmp_path / "suite.toml"
    suite_file.write_text(f"""
name = "hang"
duration = 0.2
dt = [1e-2]
timeout = 1.5

[[scenes]]
scene = "bead"

[[engines]]
command = {json.dumps([*PROGRAM, "hang"])}
label = "hang"
options = {{ pidfile = {json.dumps(str(pidfile))} }}
""")
    run_suite(load_suite(suite_file), tmp_path / "results", jobs=1)
    (record,) = load_results(tmp_path / "results").records
    assert record.status == "timeout", record.message
    assert "hang ran past the timeout of 1 s and its process group was killed" in record.message
    assert record.run_info["variant"] == "command/hang"
    pid, pgid, child = read_pids(pidfile)
    assert live_members(pgid) == []


# -- suites naming programs --------------------------------------------------------------

SUITE_HEAD = 'name = "s"\ndt = [1e-2]\n\n[[scenes]]\nscene = "bead"\n\n'


def test_a_suite_command_entry_runs_in_the_suite_s_folder(tmp_path):
    from compare.suite.reader import load_suite

    (tmp_path / "suite.toml").write_text(SUITE_HEAD + """[[engines]]
command = ["build/solver", "--input", "data/x.txt"]
label = "mine"
version = "1.2"
capabilities = ["constraint-forces"]
options = { method = "rk4", order = 4 }
""")
    (spec,) = load_suite(tmp_path / "suite.toml").engines
    assert (spec.id, spec.label, spec.variant, dict(spec.options)) == (
        "command/mine", "command/mine", "mine", {"method": "rk4", "order": 4})
    made = spec.engine.spec
    assert made.argv == (str(tmp_path / "build" / "solver"), "--input", "data/x.txt") and made.cwd == str(tmp_path)
    assert made.version == "1.2" and made.capabilities == {"constraint-forces"}


def test_reading_a_suite_registers_nothing(tmp_path):
    # A suite read is pure: its command engine travels with the suite to the run, and the
    # process-wide table of command labels (what `command/<label>` ids resolve against) is untouched.
    from compare.suite.reader import load_suite

    (tmp_path / "suite.toml").write_text(SUITE_HEAD + '[[engines]]\ncommand = ["prog"]\nlabel = "unread"\n')
    before = command.registered_labels()
    (spec,) = load_suite(tmp_path / "suite.toml").engines
    assert spec.engine.spec.label == "unread" and command.registered_labels() == before
    with pytest.raises(UserError, match="no command engine labelled 'unread' here"):
        registry.load_engine("command/unread")


@pytest.mark.parametrize("entry, message", [
    ('command = ["prog"]', "suite.toml:7: engines[0]: missing label; a command needs one"),
    ('command = ["prog"]\nlabel = "a"\nid = "ours"', "engines[0].id: unknown key; id and command are alternatives"),
    ('command = ["prog"]\nlabel = "a"\ncapabilities = ["2d"]', "suite.toml:10: engines[0].capabilities: unknown "
                                                                 "capability '2d'"),
    ('command = []\nlabel = "a"', "suite.toml:8: engines[0].command: must be a non-empty list of strings"),
    ('command = ["prog"]\nlabel = "a"\noptions = { when = 1979-05-27 }', "engines[0].options: must hold JSON values"),
    ('command = ["prog"]\nlabel = "a"\n\n[[engines]]\ncommand = ["other"]\nlabel = "a"',
     "engines[1].label: 'a' is used twice; give each command its own label"),
])
def test_a_bad_command_entry_is_one_user_error_naming_file_line_and_key(tmp_path, entry, message):
    from compare.suite.reader import load_suite

    (tmp_path / "suite.toml").write_text(SUITE_HEAD + "[[engines]]\n" + entry + "\n")
    with pytest.raises(UserError) as error:
        load_suite(tmp_path / "suite.toml")
    assert str(error.value).startswith(str(tmp_path / "suite.toml")) and message in str(error.value)
