"""The one stepping loop of every adapter: sampling, runaway detection, timing.

:meth:`Recorder.run` steps an engine from sample to sample (``advance(n)``
timed, ``read()`` not) and stores each sample; an engine that steps in
batches (MuJoCo's rollout) times its batches with :meth:`Recorder.stepping`
and hands the samples over with :meth:`Recorder.record`. Either way one rule
decides when a run stops (:data:`RUNAWAY_LENGTHS`): a non-finite sample, or a
coordinate farther than RUNAWAY_LENGTHS·L from the origin. Both samples are
kept; the adapter protocol (engines.adapter) cuts a non-finite one off and
marks the run ``unstable``; a runaway sample is finite, what the engine
computed, so it stays, and the run is ``unstable`` with the message. Timing
counts only what runs inside ``advance`` / ``stepping()``, minus ``paused()``:
wall time (``perf_counter``) and this thread's CPU time (``thread_time``).
"""

from __future__ import annotations

import itertools
import math
import time
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from engines.adapter import RawRun, Schedule
from engines.scene.pendulum import force_array
from engines.scene.scene import Scene

#: A coordinate this many characteristic lengths L from the origin has run away: stepping stops there.
RUNAWAY_LENGTHS = 1e6


def finite_sample(rows: Any) -> bool:
    """Whether every number of one sample is finite: an array, or per-particle coordinate tuples (as an
    engine's Python API gives them; the loop runs in C, ``map`` over the flattened tuples)."""
    if isinstance(rows, np.ndarray):
        return bool(np.isfinite(rows).all())
    return all(map(math.isfinite, itertools.chain.from_iterable(rows)))


def largest_coordinate(rows: Any) -> float:
    """The largest |coordinate| of one sample (as :func:`finite_sample` takes it), m."""
    if isinstance(rows, np.ndarray):
        return float(np.abs(rows).max(initial=0.0))
    return max(map(abs, itertools.chain.from_iterable(rows)), default=0.0)


class Recorder:
    """Steps, samples at ``schedule.sample_steps``, stops a run that runs away, and times the stepping.

    The loop, for an engine that steps in Python (PyBullet, pymunk, a plugin)::

        rec = Recorder(scene, schedule, forces=True)
        rec.record(0, q, v, f)                 # the initial state (f: the t = 0 forces, or None)
        rec.run(advance, read)                 # advance(n): take n steps (timed); read() -> (q, v[, f])
        return rec.raw_run()

    or written out, ``with rec.stepping(): ... if rec.wants(step): with rec.paused():
    if not rec.record(step, q, v, f): break``.

    q, v : one sample, (P, k) m, m/s: an array, or the per-particle coordinate
    tuples an engine's API gives (kept as they are until :meth:`samples`).
    f : (C, 3) N on each constraint's first particle, ``{k: (3,)}`` for the
    constraints reported, or anything an adapter turns into forces itself
    (:meth:`raw_run`'s ``forces``); not reported (None, absent, NaN) stays NaN.
    """

    def __init__(self, scene: Scene, schedule: Schedule, *, forces: bool = False) -> None:
        self.schedule = schedule
        self.steps: list[int] = schedule.sample_steps.tolist()
        self._index = {step: k for k, step in enumerate(self.steps)}
        self.n_constraints = len(scene.constraints)
        self.forces = forces
        #: m: a sample with a coordinate beyond this has run away.
        self.limit = RUNAWAY_LENGTHS * scene.characteristic_length
        self.q_rows: list[Any] = []
        self.v_rows: list[Any] = []
        self.f_rows: list[Any] = []
        self.last_step = 0
        self.stopped = False
        self.message = ""
        self.wall_time = 0.0  # s
        self.cpu_time = 0.0  # s

    # -- sampling --

    def wants(self, step: int) -> bool:
        """True when ``step`` is a sample step."""
        return step in self._index

    def record(self, step: int, q: Any, v: Any, f: Any = None) -> bool:
        """Store the sample after ``step`` steps; False when stepping must stop (the run is over).

        Steps that are not sample steps are ignored. Samples come in order.
        """
        if self.stopped:
            return False
        k = self._index.get(step)
        if k is None:
            return True
        if isinstance(q, np.ndarray):  # a copy: the caller may step its arrays in place
            q, v = np.array(q, dtype=float), np.array(v, dtype=float)
        if isinstance(f, np.ndarray):
            f = np.array(f, dtype=float)
        if k != len(self.q_rows):
            expected = self.steps[len(self.q_rows)] if len(self.q_rows) < len(self.steps) else None
            raise ValueError(f"Recorder.record: sample steps come in order; expected step {expected}, got {step}")
        self.q_rows.append(q)
        self.v_rows.append(v)
        self.f_rows.append(f)
        self.last_step = step
        if not (finite_sample(q) and finite_sample(v)):
            self.stopped = True  # engines.adapter cuts the run before this sample: "non-finite state at t = …"
        elif largest_coordinate(q) > self.limit:
            self.stopped = True
            self.message = (f"stepping stopped at t = {step * self.schedule.dt:.6g} s: a particle ran "
                            f"{self.limit:g} m away")
        return not self.stopped

    def run(self, advance: Callable[[int], Any], read: Callable[[], Sequence[Any]], *, taken: int = 0) -> None:
        """The stepping loop: to each sample step not yet recorded, ``advance(n)`` then ``record(*read())``.

        taken : steps the engine has already taken (after sample 0); stops early when :meth:`record` says so.
        """
        perf, cpu = time.perf_counter, time.thread_time
        steps = self.steps
        for k in range(len(self.q_rows), len(steps)):
            started, cpu_started = perf(), cpu()
            advance(steps[k] - taken)
            self.cpu_time += cpu() - cpu_started
            self.wall_time += perf() - started
            taken = steps[k]
            if not self.record(taken, *read()):
                break

    # -- timing --

    def stepping(self) -> "_Clock":
        """A context whose wall and CPU time (s) count as stepping."""
        return _Clock(self, +1)

    def paused(self) -> "_Clock":
        """A context, inside ``stepping()`` or ``advance``, whose time is not stepping (reading a state)."""
        return _Clock(self, -1)

    # -- results --

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """(n, P, k) positions and velocities recorded, float64, as the engine gave them (its frame); each its
        own shape (a model's q and v differ in size with a floating base: 7 + n against 6 + n)."""
        n = len(self.q_rows)

        def stacked(rows: list) -> np.ndarray:
            return np.array(rows, dtype=float).reshape((n, *np.shape(rows[0])) if n else (0, 0, 3))

        return stacked(self.q_rows), stacked(self.v_rows)

    def force_samples(self) -> np.ndarray:
        """(n, C, 3) N from the forces recorded: arrays as given, a mapping's missing rows and None NaN."""
        out = np.full((len(self.f_rows), self.n_constraints, 3), np.nan)
        for k, f in enumerate(self.f_rows):
            if isinstance(f, Mapping):
                out[k] = force_array(self.n_constraints, f)
            elif f is not None:
                out[k] = f
        return out

    def raw_run(self, *, positions: np.ndarray | None = None, velocities: np.ndarray | None = None,
                forces: np.ndarray | None = None, steps: int | None = None, message: str = "",
                settings: Mapping[str, Any] | None = None) -> RawRun:
        """The RawRun of the samples recorded (steps taken = the last recorded step).

        positions, velocities, forces : (n, ·, 3) in the scene frame when the adapter converted them
        (from :meth:`samples`, its own frame); by default the samples as recorded, and the forces
        recorded when the Recorder was made with ``forces=True`` (else None).
        steps : the steps taken, when the engine took more than the last recorded sample's.
        """
        if positions is None or velocities is None:
            q, v = self.samples()
            positions = q if positions is None else positions
            velocities = v if velocities is None else velocities
        if forces is None and self.forces:
            forces = self.force_samples()
        message = "; ".join(m for m in (self.message, message) if m)
        return RawRun(positions, velocities, forces, steps=self.last_step if steps is None else steps, wall_time=self.wall_time,
                      message=message, settings=dict(settings or {}), cpu_time=self.cpu_time)


class _Clock:
    def __init__(self, recorder: Recorder, sign: int) -> None:
        self.recorder, self.sign = recorder, sign

    def __enter__(self) -> None:
        self.started, self.cpu_started = time.perf_counter(), time.thread_time()

    def __exit__(self, *exc: Any) -> None:
        self.recorder.cpu_time += self.sign * (time.thread_time() - self.cpu_started)
        self.recorder.wall_time += self.sign * (time.perf_counter() - self.started)
