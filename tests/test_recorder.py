"""The one stepping loop (engines.recorder.Recorder): sampling, the stop rule every adapter shares, timing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engines.scene import catalog
from engines.adapter import Schedule
from engines.external.plugin import Engine, Recorder, capabilities, scene_arrays
from engines.recorder import RUNAWAY_LENGTHS, finite_sample, largest_coordinate


class Growing(Engine):
    """A bead integrated as q' = v, v' = λ(q − anchor) (semi-implicit Euler): the state grows like e^{√λ t}.

    λ (1/s²) is chosen so that the pendulum leaves 10⁶ L within the run: the runaway rule must stop it.
    """

    name = "growing"
    capabilities = capabilities(three_d=True)
    variants = {"default": {}}

    def __init__(self, rate: float) -> None:
        self.rate = rate

    def version(self) -> str:
        return "1"

    def _run(self, scene, schedule, settings):
        s = scene_arrays(scene)
        q, v = s.positions.copy(), s.velocities.copy()
        rec = Recorder(scene, schedule)
        rec.record(0, q, v)

        def advance(n: int) -> None:
            for _ in range(n):
                q[:] += schedule.dt * v  # in place: the recorder keeps copies
                v[:] += schedule.dt * self.rate * (q - s.anchors[0])

        rec.run(advance, lambda: (q, v))
        return rec.raw_run()


def test_sample_steps_and_the_steps_taken():
    scene = catalog.build("bead", {"duration": 0.1})
    run = Growing(0.0).simulate(scene, 1e-3, sample_interval=0.02)
    assert run.info.status == "ok" and run.info.steps == 100
    assert np.allclose(run.t, [0, 0.02, 0.04, 0.06, 0.08, 0.1])
    # λ = 0: uniform motion from the initial state, q(t) = q0 + v0 t, and every sample is a copy of its own step
    assert np.allclose(run.positions, scene.initial_positions + run.t[:, None, None] * scene.initial_velocities)
    assert run.info.wall_time >= 0 and run.info.cpu_time >= 0


def test_a_state_that_runs_away_stops_the_run_there_and_keeps_that_sample():
    scene = catalog.build("bead", {"duration": 2.0})
    length = scene.characteristic_length
    run = Growing(2500.0).simulate(scene, 1e-3, sample_interval=0.01)
    assert run.info.status == "unstable"
    limit = RUNAWAY_LENGTHS * length
    assert run.info.message == f"stepping stopped at t = {run.t[-1]:.6g} s: a particle ran {limit:g} m away"
    largest = np.abs(run.positions).max(axis=(1, 2))
    assert largest[-1] > limit and (largest[:-1] <= limit).all()  # the runaway sample is the last one kept
    assert run.info.steps == round(run.t[-1] / 1e-3)
    # x = 0.866 m · cosh(50 t) passes 1e6 m at t = acosh(1.155e6)/50 = 0.2935 s (the semi-implicit Euler step
    # grows by 1.0513 = e^0.05 per step, as the exact flow): the first sample past it is t = 0.30 s
    assert run.t[-1] == pytest.approx(0.30)


def test_a_non_finite_state_stops_the_run_and_is_cut_off():
    scene = catalog.build("bead", {"duration": 1.0})
    schedule = Schedule.make(1.0, 1e-2, 0.1)
    rec = Recorder(scene, schedule)
    q, v = scene.initial_positions, scene.initial_velocities
    assert rec.record(0, q, v)
    assert rec.record(5, q, v)  # not a sample step: ignored
    assert rec.record(10, q, v)
    assert not rec.record(20, q + math.nan, v)
    assert not rec.record(30, q, v)  # after the stop nothing more is kept
    assert len(rec.q_rows) == 3 and rec.last_step == 20 and rec.message == ""
    with pytest.raises(ValueError, match="sample steps come in order; expected step 10, got 20"):
        fresh = Recorder(scene, schedule)
        fresh.record(0, q, v)
        fresh.record(20, q, v)


def test_the_per_sample_checks_see_every_number_of_every_row():
    # What Recorder.record checks at each sample, on the rows engines' APIs give (tuples per particle;
    # pymunk's Vec2d is one) and on arrays.

    def with_value(sample, row, k, value):
        return [tuple(value if (i, j) == (row, k) else c for j, c in enumerate(r)) for i, r in enumerate(sample)]

    x, u = [(0.0, -1.0), (2.0, -0.5)], [(0.1, 0.2), (0.3, 0.4)]
    assert finite_sample(x) and finite_sample(u)
    for row in range(2):
        for k in range(2):
            for big in (5.0, -5.0):  # the largest magnitude wherever it sits, of either sign
                assert largest_coordinate(with_value(x, row, k, big)) == 5.0, (row, k, big)
                assert largest_coordinate(np.array(with_value(x, row, k, big))) == 5.0, (row, k, big)
            for bad in (float("nan"), float("inf"), -float("inf")):
                assert not finite_sample(with_value(x, row, k, bad)), (row, k, bad)
                assert not finite_sample(np.array(with_value(x, row, k, bad))), (row, k, bad)
