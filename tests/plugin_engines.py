"""Plugins that break the engine protocol on purpose, for tests/test_plugins.py (not collected by pytest).

Each returns the reference solution except for the one thing it gets wrong,
so a case that xval did not catch would look perfect.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from engines.external.plugin import Engine, RawRun, Schedule, capabilities
from engines.scene.scene import Scene


def _reference(scene: Scene, schedule: Schedule) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from engines.reference.reference import solve

    return solve(scene).at(schedule.times)


class _Base(Engine):
    api_version = 1
    capabilities = capabilities(three_d=True, constraint_forces=True)
    variants = {"default": {}}

    def version(self) -> str:
        return "test 1"


class FlatPositions(_Base):
    """positions without the particle axis: (n, 3) instead of (n, P, 3)."""

    name = "flat-positions"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        return RawRun(q[:, 0, :], v, f, steps=schedule.n_steps, wall_time=0.0)


class TooManySamples(_Base):
    """one sample per step instead of per scheduled sample."""

    name = "too-many-samples"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        q, v, f = (np.repeat(a, 3, axis=0) for a in (q, v, f))
        return RawRun(q, v, f, steps=schedule.n_steps, wall_time=0.0)


class WrongForces(_Base):
    """forces per particle (n, P, 3) on a scene with a different number of constraints."""

    name = "wrong-forces"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        return RawRun(q, v, np.zeros((len(q), len(scene.constraints) + 1, 3)), steps=schedule.n_steps, wall_time=0.0)


class Millimetres(_Base):
    """positions in millimetres."""

    name = "millimetres"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        return RawRun(1e3 * q, v, f, steps=schedule.n_steps, wall_time=0.0)


class Nanoseconds(_Base):
    """wall time in nanoseconds."""

    name = "nanoseconds"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        return RawRun(q, v, f, steps=schedule.n_steps, wall_time=5e8)


class NaNHalfway(_Base):
    """NaN positions from halfway."""

    name = "nan-halfway"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        q[len(q) // 2:] = np.nan
        return RawRun(q, v, f, steps=schedule.n_steps, wall_time=0.0)


class RaisesWhileBuilding(_Base):
    """raises before stepping (a model it cannot build)."""

    name = "raises"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        raise ValueError("cannot build a model with 1 particle")


class OldProtocol(_Base):
    """written for a protocol version this xval does not speak."""

    name = "old-protocol"
    api_version = 0

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        raise AssertionError("an adapter with an unsupported api_version must never run")


class FutureProtocol(OldProtocol):
    name = "future-protocol"
    api_version = 99


class Exact(_Base):
    """the reference itself: a plugin that follows the protocol, loaded as a class (not an instance)."""

    name = "exact"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        q, v, f = _reference(scene, schedule)
        return RawRun(q, v, f, steps=schedule.n_steps, wall_time=0.0)


FLAT_POSITIONS = FlatPositions()
TOO_MANY_SAMPLES = TooManySamples()
WRONG_FORCES = WrongForces()
MILLIMETRES = Millimetres()
NANOSECONDS = Nanoseconds()
NAN_HALFWAY = NaNHalfway()
RAISES = RaisesWhileBuilding()
OLD_PROTOCOL = OldProtocol()
FUTURE_PROTOCOL = FutureProtocol()
EXACT_CLASS = Exact
NOT_AN_ENGINE = 42
