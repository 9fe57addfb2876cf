"""Cases on a real Dask cluster: the same records as the local pool, the reference solved once per scene,
a killed worker fails only its case, a lost scheduler stops the run for --resume, version mismatches are
reported, and --scheduler without dask says how to install it."""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import distributed
import pytest


from compare.run import environment
from compare.run.cluster import connect, parse_scheduler, run_on_cluster, start_local_cluster
from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import load_suite, parse_suite
from engines.errors import UserError
from conftest import ROOT, XVAL, XVAL_ENV, run_xval, wait_for



@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 worker processes of 1 thread, as ``--scheduler local:2`` starts; tests reach it by address."""
    with start_local_cluster(2) as local:
        yield local


#: Fields that depend on the machine's speed or the clock, left out when runs are compared.
TIMING = {"wall_time", "cost_per_simulated_second", "steps_per_second"}
TIMING_SETTINGS = {"ours.compile_or_cache_load_s"}


def deterministic(record) -> dict:
    clocks = ("elapsed", "wall_times", "finished", "cpu_times", "calibrations")
    record = {k: v for k, v in record.to_json().items() if k not in clocks}
    record["metrics"] = {k: v for k, v in (record["metrics"] or {}).items() if k not in TIMING}
    for part in ("run_info", "reference"):
        if record[part]:
            record[part] = {k: v for k, v in record[part].items() if k not in ("wall_time", "cpu_time")}
    if record["run_info"] and record["run_info"].get("settings"):
        record["run_info"]["settings"] = {k: v for k, v in record["run_info"]["settings"].items()
                                          if k not in TIMING_SETTINGS}
    return record


def records_by_id(path: Path) -> dict[str, dict]:
    return {r.case.id: r for r in load_results(path).records}


def suite_text(engines: list[str], timeout: float = 20, dt: str = "[1e-2]") -> str:
    lines = ["duration = 0.5", f"dt = {dt}", f"timeout = {timeout}", "[[scenes]]", 'scene = "bead"']
    for engine in engines:
        lines += ["[[engines]]", f'id = "{engine}"']
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("suite_path", ["tests/cluster_suite.toml", "suites/smoke.toml"])
def test_a_cluster_gives_the_local_pools_records_and_solves_each_reference_once(cluster, tmp_path, suite_path):
    suite = load_suite(ROOT / suite_path)
    run_suite(suite, tmp_path / "local", jobs=2)
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as observer:
        with distributed.get_task_stream(client=observer) as stream:
            run_on_cluster(suite, tmp_path / "cluster", cluster.scheduler_address)
    local, remote = records_by_id(tmp_path / "local"), records_by_id(tmp_path / "cluster")
    assert len(remote) == len(suite.scenes) * len(suite.engines) * len(suite.dts)
    assert {k: deterministic(r) for k, r in remote.items()} == {k: deterministic(r) for k, r in local.items()}
    assert all(r.status == "ok" for r in remote.values())

    # One reference task per scene; every case got its reference's metrics from it.
    references = sorted(task["key"].rsplit(" ", 1)[0] for task in stream.data if task["key"].startswith("solve_reference"))
    assert references == sorted(f"solve_reference {s.scene.name}" for s in suite.scenes)

    info = json.loads((tmp_path / "cluster" / "run.json").read_text())["environment"]["cluster"]
    assert info["scheduler"] == cluster.scheduler_address and info["local_cluster"] is False
    assert (info["workers"], info["threads"], info["mismatches"]) == (2, 2, [])
    [software] = info["worker_software"]
    assert software["engines"] == environment.engine_versions() and len(software["workers"]) == 2


def _pretend_engine_version(engine: str, version: str) -> None:
    """Runs on a worker: its engine_versions() reports ``version`` for ``engine`` (undone by _restore_engine_versions)."""
    real = getattr(environment, "_real_engine_versions", environment.engine_versions)
    environment._real_engine_versions = real
    environment.engine_versions = lambda: {**real(), engine: version}


def _restore_engine_versions() -> None:
    environment.engine_versions = getattr(environment, "_real_engine_versions", environment.engine_versions)


def test_a_worker_with_other_engine_versions_is_reported(cluster, tmp_path):
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        odd = sorted(client.scheduler_info()["workers"])[0]
        client.run(_pretend_engine_version, "mujoco", "0.0-odd", workers=[odd])
        try:
            warnings: list[str] = []
            run_on_cluster(parse_suite(suite_text(["pymunk/pin"])), tmp_path / "r", cluster.scheduler_address,
                           warn=warnings.append)
        finally:
            client.run(_restore_engine_versions)
    here = environment.engine_versions()["mujoco"]
    expected = f"worker {odd} runs mujoco 0.0-odd (here {here}); its results are not comparable with this machine's"
    assert warnings == [expected]
    info = load_results(tmp_path / "r").header["environment"]["cluster"]
    assert info["mismatches"] == [expected]
    assert sorted(g["engines"]["mujoco"] for g in info["worker_software"]) == sorted(["0.0-odd", here])


#: What a case may take, in multiples of :func:`startup_seconds` now, before the test calls it hung (and 20 s at least).
STARTUP_MULTIPLE = 10


def startup_seconds() -> float:
    """s of wall time a fresh process takes now to import the engines and solve the suite's bead: what a case
    on a restarted worker pays before it answers, on this machine at its present load."""
    probe = ("from engines.registry import load_engine; from engines.scene import catalog; "
             "from engines.reference.reference import solve; load_engine('mujoco/hinge'); "
             "solve(catalog.build('bead', {'duration': 0.5}))")
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=XVAL_ENV, check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


@pytest.mark.timeout(1800)  # the case timeout grows with the load (below); a hang still ends here
def test_a_killed_worker_fails_only_its_case(cluster, tmp_path):
    engines = ["compare_engines:MISBEHAVING/kill-worker", "compare_engines:MISBEHAVING/exact",
               "compare_engines:MISBEHAVING/kill", "compare_engines:MISBEHAVING/sleep",
               "compare_engines:MISBEHAVING/raise", "mujoco/hinge"]
    # Holds at any load: only the hour-long sleeper may reach the timeout, so the timeout is what a case on a
    # freshly restarted worker takes *now* (imports and the bead's reference, measured in a new process just
    # before), times STARTUP_MULTIPLE, and 20 s at least: it grows as the machine slows (a fixed 20 s failed
    # above a load of ~20, a case other than the sleeper timing out). No wall-clock bound on the run (a hang
    # is pytest-timeout's to catch).
    timeout = max(20, math.ceil(STARTUP_MULTIPLE * startup_seconds()))
    summary = run_on_cluster(parse_suite(suite_text(engines, timeout=timeout)), tmp_path / "r", cluster.scheduler_address)
    status = {r.case.engine.split("/")[-1]: (r.status, r.message) for r in load_results(tmp_path / "r").records}
    # The worker killer took down a worker on each of its two attempts (allowed-failures = 1, as the local pool retries once).
    assert status.pop("kill-worker")[0] == "failed"
    assert status == {
        "exact": ("ok", ""),
        "kill": ("failed", "the engine's process died (signal SIGKILL) before returning a result"),
        "sleep": ("timeout", f"ran past the timeout of {timeout:g} s and was killed; raise --timeout if it is only slow"),
        "raise": ("failed", "RuntimeError: deliberate failure in the stepping loop"),
        "hinge": ("ok", ""),
    }
    [killer] = [r for r in load_results(tmp_path / "r").records if r.case.variant == "kill-worker"]
    assert killer.message.startswith("WorkerDied: the Dask worker process running it died (2 attempts, the last on tcp://")
    assert summary.counts == {"failed": 3, "ok": 2, "timeout": 1}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_lost_scheduler_stops_the_run_and_resume_finishes_it(tmp_path):
    address = f"tcp://127.0.0.1:{free_port()}"
    dask = [str(Path(sys.executable).parent / "dask")]
    started = []
    try:
        started.append(subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                                                "--no-dashboard"], start_new_session=True, env=XVAL_ENV,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        started.append(subprocess.Popen(dask + ["worker", address, "--nthreads", "1", "--no-dashboard"],
                                        start_new_session=True, env=XVAL_ENV, cwd=ROOT,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        suite_file = tmp_path / "s.toml"
        # One thread: the cases run in this order, and the sleeper holds the worker when the scheduler dies.
        suite_file.write_text(suite_text(["compare_engines:MISBEHAVING/exact", "mujoco/hinge", "pymunk/pin",
                                          "compare_engines:MISBEHAVING/sleep", "compare_engines:MISBEHAVING/raise"],
                                         timeout=60))
        out = tmp_path / "r"
        run = subprocess.Popen(XVAL + ["run", str(suite_file), "--output", str(out), "--scheduler", address],
                               cwd=ROOT, env=XVAL_ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        wait_for(lambda: len(list((out / "cases").glob("*.json"))) >= 3, 180, "3 finished cases")
        os.killpg(started[0].pid, signal.SIGKILL)
        stdout, stderr = run.communicate(timeout=120)  # the run notices the lost scheduler (a hang fails here)
        assert run.returncode == 1, stderr
        assert stderr.splitlines()[-1] == (f"xval: error: lost the connection to the Dask scheduler at {address}; "
                                           f"the finished cases are in {out}: run again with --resume")
        assert "Traceback" not in stderr
        kept = sorted(r.case.engine for r in load_results(out).records)
        assert kept == ["compare_engines:MISBEHAVING/exact", "mujoco/hinge", "pymunk/pin"]
        assert json.loads((out / "run.json").read_text())["finished"] is None
    finally:
        for process in started:
            with_group_killed(process)
    # --timeout 10: the sleeper's (an hour) stops it; raise, the other case left, needs far less even under load.
    resumed = run_xval("run", str(suite_file), "--output", str(out), "--resume", "--timeout", "10")
    assert resumed.returncode == 0, resumed.stderr
    assert "2 cases run" in resumed.stdout and "3 already done" in resumed.stdout
    status = {r.case.engine: r.status for r in load_results(out).records}
    assert status["compare_engines:MISBEHAVING/sleep"] == "timeout" and len(status) == 5


def with_group_killed(process: subprocess.Popen) -> None:
    """SIGKILL the process group this test started (the process, its Dask worker, its case hosts)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait(timeout=10)


def test_scheduler_local_from_the_command_line(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(suite_text(["pymunk/pin", "compare_engines:MISBEHAVING/raise"]))
    out = tmp_path / "r"
    run = run_xval("run", str(suite_file), "--output", str(out), "--scheduler", "local:2")
    assert run.returncode == 0, run.stderr
    assert f"results: {out}" in run.stdout and "2 cases run" in run.stdout
    status = {r.case.engine: (r.status, r.message) for r in load_results(out).records}
    assert status == {"pymunk/pin": ("ok", ""),
                      "compare_engines:MISBEHAVING/raise": ("failed", "RuntimeError: deliberate failure in the stepping loop")}
    info = load_results(out).header["environment"]["cluster"]
    assert info["local_cluster"] is True and info["workers"] == 2 and info["scheduler"].startswith("tcp://127.0.0.1:")


def test_without_dask_scheduler_exits_2_with_the_install_hint(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(suite_text(["pymunk/pin"]))
    blocked = "import sys; sys.modules['distributed'] = None; from compare.cli import main; main()"
    run = subprocess.run([sys.executable, "-c", blocked, "run", str(suite_file), "--output", str(tmp_path / "r"),
                          "--scheduler", "local:2"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr == ("xval: error: --scheduler needs Dask's distributed scheduler, which is not installed; "
                          "install it with: pip install 'xval[dask]'\n")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("text, message", [
    ("local:0", "--scheduler: 'local:0' asks for no workers; use local:N with N >= 1"),
    ("locale", "--scheduler: expected tcp://HOST:PORT or local\\[:N\\], got 'locale'"),
    ("tcp://host", "--scheduler: expected tcp://HOST:PORT or local\\[:N\\], got 'tcp://host'"),
])
def test_a_malformed_scheduler_is_refused(text, message):
    with pytest.raises(UserError, match=f"^{message}$"):
        parse_scheduler(text)


def test_a_scheduler_that_does_not_answer_or_jobs_with_an_address_is_refused():
    address = f"tcp://127.0.0.1:{free_port()}"
    with pytest.raises(UserError, match=f"^--scheduler: cannot reach a Dask scheduler at {address} .*start one with 'dask scheduler'"):
        with connect(address, connect_timeout=1):
            pass
    with pytest.raises(UserError, match="^--jobs sets the local pool's processes; with --scheduler ADDRESS"):
        with connect(address, jobs=2):
            pass
    with start_local_cluster(0) as empty:
        with pytest.raises(UserError, match=f"^--scheduler: no Dask worker joined {empty.scheduler_address} within 0.5 s; "
                                            f"start workers with: dask worker {empty.scheduler_address}$"):
            with connect(empty.scheduler_address, worker_timeout=0.5):
                pass
    assert parse_scheduler("local").workers is None and parse_scheduler("127.0.0.1:8786").address == "127.0.0.1:8786"
