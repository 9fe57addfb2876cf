"""A case is measured in one place (compare/results/measure.py) and its status decided by one function.

decide_status is walked through every status and every rule; measure() is walked through every status
on real runs of ours (a bead, 0.5 s) against the real reference, with the host's answers the isolation
module gives for a case that timed out, died or raised.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from engines.reference.reference import solve_and_bound
from engines.registry import load_engine
from engines.scene.trajectory import Status

from compare.results.measure import (NO_TRAJECTORY, NON_FINITE, CaseOutcome, CaseStatus, SampledReference,
                                     decide_status, measure)
from compare.results.metrics import Bounds
from compare.results.record import CaseKey
from compare.run.isolation import CaseHost, CaseTask, _failure, died, timed_out
from compare.suite.reader import parse_suite

ROOT = Path(__file__).resolve().parents[1]
OK = CaseStatus(Status.OK, "")


def test_decide_status_walks_every_status_and_rule():
    # 1. skipped wins over everything, with its reason.
    assert decide_status(skipped="pymunk is 2-D", host=CaseStatus(Status.TIMEOUT, "late")) == ("skipped", "pymunk is 2-D")
    # 2. what the host saw, when not ok, is kept: timeout, failed.
    assert decide_status(host=CaseStatus(Status.TIMEOUT, "ran past"), run=OK) == (Status.TIMEOUT, "ran past")
    assert decide_status(host=CaseStatus(Status.FAILED, "died"), run=OK) == (Status.FAILED, "died")
    # 3. the host said ok but no run came back: failed.
    assert decide_status() == (Status.FAILED, NO_TRAJECTORY)
    # 4. the engine's own status when not ok is kept, notes added, bounds and finiteness not consulted.
    assert decide_status(run=CaseStatus(Status.UNSTABLE, "non-finite state at t = 1 s"), finite=False,
                         exceeded=["energy drift 9 E* exceeds the bound 1 E*"], notes=["warnings: x"]) == (
        Status.UNSTABLE, "non-finite state at t = 1 s; warnings: x")
    assert decide_status(run=CaseStatus(Status.FAILED, "ValueError: bad")) == (Status.FAILED, "ValueError: bad")
    # 5. an ok run that is not finite is unstable, before the bounds are read.
    assert decide_status(run=OK, finite=False, exceeded=["past"]) == (Status.UNSTABLE, NON_FINITE)
    # 6. an ok run past a bound is unstable; the reasons replace the engine's message, the notes follow.
    assert decide_status(run=CaseStatus(Status.OK, "engine note"), exceeded=["a", "b"], notes=["", "ref failed"]) == (
        Status.UNSTABLE, "a; b; ref failed")
    # 7. otherwise ok, with the engine's message and the notes.
    assert decide_status(run=CaseStatus(Status.OK, "engine note"), notes=["ref failed"]) == (
        Status.OK, "engine note; ref failed")
    # Every status is reached by some rule.
    reached = {decide_status(skipped="").status, decide_status(host=CaseStatus(Status.TIMEOUT)).status,
               decide_status().status, decide_status(run=OK, finite=False).status, decide_status(run=OK).status}
    assert reached == set(Status)


SUITE = parse_suite("""
duration = 0.5
dt = [2e-3]
[[scenes]]
scene = "bead"
[[engines]]
id = "ours/baumgarte-rk4"
""", str(ROOT / "suites" / "inline.toml"))


@pytest.fixture(scope="module")
def bead():
    """A real run of ours on the bead, the key of its case and the scene's real reference."""
    spec, engine_spec = SUITE.scenes[0], SUITE.engines[0]
    engine, variant = load_engine(engine_spec.id)
    run = engine.simulate(spec.scene, SUITE.dts[0], variant=variant, sample_interval=SUITE.sample_interval)
    assert run.info.status is Status.OK
    key = CaseKey(id="bead|ours|dt=0.002", scene_id=spec.id, scene_name="bead", engine=engine_spec.label,
                  engine_id=engine_spec.id, variant=variant, options={}, dt=SUITE.dts[0])
    return spec.scene, run, key, SampledReference(solve_and_bound(spec.scene, SUITE.rtol, SUITE.atol))


def _task(key: CaseKey, scene) -> CaseTask:
    return CaseTask(case_id=key.id, engine_id=key.engine_id, variant=key.variant, options={}, scene=scene, dt=key.dt,
                    sample_interval=SUITE.sample_interval, repeats=1, timeout=5.0)


def test_measure_walks_every_status_on_real_runs(bead):
    scene, run, key, reference = bead

    def record(outcome, settings=SUITE, **kw):
        return measure(key, scene, outcome, reference, settings, **kw)

    ok = record(CaseOutcome(key.id, run, [run.info.wall_time]))
    assert (ok.status, ok.message) == (Status.OK, "")
    assert ok.metrics["position_error_final"] < 1e-6 and ok.run_info["status"] == "ok"  # 4th order at 2 ms
    assert ok.reference["rtol"] == SUITE.rtol

    tight = replace(SUITE, bounds=Bounds(energy_drift=0.0, constraint_error=0.0))
    bounded = record(CaseOutcome(key.id, run, [run.info.wall_time]), settings=tight)
    assert bounded.status is Status.UNSTABLE and "exceeds the bound 0 E*" in bounded.message

    planted = run.positions.copy()
    planted[-1] = np.nan  # a plug-in that bypasses Engine.simulate hands back NaN and calls it ok
    nan = record(CaseOutcome(key.id, replace(run, positions=planted), [run.info.wall_time]))
    assert (nan.status, nan.message) == (Status.UNSTABLE, NON_FINITE)
    assert len(nan.series["t"]) == run.n_samples - 1  # cut at the first non-finite sample

    blown = replace(run, info=replace(run.info, status="unstable", message="stepping stopped at t = 0.3 s"))
    engine_said = record(CaseOutcome(key.id, blown, [run.info.wall_time]))
    assert (engine_said.status, engine_said.message) == (Status.UNSTABLE, "stepping stopped at t = 0.3 s")

    no_reference = measure(key, scene, CaseOutcome(key.id, run, [run.info.wall_time]), RuntimeError("solver died"),
                           SUITE)
    assert no_reference.status is Status.OK and no_reference.metrics["position_error_final"] is None
    assert no_reference.message == "reference failed (solver died): no reference-based metric"

    task = _task(key, scene)
    late = record(timed_out(task, time.perf_counter()))
    assert late.status is Status.TIMEOUT and late.message.startswith("ran past the timeout of 5 s") and not late.metrics
    raised = record(_failure(task, ValueError("bad input")))
    assert (raised.status, raised.message) == (Status.FAILED, "ValueError: bad input")
    host = CaseHost()
    host.close(kill=True)
    dead = record(died(task, host, time.perf_counter()))
    assert dead.status is Status.FAILED and dead.message.startswith("the engine's process died (")

    skipped = record(None, skipped="the engine is not installed")
    assert (skipped.status, skipped.message, skipped.metrics) == (Status.SKIPPED, "the engine is not installed", {})

    walked = {r.status for r in (ok, bounded, engine_said, late, raised, skipped)}
    assert walked == set(Status)
