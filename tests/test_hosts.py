"""compare.run.hosts: case hosts driven from this process, on real engines.

The runner's tests (test_compare_runner.py, test_fault_processes.py) cover
what a host's crash, timeout or memory limit becomes; these check the pool's
own bookkeeping: answers reach their own futures, a reference comes back as
its solution, and closing the pool ends every host at once.
"""

from __future__ import annotations

import numpy as np

from compare.run.hosts import HostPool
from compare.run.isolation import CaseTask, ReferenceTask
from engines.catalog import build
from engines.reference import solve_and_bound


def case(engine: str, variant: str, scene, dt: float = 1e-2) -> CaseTask:
    return CaseTask(case_id=f"{engine}/{variant}@{dt}", engine_id=f"{engine}/{variant}", variant=variant, options={},
                    scene=scene, dt=dt, sample_interval=0.05, timeout=60)


def test_each_answer_reaches_its_own_future_and_closing_ends_every_host():
    scene = build("bead", {"duration": 0.5})
    pool = HostPool(2)
    hosts = [h for h in pool.idle]
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
    assert pool.idle == [] and pool.busy == {}
