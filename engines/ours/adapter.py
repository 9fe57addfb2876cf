"""Adapter for ``ours``, the project's own constrained-dynamics solver.

Variants are ``<method>-<integrator>`` (``baumgarte-rk4``, ``plain-euler``,
``projection-symplectic-euler``, ``lagrangian-rk4``, …) plus ``rattle``, which
is its own integrator; every pair ``ours.valid_pairs()`` accepts has one.

Details: docs/engines.md, "Adapter notes", ``engines/ours/adapter.py``.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

import ours
from engines.adapter import Engine, Option, RawRun, Schedule
from engines.errors import Unsupported, UserError
from engines.model.stepping import run_model
from engines.scene.scene import Ellipse, Line, Pin, Rod, Scene, ModelSceneLike

_INTEGRATOR_ORDER = ("rk4", "midpoint", "symplectic-euler", "euler")


def _variants() -> dict[str, dict[str, Any]]:
    pairs = set(ours.valid_pairs())
    variants: dict[str, dict[str, Any]] = {"baumgarte-rk4": {"method": "baumgarte", "integrator": "rk4"}}
    for method in ("baumgarte", "plain", "projection", "lagrangian"):
        for integrator in _INTEGRATOR_ORDER:
            if (method, integrator) in pairs:
                variants.setdefault(f"{method}-{integrator}", {"method": method, "integrator": integrator})
    variants["rattle"] = {"method": "rattle", "integrator": "rattle"}
    return variants


def _to_system(scene: Scene) -> tuple[ours.System, np.ndarray, np.ndarray, list[int]]:
    """ours' System, q0, v0 and the scene axes it uses ([0, 2] for planar scenes, else [0, 1, 2])."""
    axes = [0, 2] if scene.is_planar else [0, 1, 2]
    constraints = []
    for c in scene.constraints:
        if isinstance(c, Pin):
            constraints.append(ours.Pin(c.particle, tuple(np.asarray(c.anchor)[axes]), c.length))
        elif isinstance(c, Rod):
            constraints.append(ours.Rod(c.a, c.b, c.length))
        elif isinstance(c, Line) and len(axes) == 2:
            constraints.append(ours.Line(c.particle, tuple(np.asarray(c.point)[axes]),
                                         tuple(np.asarray(c.direction)[axes])))
        elif isinstance(c, Ellipse) and len(axes) == 2:
            constraints.append(ours.Ellipse(c.particle, tuple(np.asarray(c.centre)[axes]), (c.semi_x, c.semi_z)))
        else:  # pragma: no cover - a new scene kind must be mapped here first
            raise Unsupported(f"ours has no constraint for scene kind {c.kind!r}")
    system = ours.System(tuple(scene.masses), tuple(np.asarray(scene.gravity)[axes]), tuple(constraints))
    q0 = scene.initial_positions[:, axes]
    v0 = scene.initial_velocities[:, axes]
    return system, q0, v0, axes


_compile_seconds: float | None = None


def _ensure_compiled() -> float:
    """Compile ours' loops (or load them from numba's cache) once per process; the seconds it took."""
    global _compile_seconds
    if _compile_seconds is None:
        _compile_seconds = ours.compile_all()
    return _compile_seconds


class OursEngine(Engine):
    name = "ours"
    capabilities = frozenset({"3d", "constraint-forces", "model"})
    options = {
        "method": Option("method", "baumgarte", "drift cure: plain, baumgarte, projection, rattle or lagrangian",
                         kind="str", choices=tuple(ours.METHODS)),
        "integrator": Option("integrator", "rk4", "euler, symplectic-euler, midpoint, rk4 or rattle",
                             kind="str", choices=tuple(ours.INTEGRATORS)),
        "k_s": Option("k_s", ours.DEFAULT_K_S,
                      "Baumgarte stiffness, 1/s² (default 100: a 0.1 s correction time constant)", low=0.0, high=1e12),
        "k_d": Option("k_d", None, "Baumgarte damping, 1/s (default 2·sqrt(k_s), critical damping)",
                      low=0.0, high=1e6),
        "tolerance": Option("tolerance", 1e-12,
                            "projection / RATTLE solve: stop at max |C|/l² ≤ tolerance (relative length error)",
                            low=0.0, high=1.0, low_open=True),
        "max_iterations": Option("max_iterations", 50, "most Newton / SHAKE iterations per step", kind="int",
                                 low=1, high=10_000),
    }
    variants = _variants()
    variant_docs = {
        name: f"{ours.METHODS[v['method']].doc} Integrator: {ours.INTEGRATORS[v['integrator']].doc}"
        for name, v in variants.items()
    }
    overrides = {}

    def version(self) -> str:
        return ours.__version__

    def preload(self, scenes) -> None:
        """Compile, or load from numba's cache, the kernels these scenes will use, in this process.

        A runner calls it before it forks its workers, which then inherit the loaded machine code
        instead of each loading it again. A scene ours cannot express is passed over (its cases say why).
        """
        _ensure_compiled()
        for scene in scenes:
            if scene.is_model:  # rigid bodies: compiled when their run is set up
                continue
            try:
                system, q0, v0, _ = _to_system(scene)
                ours.simulate(system, q0, v0, 1e-3, 1, method="baumgarte")
                if system.dim == 2 and system.why_not_a_chain() is None:
                    ours.simulate(system, q0, v0, 1e-3, 1, method="lagrangian")
            except (Unsupported, ours.OursError):
                continue

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        from engines.ours.model import OursStepper  # for cost: ours' rigid bodies load only for a model scene

        return run_model(scene, schedule, OursStepper(scene, schedule.dt, settings["method"], settings["integrator"], k_s=settings["k_s"],
                                                      k_d=settings["k_d"], tolerance=settings["tolerance"],
                                                      max_iterations=settings["max_iterations"]))

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        """A model file: ours' rigid bodies (engines/ours/model.py) with the variant's method and integrator."""
        from ours.rigid.method import resolve as rigid_pair

        try:
            rigid_pair(settings["method"], settings["integrator"])
        except ours.OursError as exc:
            raise Unsupported(f"ours: {exc}") from None
        scene.refuse_kept_dynamics(self.name)

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        try:
            ours.resolve_pair(settings["method"], settings["integrator"])
        except ours.InvalidPair as exc:
            raise UserError(f"ours: {exc}") from None
        curves = [c.kind for c in scene.constraints if isinstance(c, (Line, Ellipse))]
        if curves and not scene.is_planar:
            raise Unsupported(
                f"ours' Line and Ellipse are planar (2-D) constraints; {scene.name!r} moves in 3-D"
            )
        if settings["method"] == "lagrangian":
            if not scene.is_planar:
                raise Unsupported(
                    f"ours/lagrangian uses the link angles of a planar chain; {scene.name!r} moves in 3-D"
                )
            why = _to_system(scene)[0].why_not_a_chain()
            if why is not None:
                raise Unsupported(
                    f"ours/lagrangian needs a chain hung from a fixed point (Pin on particle 0, then "
                    f"Rod(k-1, k)); {scene.name!r} is not one: {why}"
                )

    def _baumgarte_gains(self, variant: str | None, options: Mapping[str, Any] | None) -> tuple[str, float, float] | None:
        """(integrator, k_s 1/s², k_d 1/s) of a Baumgarte variant its linear theory covers, else None."""
        from ours.stability import INTEGRATORS

        settings = self.resolve(variant, options)
        if settings["method"] != "baumgarte" or settings["integrator"] not in INTEGRATORS:
            return None
        k_s = float(settings["k_s"])
        k_d = 2.0 * k_s ** 0.5 if settings["k_d"] is None else float(settings["k_d"])
        return settings["integrator"], k_s, k_d

    def spectral_radius(self, variant: str | None, options: Mapping[str, Any] | None, dt: float) -> float | None:
        """ρ of one step of the linearized constraint error (C, Ċ) under Baumgarte feedback (ours/stability.py)."""
        from ours.stability import spectral_radius

        gains = self._baumgarte_gains(variant, options)
        return None if gains is None else spectral_radius(gains[0], dt, gains[1], gains[2])

    def largest_stable_dt(self, variant: str | None, options: Mapping[str, Any] | None) -> float | None:
        """s: the largest dt with ρ ≤ 1 for a Baumgarte variant (None for other methods)."""
        from ours.stability import largest_stable_dt

        gains = self._baumgarte_gains(variant, options)
        return None if gains is None else largest_stable_dt(*gains)

    def jacobian(self, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                 wrt: list[str]) -> tuple[Any, ...] | None:
        """Forward sensitivities by ours' tangent-linear step for every parameter, with J at every sample as well
        (engines/ours/gradients.py)."""
        from engines.ours import gradients

        return gradients.jacobian(self, scene, variant, options, dt, wrt, _to_system)

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        system, q0, v0, axes = _to_system(scene)
        compile_seconds = _ensure_compiled()  # before the clock starts: wall_time is stepping alone
        result = ours.simulate(
            system, q0, v0, schedule.dt, schedule.n_steps, schedule.stride,
            method=settings["method"], integrator=settings["integrator"],
            k_s=settings["k_s"], k_d=settings["k_d"],
            tolerance=settings["tolerance"], max_iterations=settings["max_iterations"],
        )
        n = len(result.t)
        positions = np.zeros((n, system.n_particles, 3))
        velocities = np.zeros_like(positions)
        forces = np.zeros((n, system.n_constraints, 3))
        positions[:, :, axes] = result.q
        velocities[:, :, axes] = result.v
        forces[:, :, axes] = result.forces
        return RawRun(
            positions, velocities, forces, result.steps, result.wall_time, message=result.message,
            settings={**{f"ours.{k}": v for k, v in result.settings.items()},
                      "ours.frame": "2-D (scene x, z)" if len(axes) == 2 else "3-D",
                      "ours.compile_or_cache_load_s": round(compile_seconds, 3)},
        )


ENGINE = OursEngine()
