"""Faults against a real ``xval run``: kill -9 and SIGTERM mid-run, two runs of one directory, a hung
reference, a case past the memory limit, a timed-out case whose engine left children, a full disk.

Every test that starts processes bounds them (timeouts) and cleans up by pid: whatever xval
started is recorded from /proc before the fault and SIGKILLed in ``finally`` if it survived.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path



from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from conftest import HERE, ROOT, XVAL, XVAL_ENV, run_xval, wait_for



def suite_text(engines, duration=0.5, dt="[1e-2]", scene="bead", parameters=""):
    lines = [f"duration = {duration}", f"dt = {dt}", "timeout = 60", "[[scenes]]", f'scene = "{scene}"']
    if parameters:
        lines.append(f"parameters = {{ {parameters} }}")
    for engine in engines:
        lines += ["[[engines]]", f'id = "{engine}"']
    return "\n".join(lines) + "\n"


def alive(pid: int) -> bool:
    """True when ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


def descendants(root: int) -> set[int]:
    """Every live process below ``root`` (children, their children, ...), from /proc."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                parents[int(entry)] = int(fields[1])
            except (OSError, IndexError, ValueError):
                continue
    found, frontier = set(), {root}
    while frontier:
        frontier = {pid for pid, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return {pid for pid in found if alive(pid)}


def kill_all(pids) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def start_run(suite_file: Path, output: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(XVAL + ["run", str(suite_file), "--output", str(output), *extra], cwd=ROOT, env=XVAL_ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


HANGING = suite_text(["compare_engines:MISBEHAVING/sleep", "guard_engines:HOG/children"])


def wait_for_hosts(process: subprocess.Popen, n: int) -> set[int]:
    """The run's processes once there are ``n`` of them under xval (its case hosts, and their engines' children)."""
    return wait_for(lambda: (lambda d: d if len(d) >= n else None)(descendants(process.pid)), 60,
                    f"{n} processes under xval")


def test_kill_9_leaves_no_process_a_second_run_is_locked_out_and_resume_finishes(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(HANGING)
    out = tmp_path / "r"
    first = start_run(suite_file, out, "--jobs", "2")
    seen: set[int] = set()
    try:
        # 2 case hosts, 2 `sleep` children of the children engine.
        seen = wait_for_hosts(first, 4)
        second = run_xval("run", str(suite_file), "--output", str(out), "--resume", timeout=60)
        assert second.returncode == 2
        assert second.stderr.strip() == (f"xval: error: --output: {out} is being written by another xval run "
                                         f"(pid {first.pid}); wait for it to finish, or stop it, then run again "
                                         f"with --resume")
        seen |= descendants(first.pid)
        first.kill()
        first.wait(timeout=30)
        wait_for(lambda: not any(alive(pid) for pid in seen), 15, f"every process of the run to end: {seen}")
    finally:
        first.kill()
        kill_all(seen)
        first.communicate(timeout=30)
    assert json.loads((out / "run.json").read_text())["finished"] is None
    resumed = run_xval("run", str(suite_file), "--output", str(out), "--resume", "--timeout", "1")
    assert resumed.returncode == 0, resumed.stderr
    results = load_results(out)
    assert results.header["finished"] is not None
    assert sorted(r.status.value for r in results.records) == ["timeout", "timeout"]


def test_sigterm_stops_the_run_leaves_no_process_nor_temporary_and_resume_finishes(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(suite_text(["compare_engines:MISBEHAVING/sleep", "compare_engines:MISBEHAVING/exact"]))
    out = tmp_path / "r"
    run = start_run(suite_file, out, "--jobs", "2")
    seen: set[int] = set()
    try:
        # The exact case finishes; the sleeper holds its case host (the other host waits, idle).
        wait_for(lambda: list((out / "cases").glob("*.json")) if (out / "cases").is_dir() else [], 60, "a case record")
        seen = wait_for_hosts(run, 2)
        run.send_signal(signal.SIGTERM)
        _, stderr = run.communicate(timeout=30)
        assert run.returncode == 143 and stderr.strip().splitlines()[-1] == "xval: terminated"
        assert "Traceback" not in stderr
        wait_for(lambda: not any(alive(pid) for pid in seen), 15, f"every process of the run to end: {seen}")
    finally:
        run.kill()
        kill_all(seen)
    assert [p.name for p in out.rglob("*.tmp")] == []
    assert len(list((out / "cases").glob("*.json"))) == 1
    resumed = run_xval("run", str(suite_file), "--output", str(out), "--resume", "--timeout", "1")
    assert resumed.returncode == 0, resumed.stderr
    assert "1 already done" in resumed.stdout


def test_a_timed_out_engine_leaves_no_children(tmp_path):
    suite = parse_suite(suite_text(["guard_engines:HOG/children"]))
    before = descendants(os.getpid())
    run_suite(suite, tmp_path / "r", jobs=1, timeout=2)
    [record] = load_results(tmp_path / "r").records
    assert record.status.value == "timeout"
    wait_for(lambda: descendants(os.getpid()) <= before, 10, "the engine's `sleep` children to be killed")


def test_the_reference_solve_runs_under_the_case_timeout(tmp_path):
    # 1e5 rad/s for 5 s (8e4 turns): DOP853 at 1e-12 needs minutes (1e4 rad/s for 2 s took ~2 s on an idle
    # machine, too close to the timeout); the engine's case is quick.
    suite = parse_suite(suite_text(["mujoco/hinge"], duration=5.0, dt="[1e-2]", parameters="omega0 = 1e5"))
    run_suite(suite, tmp_path / "r", jobs=1, timeout=2)  # no wall-clock bound: the message below says it was cut
    [record] = load_results(tmp_path / "r").records
    assert ("reference failed (the reference of scene 'bead' ran past the timeout of 2 s and was killed): "
            "no reference-based metric") in record.message
    for name in ("position_error_linf", "position_error_rms", "position_error_final", "divergence_time"):
        assert record.metrics[name] is None, name  # null: not measured (the message says why), never "never diverged"


def test_a_case_past_the_memory_limit_fails_with_the_reason_and_the_others_carry_on(tmp_path):
    suite = parse_suite(suite_text(["guard_engines:HOG/memory", "mujoco/hinge"]))
    run_suite(suite, tmp_path / "r", jobs=1, memory_limit=2 * 2**30)
    records = {r.case.engine: r for r in load_results(tmp_path / "r").records}
    hog = records["guard_engines:HOG/memory"]
    assert hog.status.value == "failed"
    assert hog.message.startswith("ran out of memory past the memory limit of 2 GiB (")
    assert hog.message.endswith("); raise --memory-limit if the case needs more")
    assert records["mujoco/hinge"].status.value == "ok", records["mujoco/hinge"].message


def _small_files() -> None:
    # Past 12 kB a write fails with EFBIG (Python ignores SIGXFSZ): a disk that fills after the first files.
    resource.setrlimit(resource.RLIMIT_FSIZE, (12288, resource.RLIM_INFINITY))


def test_a_full_disk_mid_run_is_one_line_exit_1_and_resume_finishes(tmp_path):
    suite_file = tmp_path / "s.toml"
    # A bead's record (~8.2 kB) fits under the 12 kB limit, a double pendulum's (~15 kB) does not.
    suite_file.write_text('dt = [1e-2]\nengines = ["mujoco/hinge"]\n[[scenes]]\nscene = "bead"\nparameters = { duration = 0.3 }\n'
                          '[[scenes]]\nscene = "double-pendulum"\nparameters = { duration = 1.0 }\n')
    out = tmp_path / "r"
    full = run_xval("run", str(suite_file), "--output", str(out), "--jobs", "1", preexec_fn=_small_files)
    assert full.returncode == 1, full.stderr
    [line] = full.stderr.strip().splitlines()[-1:]
    assert line.startswith("xval: error: ") and "File too large: no room to write" in line
    assert "Traceback" not in full.stderr
    assert [p.name for p in out.rglob("*.tmp")] == []
    assert [r.case.scene_id for r in load_results(out).records] == ["bead"]  # the finished case is kept
    resumed = run_xval("run", str(suite_file), "--output", str(out), "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert "1 already done" in resumed.stdout
    assert len(load_results(out).records) == 2


def test_kill_9_also_ends_an_outside_program_in_its_own_session(tmp_path):
    # A command engine's program runs in a session of its own (engines/external/command.py), out of the case
    # host's group: the host, told by the kernel that xval died, kills that group too.
    pidfile = tmp_path / "pids"
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(
        f'duration = 0.2\ndt = [1e-2]\ntimeout = 60\n[[scenes]]\nscene = "bead"\n[[engines]]\n'
        f'command = {json.dumps([sys.executable, str(HERE / "protocol_program.py"), "hang"])}\nlabel = "hang"\n'
        f'options = {{ pidfile = {json.dumps(str(pidfile))} }}\n'
    )
    run = start_run(suite_file, tmp_path / "r", "--jobs", "1")
    program: list[int] = []
    try:
        wait_for(lambda: pidfile.exists() and len(pidfile.read_text().split()) == 3, 60, "the program's pids")
        program = [int(x) for x in pidfile.read_text().split()]  # pid, pgid, its `sleep` child
        assert alive(program[0]) and alive(program[2])
        run.kill()
        run.wait(timeout=30)
        wait_for(lambda: not alive(program[0]) and not alive(program[2]), 15, "the program and its child to end")
    finally:
        run.kill()
        kill_all(program[:1] + program[2:])
        run.communicate(timeout=30)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time (s) of ``pid`` so far, from /proc (0 when it is gone)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_kill_9_ends_a_case_host_inside_a_long_compiled_loop(tmp_path):
    # The host runs a numba loop of ~10 minutes, holding the GIL: no Python signal handler can run in it.
    # The kernel's SIGKILL (PR_SET_PDEATHSIG) ends it when xval dies; with SIGTERM it ran on to the loop's end.
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(suite_text(["guard_engines:HOG/spin"]).replace("timeout = 60", "timeout = 3600"))
    run = start_run(suite_file, tmp_path / "r", "--jobs", "1")
    seen: set[int] = set()
    try:
        # The host (and its reaper) once the host has spent 3 s of CPU past its start: numba compiled, looping.
        seen = wait_for_hosts(run, 2)
        host = wait_for(lambda: next((p for p in descendants(run.pid) if cpu_seconds(p) > 3.0), None), 120,
                        "the case host to be inside the compiled loop")
        before = cpu_seconds(host)
        wait_for(lambda: cpu_seconds(host) > before + 0.5, 60, "the host to keep spinning")
        seen |= descendants(run.pid)
        run.kill()
        run.wait(timeout=30)
        # The kernel delivers the SIGKILL at once; 20 s only absorbs a loaded machine's scheduling.
        wait_for(lambda: not any(alive(pid) for pid in seen), 20, "the host and its reaper to be killed")
    finally:
        run.kill()
        kill_all(seen)
        run.communicate(timeout=30)
