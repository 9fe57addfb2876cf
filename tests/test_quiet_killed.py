"""What an engine printed before its case host died (a segfault) or was killed (past its timeout) stays with the
case's record: the host prints into a file without a name that its driver holds too (engines.stdio.output_file),
emptied once each answered case has its summary, and the driver reads it when the host ends without an answer.

The stand-in (compare_engines.PRINTING) is real code doing to its own process what an engine library may: it
prints 40 lines through C's stdio, write(2) and Python's print, then reads address 0 (SIGSEGV) or sleeps past
its timeout. Nothing of it reaches the terminal without --verbose, and nothing is left behind: no process (by
pid), no file.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
from dataclasses import replace

from compare.run.hosts import HostPool
from compare.run.isolation import CaseTask
from engines.scene.catalog import build
from engines.stdio import KEPT_LINES

from compare_engines import PRINTED, printed_line
from conftest import ROOT, XVAL, XVAL_ENV
from test_fault_processes import alive, kill_all

#: What a record keeps of the stand-in's 40 lines: the count, the first 5 and the last 5.
KEPT = {"lines": PRINTED, "first": [printed_line(k) for k in range(KEPT_LINES)],
        "last": [printed_line(k) for k in range(PRINTED - KEPT_LINES, PRINTED)]}
#: s a stand-in may run: its 40 lines take microseconds, so only the hanging one reaches it.
TIMEOUT = 5


def suite_text(modes, pidfile) -> str:
    engines = "".join(f'[[engines]]\nid = "compare_engines:PRINTING/{mode}"\noptions = {{ pidfile = "{pidfile}" }}\n'
                      for mode in modes)
    return f'duration = 0.2\ndt = [1e-2]\ntimeout = {TIMEOUT}\n[[scenes]]\nscene = "bead"\n{engines}'


def run(tmp_path, modes, *extra):
    """``xval run`` of the stand-ins in ``modes``, with a temporary directory of its own (TMPDIR), no
    faulthandler (whose dump of a segfault, where enabled, joins the case's lines) and Python's default
    buffering (PYTHONUNBUFFERED would also unbuffer C's stdout, and hide a host that did not line-buffer
    its own); returns the finished process, the records by variant, the pids the stand-ins ran in, and
    the temporary directory."""
    pidfile, scratch, out = tmp_path / "pids", tmp_path / "tmp", tmp_path / "out"
    scratch.mkdir()
    (tmp_path / "suite.toml").write_text(suite_text(modes, pidfile))
    env = {k: v for k, v in XVAL_ENV.items() if k not in ("PYTHONFAULTHANDLER", "PYTHONUNBUFFERED")}
    env["TMPDIR"] = str(scratch)
    pids: list[int] = []
    try:
        done = subprocess.run(XVAL + ["run", str(tmp_path / "suite.toml"), "--output", str(out), "--jobs", "2",
                                      *extra], cwd=ROOT, env=env, capture_output=True, text=True, timeout=240)
    finally:
        pids = [int(p) for p in pidfile.read_text().split()] if pidfile.exists() else []
        kill_all([p for p in pids if alive(p)])  # only if the assertion below is to fail: never left running
    records = {json.loads(f.read_text())["case"]["variant"]: json.loads(f.read_text())
               for f in (out / "cases").glob("*.json")}
    return done, records, pids, scratch


def open_files() -> set[str]:
    """What this process's file descriptors point at (a pipe's inode, a file's path, ``(deleted)`` once unnamed)."""
    found = set()
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):  # the listing's own descriptor, closed by now
            found.add(os.readlink(f"/proc/self/fd/{fd}"))
    return found


def test_a_segfaulted_and_a_timed_out_case_keep_what_their_engine_printed_and_the_terminal_stays_quiet(tmp_path):
    done, records, pids, scratch = run(tmp_path, ["segfault", "hang"])
    assert done.returncode == 0, done.stderr
    assert "stand-in engine line" not in done.stdout + done.stderr
    assert "Fatal Python error" not in done.stdout + done.stderr
    crashed, hung = records["segfault"], records["hang"]
    assert (crashed["status"], crashed["message"]) == (
        "failed", "the engine's process died (signal SIGSEGV) before returning a result")
    assert (hung["status"], hung["message"]) == (
        "timeout", f"ran past the timeout of {TIMEOUT} s and was killed; raise --timeout if it is only slow")
    # Every line, the last one (C's printf, line-buffered in the host) too: none died in a buffer.
    assert crashed["engine_output"] == KEPT
    assert hung["engine_output"] == KEPT
    # Two hosts, one per stand-in, both ended; no file left in the temporary directory (the capture has no name).
    assert len(pids) == 2 and not any(alive(p) for p in pids)
    assert list(scratch.iterdir()) == []
    assert list((tmp_path / "out").rglob("*.tmp")) == []


def test_verbose_shows_what_a_segfaulted_case_printed(tmp_path):
    done, records, pids, _ = run(tmp_path, ["segfault"], "--verbose")
    assert done.returncode == 0, done.stderr
    assert records["segfault"]["engine_output"] == KEPT
    lines = done.stderr.splitlines()
    at = next(k for k, line in enumerate(lines) if "PRINTING/segfault" in line and "failed" in line)
    assert [line.strip() for line in lines[at + 1:at + 3 + 2 * KEPT_LINES]] == [
        f"engine printed {PRINTED} lines:", *KEPT["first"], f"… {PRINTED - 2 * KEPT_LINES} more lines …",
        *KEPT["last"]]
    assert "stand-in engine line" not in done.stdout
    assert not any(alive(p) for p in pids)


def test_each_case_keeps_only_its_own_lines_in_a_host_that_answered_then_was_killed(capsys):
    # One host runs three cases, each sent before the one ahead answers: the first answers (its lines go with its
    # answer and leave the file empty), the second hangs and is killed at its timeout (its record keeps its own
    # 40 lines, not 80), the third, waiting behind it, runs in a new host and printed nothing.
    scene = build("bead", {"duration": 0.2})
    task = CaseTask(case_id="", engine_id="", variant=None, options={}, scene=scene, dt=1e-2, sample_interval=0.05,
                    timeout=TIMEOUT)
    tasks = [replace(task, case_id=f"{k}:{engine}/{variant}", engine_id=f"compare_engines:{engine}/{variant}",
                     variant=variant) for k, (engine, variant) in
             enumerate((("PRINTING", "answer"), ("PRINTING", "hang"), ("MISBEHAVING", "exact")))]
    before = open_files()
    hosts = set()
    # Hosts forked with pytest's capture off: its sys.stdout (which print would reach) is no fd 1, as xval's is.
    with capsys.disabled():
        pool = HostPool(1, depth=3)
        futures = [pool.submit(t) for t in tasks]
        try:
            while not all(f.done() for f in futures):
                hosts |= {h.process.pid for h in pool.hosts}
                pool.wait([f for f in futures if not f.done()])
        finally:
            pool.shutdown(kill=True)
    answered, killed, after = (f.result() for f in futures)
    assert (answered.status, killed.status, after.status) == ("ok", "timeout", "ok")
    assert answered.output.to_dict() == KEPT and killed.output.to_dict() == KEPT
    assert after.output.lines == 0
    assert len(hosts) == 2 and not any(alive(p) for p in hosts)
    # The pool's pipes and the hosts' output files are all closed: this process holds no new descriptor.
    assert open_files() <= before


def test_a_case_run_by_an_executors_worker_keeps_what_it_printed_when_killed_at_its_timeout(capsys):
    # On a cluster or a thread pool, each worker thread drives a host of its own (compare.run.isolation.execute):
    # the same file, read the same way when the host is killed.
    from compare.run.isolation import execute

    task = CaseTask(case_id="hang", engine_id="compare_engines:PRINTING/hang", variant="hang", options={},
                    scene=build("bead", {"duration": 0.2}), dt=1e-2, sample_interval=0.05, timeout=TIMEOUT)
    before = open_files()
    with capsys.disabled():  # as above: print reaches fd 1 in the host, as in xval's
        outcome = execute(task)
    assert outcome.status == "timeout" and outcome.output.to_dict() == KEPT
    assert open_files() <= before


def test_a_host_forked_under_an_in_memory_stdout_still_keeps_what_python_printed(monkeypatch):
    # A test runner's capture (or any caller's) may leave sys.stdout an in-memory stream; the host inherits it
    # through the fork, and its print() went there and died with it (27 of 40 lines kept, on CI). The host
    # puts Python's streams back on fds 1 and 2, line-buffered.
    import io

    from compare.run.isolation import execute

    task = CaseTask(case_id="hang", engine_id="compare_engines:PRINTING/hang", variant="hang", options={},
                    scene=build("bead", {"duration": 0.2}), dt=1e-2, sample_interval=0.05, timeout=TIMEOUT)
    monkeypatch.setattr("sys.stdout", io.StringIO())
    outcome = execute(task)
    assert outcome.status == "timeout" and outcome.output.to_dict() == KEPT
