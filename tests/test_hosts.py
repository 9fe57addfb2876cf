"""compare.run.hosts: case hosts driven from this process, on real engines.

The runner's tests (test_compare_runner.py, test_fault_processes.py) cover
what a host's crash, timeout or memory limit becomes; these check the pool's
own bookkeeping: answers reach their own futures, a reference comes back as
its solution, a task sent to wait behind one whose host dies or is killed
runs in a new host (and its timeout counts from its own start), and closing
the pool ends every host at once.
"""

from __future__ import annotations

import gc
from dataclasses import replace
import pickle

import numpy as np

from compare.run.hosts import PIPELINED_BYTES, HostPool
from compare.run.isolation import _DRIVER_ENDS, CaseHost, CaseTask, ReferenceTask, send
from engines.adapter import scheduled_times
from engines.scene.catalog import build
from engines.reference.reference import solve_and_bound

from compare_engines import PAUSE


def case(engine: str, variant: str, scene, dt: float = 1e-2, timeout: float = 60) -> CaseTask:
    return CaseTask(case_id=f"{engine}/{variant}@{dt}", engine_id=f"{engine}/{variant}", variant=variant, options={},
                    scene=scene, dt=dt, sample_interval=0.05, timeout=timeout)


def run_all(pool: HostPool, tasks, waiting_behind: int | None = None) -> list:
    """Every task's answer, in order. waiting_behind: how many tasks the first host must hold once
    the first tasks are sent (the one it runs and those sent to wait behind it)."""
    futures = [pool.submit(t) for t in tasks]
    try:
        if waiting_behind is not None:
            pool._send_queued()
            assert len(pool.slots[0].jobs) == waiting_behind
        while not all(f.done() for f in futures):
            pool.wait([f for f in futures if not f.done()])
    finally:
        pool.shutdown(kill=True)  # a host still busy (an assertion failed) is killed, by its process group
    return [f.result() for f in futures]


def test_each_answer_reaches_its_own_future_and_closing_ends_every_host():
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(2)
    hosts = pool.hosts
    tasks = [case("mujoco", "hinge", scene), case("pymunk", "pin", scene), case("ours", "baumgarte-rk4", scene),
             case("mujoco", "hinge", scene, dt=1e-3)]
    reference = ReferenceTask("bead", scene, rtol=1e-10, atol=1e-12, timeout=60)
    *outcomes, (solution, _bound) = run_all(pool, tasks + [reference])
    assert [o.case_id for o in outcomes] == [t.case_id for t in tasks]
    assert [o.status for o in outcomes] == ["ok"] * 4
    assert [o.trajectory.n_samples for o in outcomes] == [11] * 4
    assert outcomes[3].trajectory.info.steps == 500 and outcomes[0].trajectory.info.steps == 50
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
    killer, after = run_all(pool, [case("compare_engines:MISBEHAVING", "kill", scene), case("pymunk", "pin", scene)],
                            waiting_behind=2)
    assert (killer.status, killer.message) == (
        "failed", "the engine's process died (signal SIGKILL) before returning a result")
    assert after.status == "ok" and after.trajectory.n_samples == 11
    assert first.process.exitcode == -9


def test_a_task_waiting_behind_a_timed_out_one_runs_and_its_timeout_counts_from_its_own_start():
    # The sleeper is killed at its 6 s timeout; the case behind it had waited that long in the dead
    # host's pipe, yet it runs in a new host and is timed from its start there, not from when it was sent
    # (its 4 s would have run out). 4 s is ~10x what the pymunk case needs: load alone does not time it out.
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(1, depth=2)
    sleeper, after = run_all(pool, [case("compare_engines:MISBEHAVING", "sleep", scene, timeout=6.0),
                                    case("pymunk", "pin", scene, timeout=4.0)], waiting_behind=2)
    assert sleeper.status == "timeout"
    assert after.status == "ok", after.message


def test_a_task_waiting_behind_one_that_answers_is_timed_from_when_its_host_takes_it():
    # The first case takes PAUSE (6 s) and answers ok; the one sent behind it has a 4 s timeout, which
    # would have run out while it waited if its clock started when it was sent. 4 s is ~10x what the
    # 0.5 s pymunk case needs on an idle machine: a loaded one does not make it time out on its own.
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(1, depth=2)
    paused, after = run_all(pool, [case("compare_engines:MISBEHAVING", "pause", scene, timeout=30),
                                   case("pymunk", "pin", scene, timeout=4.0)], waiting_behind=2)
    assert paused.status == "ok" and paused.elapsed >= PAUSE
    assert after.status == "ok", after.message


def test_a_task_bigger_than_a_pipe_page_waits_for_an_idle_host():
    # Written into the pipe of a host busy with a 1.5 s case, a task bigger than the pipe would block
    # the driver while the host blocks writing its answer: it is held back until the host is idle.
    scene = build("bead", {"duration": 0.5})
    big = case("pymunk", "pin", scene)
    big = CaseTask(**{**big.__dict__, "case_id": "x" * PIPELINED_BYTES})  # as big as a long chain's task
    assert len(pickle.dumps(big)) > PIPELINED_BYTES
    paused, after = run_all(HostPool(1, depth=2), [case("compare_engines:MISBEHAVING", "pause", scene), big],
                            waiting_behind=1)
    assert paused.status == "ok"
    assert after.case_id == big.case_id and after.status == "ok", after.message


def test_a_reference_task_stays_small_and_its_samples_are_the_runs_sample_times(tmp_path, monkeypatch):
    # A reference task names the dts, not the 100,001 times of this 100 s scene sampled every 1 ms
    # (so it is small enough to wait in a busy host's pipe), and the host rebuilds exactly the times
    # the runner samples the cases at.
    monkeypatch.setenv("XVAL_CACHE_DIR", str(tmp_path))
    scene = build("bead", {"duration": 100.0})
    dts = (1e-3, 1e-2)
    task = ReferenceTask("bead", scene, rtol=1e-6, atol=1e-8, timeout=120, sample_dts=dts, sample_interval=1e-3)
    assert len(pickle.dumps(task)) <= PIPELINED_BYTES
    solution, _bound = run_all(HostPool(1), [task])[0]
    assert set(solution.samples) == {scheduled_times(100.0, dt, 1e-3).tobytes() for dt in dts}
    assert len(scheduled_times(100.0, 1e-3, 1e-3)) == 100_001


def test_a_run_forks_no_more_hosts_than_it_has_tasks():
    # Four cases of two scenes asked to run on 16 jobs: six hosts (a case each and a reference per
    # scene), not sixteen; one case left of one scene (a --resume): two.
    from compare.run.runner import _Dispatcher, plan
    from compare.suite.reader import parse_suite

    suite = parse_suite('duration = 0.1\ndt = [1e-2, 5e-3]\n[[scenes]]\nscene = "bead"\n'
                        '[[scenes]]\nscene = "double-pendulum"\n[[engines]]\nid = "pymunk/pin"\n')
    cases = plan(suite)
    assert len(cases) == 4
    for todo, hosts in ((cases, 6), (cases[:1], 2)):
        dispatcher = _Dispatcher(suite, todo, writer=None, jobs=16, executor=None, timeout=20, isolate=True)
        try:
            assert dispatcher.jobs == hosts and len(dispatcher.pool.hosts) == hosts
        finally:
            dispatcher.pool.shutdown()
            gc.unfreeze()  # what preload_engines froze (run_suite unfreezes it as a run ends)


def test_a_dead_host_is_closed_before_a_new_one_takes_its_task():
    # Its pipe ends are this process's (held in _DRIVER_ENDS so forks can close them): they must be
    # closed and let go of, not leaked with the dead host.
    host = CaseHost()
    host.process.kill()
    host.process.join()
    task = case("pymunk", "pin", build("bead", {"duration": 0.1}))
    new = send(host, task)
    try:
        assert new is not host and host.requests.closed and host.replies.closed
        assert not {host.requests, host.replies} & _DRIVER_ENDS
        outcome, _exiting = new.replies.recv()
        assert outcome.status == "ok"
    finally:
        new.close()


def test_a_case_run_without_a_host_is_warmed_up_first_as_in_a_host():
    # isolate=False (a pool's worker or this thread runs the engine): the variant's two-step warm-up
    # runs before its first case, as _run_in_host does, so its one-off costs are not timed as stepping.
    from compare.run import isolation

    task = replace(case("pymunk", "pin", build("bead", {"duration": 0.1})), isolate=False)
    isolation._WARM.discard(task.engine_id)
    outcome = isolation.execute(task)
    assert outcome.status == "ok" and outcome.trajectory.info.status == "ok"
    assert task.engine_id in isolation._WARM
