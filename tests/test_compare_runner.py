"""The runner on real engines: isolation of misbehaving cases, skipped pairs, resume after SIGKILL,
observed orders from real sweeps, and the run/show commands."""

from __future__ import annotations

import concurrent.futures as cf
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest


from compare.run.results import load_results
from compare.run.runner import run_suite
from compare.suite.reader import parse_suite
from compare.results.sweep import sweeps
from engines.errors import UserError
from conftest import ROOT, XVAL, run_xval, wait_for



def suite_text(engines: list[str], dt: str = "[1e-2]", duration: float = 0.5, scenes=("bead",), extra: str = "") -> str:
    lines = [f"duration = {duration}", f"dt = {dt}", "timeout = 20", extra]
    for scene in scenes:
        lines += ["[[scenes]]", f'scene = "{scene}"']
    for engine in engines:
        lines += ["[[engines]]", f'id = "{engine}"']
    return "\n".join(lines) + "\n"


def by_engine(path: Path) -> dict[str, dict]:
    return {r.case.engine: r for r in load_results(path).records}


def test_misbehaving_cases_are_isolated_and_the_others_complete(tmp_path):
    modes = ["exact", "raise", "nan", "sleep", "kill", "exit", "drift"]
    suite = parse_suite(suite_text([f"compare_engines:MISBEHAVING/{m}" for m in modes] + ["mujoco/hinge"]))
    # A timeout of 20 s: only the sleeper (an hour) reaches it, even on a loaded machine (3 s once timed out
    # the exact case's cold start at a load average of 12). Its status below says it was killed there; a run
    # that waited for it would hang, which pytest-timeout (300 s, pyproject.toml) fails: no wall-clock bound.
    summary = run_suite(suite, tmp_path / "r", jobs=2, timeout=20)
    records = by_engine(tmp_path / "r")
    status = {k.split("/")[-1]: (r.status, r.message) for k, r in records.items()}
    assert status["exact"] == ("ok", "")
    assert status["raise"] == ("failed", "RuntimeError: deliberate failure in the stepping loop")
    assert status["nan"][0] == "unstable" and status["nan"][1].startswith("non-finite state at t = 0.25")
    assert status["sleep"] == ("timeout", "ran past the timeout of 20 s and was killed; raise --timeout if it is only slow")
    assert status["kill"] == ("failed", "the engine's process died (signal SIGKILL) before returning a result")
    assert status["exit"] == ("failed", "the engine's process died (exit code 3) before returning a result")
    assert status["drift"][0] == "unstable" and "constraint error 0.5 m exceeds the bound 0.1 L" in status["drift"][1]
    assert status["hinge"][0] == "ok"
    assert records["compare_engines:MISBEHAVING/exact"].metrics["position_error_linf"] == 0.0
    # The NaN run's metrics cover the samples before the first non-finite one.
    assert records["compare_engines:MISBEHAVING/nan"].metrics["n_samples"] == 25
    assert summary.counts == {"failed": 3, "ok": 2, "timeout": 1, "unstable": 2}


def test_a_trajectory_sampled_at_its_own_times_is_compared_with_the_reference_at_those_times(tmp_path):
    # compare_engines.OWN_TIMES returns the reference itself, each sample a third of an interval
    # before its scheduled time: compared at the schedule's times it would be off by the bead's motion.
    suite = parse_suite(suite_text(["compare_engines:OWN_TIMES/exact"]))
    run_suite(suite, tmp_path / "r", jobs=1)
    record = next(iter(by_engine(tmp_path / "r").values()))
    assert record.status.value == "ok"
    t = json.loads(next((tmp_path / "r" / "cases").glob("*.json")).read_text())["series"]["t"]
    assert t[1] == pytest.approx(0.01 * 2 / 3)
    assert record.metrics["position_error_linf"] == 0.0


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_case_that_kills_its_pool_worker_is_failed_and_no_other_case_is_blamed(tmp_path, jobs):
    # Not isolated, the engines run in the pool's workers: the killer's death breaks the
    # ProcessPoolExecutor. The runner rebuilds it and runs each case lost in the break again alone,
    # so only the one that breaks the pool alone is failed, while innocent cases running beside it
    # (with 2 jobs) or queued behind it (with 1) still finish ok.
    engines = ["compare_engines:MISBEHAVING/kill", "compare_engines:MISBEHAVING/exact", "mujoco/hinge", "pymunk/pin"]
    summary = run_suite(parse_suite(suite_text(engines)), tmp_path / "r", jobs=jobs, isolate=False)
    status = {r.case.engine: (r.status, r.message) for r in load_results(tmp_path / "r").records}
    assert status.pop("compare_engines:MISBEHAVING/kill") == ("failed", "a worker process of the executor died while it ran")
    assert {engine: s for engine, (s, _) in status.items()} == {
        "compare_engines:MISBEHAVING/exact": "ok", "mujoco/hinge": "ok", "pymunk/pin": "ok"}
    assert summary.counts == {"failed": 1, "ok": 3}


def live_children_like_this_process() -> list[int]:
    """Live (not zombie) processes whose parent is this one and whose command line is this one's:
    forks of it, as case hosts are. Linux /proc."""
    mine = Path("/proc/self/cmdline").read_bytes()
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and (proc / "cmdline").read_bytes() == mine:
                fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
                if int(fields[1]) == os.getpid() and fields[0] != "Z":
                    found.append(int(proc.name))
        except (OSError, ValueError):
            continue  # it exited while we looked
    return found


def test_a_local_run_drives_its_case_hosts_itself_and_leaves_none_behind(tmp_path):
    # The case hosts are this process's own children (no pool worker between): a case that kills
    # its host, one that times out and a reference solved in a host each cost only themselves, and
    # when the run returns every host it forked has ended (the killed and timed-out ones included).
    before = set(live_children_like_this_process())
    engines = ["compare_engines:MISBEHAVING/kill", "compare_engines:MISBEHAVING/sleep", "mujoco/hinge", "pymunk/pin",
               "compare_engines:MISBEHAVING/exact"]
    suite = parse_suite(suite_text(engines, dt="[1e-2, 1e-3]"))
    # 20 s: only the sleeper reaches it, however loaded the machine (2 s once cut a cold start).
    summary = run_suite(suite, tmp_path / "r", jobs=2, timeout=20)
    assert summary.counts == {"failed": 2, "ok": 6, "timeout": 2}
    assert set(live_children_like_this_process()) - before == set()
    exact = [r for r in load_results(tmp_path / "r").records if r.case.variant == "exact"]
    assert [r.run_info["settings"]["host_parent"] for r in exact] == [os.getpid()] * 2


def test_any_executor_and_skipped_pairs(tmp_path):
    # pymunk is 2-D: the spherical pendulum is recorded as skipped with the reason, not dropped.
    suite = parse_suite(suite_text(["pymunk/pin", "mujoco/hinge"], scenes=("bead", "spherical-pendulum")))
    with cf.ThreadPoolExecutor(2) as executor:
        run_suite(suite, tmp_path / "r", executor=executor)
    records = load_results(tmp_path / "r").records
    skipped = [r for r in records if r.status == "skipped"]
    assert [(r.case.scene_id, r.case.engine) for r in skipped] == [("spherical-pendulum", "pymunk/pin")]
    assert skipped[0].message == "pymunk is 2-D and cannot express the 3-D scene 'spherical-pendulum'"
    assert len(records) == 4


def test_a_results_directory_is_not_overwritten_and_resume_needs_the_same_suite(tmp_path):
    suite = parse_suite(suite_text(["pymunk/pin"]))
    run_suite(suite, tmp_path / "r")
    with pytest.raises(UserError, match="already holds results; pass --resume to finish that run"):
        run_suite(suite, tmp_path / "r")
    other = parse_suite(suite_text(["pymunk/pin"], dt="[1e-2, 1e-3]"))
    with pytest.raises(UserError, match="^--resume: .* holds results of a different suite"):
        run_suite(other, tmp_path / "r", resume=True)
    assert run_suite(suite, tmp_path / "r", resume=True).ran == 0


#: Fields that depend on the machine's speed or the clock, left out when runs are compared.
TIMING = {"wall_time", "cost_per_simulated_second", "steps_per_second"}


def deterministic(record) -> dict:
    record = record.to_json()
    for key in ("elapsed", "wall_times", "finished", "cpu_times", "calibrations"):
        record.pop(key, None)
    record["metrics"] = {k: v for k, v in (record["metrics"] or {}).items() if k not in TIMING}
    if record["run_info"]:
        record["run_info"] = {k: v for k, v in record["run_info"].items() if k not in ("wall_time", "cpu_time")}
    if record["reference"]:
        record["reference"] = {k: v for k, v in record["reference"].items() if k != "wall_time"}
    return record


def test_sigkill_part_way_then_resume_equals_an_uninterrupted_run(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(
        suite_text(["mujoco/hinge", "pymunk/pin", "pybullet/multibody", "mujoco/hinge-rk4"],
                   dt="[3e-2, 1e-2, 3e-3, 1e-3]", duration=1.0, scenes=("bead", "double-pendulum"))
    )
    total = 2 * 4 * 4
    interrupted = tmp_path / "interrupted"
    process = subprocess.Popen(
        XVAL + ["run", str(suite_file), "--output", str(interrupted), "--jobs", "1"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    cases = interrupted / "cases"
    wait_for(lambda: len(list(cases.glob("*.json"))) >= 5, 60, "5 finished cases", interval=0.01)
    os.killpg(process.pid, signal.SIGKILL)  # the CLI, its pool worker and any case child
    process.wait()
    before = {f.name: f.stat().st_mtime_ns for f in cases.glob("*.json")}
    assert 5 <= len(before) < total
    assert json.loads((interrupted / "run.json").read_text())["finished"] is None

    resumed = run_xval("run", str(suite_file), "--output", str(interrupted), "--resume", "--jobs", "2")
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(before)} already done" in resumed.stdout
    after = {f.name: f.stat().st_mtime_ns for f in cases.glob("*.json")}
    assert {name: after[name] for name in before} == before  # no finished case redone
    assert len(after) == total

    fresh = tmp_path / "fresh"
    run_suite(parse_suite(suite_file.read_text(), str(suite_file)), fresh, jobs=2)
    a = {r.case.id: deterministic(r) for r in load_results(interrupted).records}
    b = {r.case.id: deterministic(r) for r in load_results(fresh).records}
    assert a == b


@pytest.fixture(scope="module")
def bead_sweep(tmp_path_factory):
    path = tmp_path_factory.mktemp("order") / "r"
    text = suite_text(["ours/plain-rk4", "mujoco/hinge"], dt="{ from = 0.2, to = 0.002, per_decade = 2 }", duration=1.0)
    run_suite(parse_suite(text), path, jobs=2)
    return {s.engine: s for s in sweeps(load_results(path).records)}


def test_observed_order_of_ours_rk4_on_the_bead_is_4(bead_sweep):
    fit = bead_sweep["ours/plain-rk4"].order
    assert fit.order == pytest.approx(4.0, abs=0.3) and fit.n_points >= 3


def test_observed_order_of_mujoco_hinge_euler_on_the_bead_is_1(bead_sweep):
    fit = bead_sweep["mujoco/hinge"].order
    assert fit.order == pytest.approx(1.0, abs=0.1) and fit.n_points >= 3


def test_run_and_show_commands(tmp_path):
    suite_file = tmp_path / "s.toml"
    suite_file.write_text(suite_text(["pymunk/pin", "compare_engines:MISBEHAVING/raise"]))
    out = tmp_path / "r"
    run = run_xval("run", str(suite_file), "--output", str(out), "--jobs", "1", timeout=60)
    assert run.returncode == 0, run.stderr
    assert "most accurate at equal cost" in run.stdout and "pymunk/pin" in run.stdout and f"results: {out}" in run.stdout
    # Off a terminal: a line at every tenth of the run (here each of the two cases), not the cases themselves.
    assert run.stderr.splitlines() == ["running: 1/2 cases (50 %)", "running: 2/2 cases (100 %), 1 not ok"]
    show = run_xval("show", str(out))
    table = show.stdout.splitlines()
    # The scene line carries the reference's own error, horizon and Lyapunov estimate (docs/metrics.md).
    assert re.fullmatch(r"scene bead \(reference error \S+ m, horizon none, Lyapunov exponent -\)", table[2])
    assert table[3].split() == ["engine", "status", "dt", "error/m", "drift/E*", "c.err/m", "wall", "s/s", "order", "s/step",
                                "[interval]", "consistent"]
    assert table[4].split()[:4] == ["pymunk/pin", "ok", "1/1", "0.01"]
    assert table[5].split()[:3] == ["compare_engines:MISBEHAVING/raise", "failed", "1"]
    assert table[6] == "  compare_engines:MISBEHAVING/raise: RuntimeError: deliberate failure in the stepping loop"
    csv_out = run_xval("show", str(out), "--format", "csv")
    lines = csv_out.stdout.splitlines()
    assert lines[0].startswith("scene,engine,dt,status,message,position_error_final") and len(lines) == 3
    rows = json.loads(run_xval("show", str(out), "--format", "json").stdout)
    assert [(r["engine"], r["status"]) for r in rows] == [("pymunk/pin", "ok"), ("compare_engines:MISBEHAVING/raise", "failed")]


def test_cli_errors_are_one_line(tmp_path):
    missing = run_xval("run", "nope.toml", "--output", str(tmp_path / "r"))
    assert missing.returncode == 2
    assert missing.stderr.startswith("xval: error: nope.toml: no such file; pass the path of a suite") and missing.stderr.count("\n") == 1
    show = run_xval("show", str(tmp_path))
    assert show.returncode == 2
    assert show.stderr == f"xval: error: {tmp_path}: not a results directory (no run.json); give the --output directory of 'xval run'\n"


def test_a_run_leaves_the_garbage_collector_as_it_found_it(tmp_path):
    """preload_engines freezes what is loaded (gc.freeze) so full collections skip it during the run; the run
    unfreezes it at its end, so a program that runs many suites does not keep their objects for ever."""
    import gc

    assert gc.get_freeze_count() == 0
    run_suite(parse_suite(suite_text(["pymunk/pin"], duration=0.02)), tmp_path / "out", jobs=1)
    assert gc.get_freeze_count() == 0


@pytest.mark.parametrize("enabled", [True, False])
def test_the_run_command_collects_no_garbage_while_loading_and_leaves_the_collector_as_it_was(tmp_path, enabled):
    """compare/run/startup.py: ``xval run`` turns the collector off while the suite loads its engines
    (preload_engines freezes them) and back on before the case hosts fork and the cases run, so their
    garbage is collected as usual, in the hosts too; a collector the calling program turned off stays
    off."""
    import gc

    from compare.cli import main
    from compare.run import isolation, runner

    suite = tmp_path / "s.toml"
    suite.write_text(suite_text(["pymunk/pin"], duration=0.02))
    seen = []
    in_host = tmp_path / "collector-in-host"
    preload, dispatch, warm_up = runner.preload_engines, runner._Dispatcher.run, isolation.warm_up

    def watching_preload(*args):
        seen.append(("preload", gc.isenabled()))
        preload(*args)

    def watching_run(self):
        seen.append(("cases", gc.isenabled()))
        dispatch(self)

    def watching_warm_up(task):  # runs in the case host (forked with this module as patched here)
        in_host.write_text(str(gc.isenabled()))
        warm_up(task)

    was = gc.isenabled()
    (gc.enable if enabled else gc.disable)()
    runner.preload_engines, runner._Dispatcher.run = watching_preload, watching_run
    isolation.warm_up = watching_warm_up
    try:
        main(["run", str(suite), "--output", str(tmp_path / "out"), "--jobs", "1", "--quiet"])
        after = gc.isenabled()
    finally:
        runner.preload_engines, runner._Dispatcher.run, isolation.warm_up = preload, dispatch, warm_up
        (gc.enable if was else gc.disable)()
    assert seen == [("preload", False), ("cases", enabled)]
    assert in_host.read_text() == str(enabled)
    assert after is enabled and gc.get_freeze_count() == 0


def test_the_xval_program_freezes_what_is_left_as_it_exits():
    # compare.cli.console (the installed `xval`): the interpreter's last full collection, at exit, then
    # walks nothing a run loaded. Checked in a child process, whose exit is its own.
    probe = "import gc; from compare.cli import console\ntry:\n    console(['--help'])\nexcept SystemExit:\n    pass\n" \
            "print(gc.get_freeze_count() > 0)"
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "True"


def test_collection_resumes_for_a_run_on_an_executor_passed_in(tmp_path):
    # A run on an executor passed in (a cluster's) preloads nothing, so nothing else would turn the
    # collector back on that the run command turned off while loading: the runner does, as it starts.
    import gc

    from compare.run import startup

    was = gc.isenabled()
    gc.enable()
    try:
        startup.defer_collection()
        assert not gc.isenabled()
        with cf.ThreadPoolExecutor(1) as executor:
            run_suite(parse_suite(suite_text(["pymunk/pin"], duration=0.02)), tmp_path / "out", executor=executor)
        assert gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


def test_milestone_progress_prints_at_each_tenth_of_the_run_resumed_or_not():
    import io
    from types import SimpleNamespace

    from compare.results.record import Status
    from compare.run.progress import MilestoneProgress

    def lines(total, already, bad=()):
        out = io.StringIO()
        progress = MilestoneProgress(out)
        progress.start(total, already)
        for k in range(already, total):
            progress.advance(SimpleNamespace(status=Status.FAILED if k in bad else Status.OK))
        return out.getvalue().splitlines()

    fresh = lines(462, 0, bad={3})
    assert [line.split()[1] for line in fresh] == ["47/462", "93/462", "139/462", "185/462", "231/462", "278/462",
                                                   "324/462", "370/462", "416/462", "462/462"]
    assert fresh[0] == "running: 47/462 cases (10 %), 1 not ok"
    resumed = lines(462, 93)
    assert resumed[0] == "resuming: 93 of 462 cases already done" and resumed[1].startswith("running: 139/462")
    assert len(resumed) == 9
