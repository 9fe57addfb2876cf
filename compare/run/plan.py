"""A suite's cases: every scene × engine variant × dt (or tolerance), their ids, what a case's record is
keyed by, and which of them cannot run here (skipped, with the reason) or are too big to run at all.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from engines.errors import Unsupported
from engines.scene.limits import check_case_size
from engines.scene.scene import SceneLike

from compare.results.record import CaseKey
from compare.results.store import jsonable
from compare.suite.reader import EngineSpec, SceneSpec, Suite
from compare.suite.tolerance_axis import tolerance_options, with_tolerance


@dataclass(frozen=True)
class Case:
    """One scene × engine variant × dt of a suite; ``position`` is its (scene, engine, dt) index in the suite."""

    scene: SceneSpec
    engine: EngineSpec
    dt: float
    position: tuple[int, int, int] = (0, 0, 0)
    #: On the tolerance axis: the tolerance (already in ``engine.options``); dt is then the largest step.
    tolerance: float | None = None

    @property
    def id(self) -> str:
        return case_id(self.scene.id, self.engine.label, self.dt, self.tolerance)


def case_id(scene_id: str, engine_label: str, dt: float, tolerance: float | None = None) -> str:
    """``bead|mujoco/hinge-rk4|dt=0.001`` (``…|dt=0.01|tol=1e-06`` on the tolerance axis):
    stable across runs, the key ``--resume`` matches on."""
    tail = "" if tolerance is None else f"|tol={tolerance:.12g}"
    return f"{scene_id}|{engine_label}|dt={dt:.12g}{tail}"


def plan(suite: Suite) -> list[Case]:
    """Every case of the suite, scene-major, in the suite's order.

    A variant that takes a tolerance gets one case per suite tolerance instead of one per dt
    (compare/suite/tolerance_axis.py), when the suite sweeps one.
    """
    cases = []
    for i, s in enumerate(suite.scenes):
        for j, e in enumerate(suite.engines):
            names = tolerance_options(e.engine, e.variant, e.options) if suite.tolerances else ()
            if names:
                cases += [Case(s, replace(e, options=with_tolerance(e.options, names, tol)), suite.sample_interval,
                               (i, j, k), tol) for k, tol in enumerate(suite.tolerances)]
            else:
                cases += [Case(s, e, dt, (i, j, k)) for k, dt in enumerate(suite.dts)]
    return cases


def skip_reason(scene: SceneLike, engine: EngineSpec) -> str | None:
    """Why ``engine`` cannot run ``scene`` (unavailable here, or cannot express it), or None."""
    if engine.engine is None:
        return engine.unavailable
    try:
        engine.engine.check(scene, engine.variant, engine.options)
    except Unsupported as exc:
        return str(exc)
    return None


def check_sizes(suite: Suite) -> None:
    """UserError naming the scene and dt of the first case too big to run (engines/scene/limits.py)."""
    for spec in suite.scenes:
        for dt in suite.dts:
            check_case_size(len(spec.scene.particles), spec.scene.duration, dt, suite.sample_interval,
                            where=f"{suite.path}: scene {spec.id!r}")


def key_of(case: Case) -> CaseKey:
    """The record's key of ``case`` (JSON-ready options)."""
    return CaseKey(
        id=case.id, scene_id=case.scene.id, scene_name=case.scene.name, engine=case.engine.label,
        engine_id=case.engine.id, variant=case.engine.variant, options=jsonable(dict(case.engine.options)),
        dt=float(case.dt), position=tuple(int(i) for i in case.position), tolerance=case.tolerance,
    )
