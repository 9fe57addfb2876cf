"""compare.run.hosts: case hosts driven from this process, on real engines.

The runner's tests (test_compare_runner.py, test_fault_processes.py) cover
what a host's crash, timeout or memory limit becomes; these check the pool's
own bookkeeping: answers reach their own futures, a reference comes back as
its solution, a task sent to wait behind one whose host dies or is killed
runs in a new host (and its timeout counts from its own start), and closing
the pool ends every host at once.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from compare.run.hosts import HostPool
from compare.run.isolation import CaseTask, ReferenceTask
from engines.catalog import build
from engines.reference import solve_and_bound


HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # compare_engines, the misbehaving test engine, lives beside this file
    sys.path.insert(0, str(HERE))


def case(engine: str, variant: str, scene, dt: float = 1e-2, timeout: float = 60) -> CaseTask:
    return CaseTask(case_id=f"{engine}/{variant}@{dt}", engine_id=f"{engine}/{variant}", variant=variant, options={},
                    scene=scene, dt=dt, sample_interval=0.05, timeout=timeout)


def run_all(pool: HostPool, tasks) -> list:
    futures = [pool.submit(t) for t in tasks]
    try:
        while not all(f.done() for f in futures):
            pool.wait([f for f in futures if not f.done()])
    finally:
        pool.shutdown()
    return [f.result() for f in futures]


def test_each_answer_reaches_its_own_future_and_closing_ends_every_host():
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(2)
    hosts = pool.hosts
    tasks = [case("mujoco", "hinge", scene), case("pymunk", "pin", scene), case("ours", "baumgarte-rk4", scene),
             case("mujoco", "hinge", scene, dt=1e-3)]
    reference = ReferenceTask("bead", scene, rtol=1e-10, atol=1e-12, timeout=60)
    futures = [pool.submit(t) for t in tasks] + [pool.submit(reference)]
    try:
        while not all(f.done() for f in futures):
            pool.wait([f for f in futures if not f.done()])
    finally:
        pool.shutdown()
    outcomes = [f.result() for f in futures[:-1]]
    assert [o.case_id for o in outcomes] == [t.case_id for t in tasks]
    assert [o.status for o in outcomes] == ["ok"] * 4
    assert [o.trajectory.n_samples for o in outcomes] == [11] * 4
    assert outcomes[3].trajectory.info.steps == 500 and outcomes[0].trajectory.info.steps == 50
    solution, _bound = futures[-1].result()
    expected, _ = solve_and_bound(scene, rtol=1e-10, atol=1e-12)
    times = np.linspace(0, 0.5, 11)
    assert np.array_equal(solution.at(times)[0], expected.at(times)[0])
    # Closed with nothing running, every host saw EOF and exited 0 (none waited for a sibling that held
    # a copy of its request pipe).
    assert [h.process.exitcode for h in hosts] == [0, 0]
    assert pool.hosts == [] and not pool.queue


def test_a_task_waiting_behind_one_whose_host_dies_runs_in_a_new_host():
    # One host, two tasks sent at once: the first kills its host, the second (in that host's pipe,
    # never read) is sent again to a new host and finishes ok; the killer alone is failed.
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(1, depth=2)
    first = pool.hosts[0]
    killer, after = run_all(pool, [case("compare_engines:MISBEHAVING", "kill", scene), case("pymunk", "pin", scene)])
    assert (killer.status, killer.message) == (
        "failed", "the engine's process died (signal SIGKILL) before returning a result")
    assert after.status == "ok" and after.trajectory.n_samples == 11
    assert first.process.exitcode == -9


def test_a_task_waiting_behind_a_timed_out_one_runs_and_its_timeout_counts_from_its_own_start():
    # The sleeper is killed at its 1.5 s timeout; the case behind it had waited that long in the dead
    # host's pipe, yet it runs in a new host and is timed from its start there, not from when it was sent.
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(1, depth=2)
    started = time.perf_counter()
    sleeper, after = run_all(pool, [case("compare_engines:MISBEHAVING", "sleep", scene, timeout=1.5),
                                    case("pymunk", "pin", scene, timeout=1.5)])
    assert sleeper.status == "timeout"
    assert after.status == "ok" and after.elapsed < 1.0 < time.perf_counter() - started
