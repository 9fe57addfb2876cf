"""Baumgarte gain map: ours/baumgarte on one scene over a log-spaced k_s × k_d grid, with the theory's boundary.

Theory (derived in docs/ours.md, "Stability of the Baumgarte feedback"):
near the constraint manifold the constraint error x = (C, Ċ) obeys the
linear system ẋ = A x, A = [[0, 1], [−k_s, −k_d]] (eigenvalues
λ = (−k_d ± √(k_d² − 4 k_s))/2), plus forcing from the motion that does
not change stability. One step of an explicit Runge–Kutta method maps x to
R(hA) x, R the method's stability polynomial (R(z) = 1 + Σⱼ zʲ bᵀAʲ⁻¹𝟙 from
its Butcher table, so the theory uses exactly the table ours steps with);
symplectic Euler (kick, then drift with the new velocity) maps it to
M = [[1 − h²k_s, h(1 − h k_d)], [−h k_s, 1 − h k_d]]. The feedback is
stable when the spectral radius ρ of that step matrix is ≤ 1.

Measured, per cell: the run's status under the suite's bounds (as in
``xval run``), constraint error (m) and energy drift (E*). A cell whose ρ is
only slightly above 1 may stay inside the bounds for the run's duration
(ρⁿ must lift a tiny C past the bound): the theory line is the asymptotic
boundary, the measured one lies a little outside it.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from compare.results.store import now
from compare.run.runner import default_jobs
from compare.stability.search import check_output, document_head, load_document, run_probe, suite_table, write_document
from compare.suite.reader import EngineSpec, Suite, geometric_sweep, load_engine

FILE_NAME = "gainmap.json"
SCHEMA = "xval-gainmap"
SCHEMA_VERSION = 1
#: Integrators the theory covers (RATTLE is not a Baumgarte integrator).
INTEGRATORS = ("euler", "symplectic-euler", "midpoint", "rk4")
GAINMAP_KEYS = ("scene", "integrators", "dt", "k_s", "k_d", "theory_points", "sample_interval")
#: ρ ≤ 1 + this counts as stable (round-off; small enough that undamped Euler, ρ = 1 + (ωh)²/2, is unstable at h = 1e-4/ω).
RHO_SLACK = 1e-12


# -- theory ----------------------------------------------------------------------------------


def stability_polynomial(integrator: str) -> np.ndarray:
    """Coefficients c₀..c_s (ascending powers of z) of R(z) for an explicit RK integrator of ours.

    R(z) = 1 + Σ_{j≥1} zʲ · bᵀ A^{j−1} 𝟙 (A strictly lower triangular, so the sum stops at j = stages).
    """
    from ours.integrator import EXPLICIT_RK, get_integrator

    scheme = get_integrator(integrator)
    if scheme.code != EXPLICIT_RK:
        raise ValueError(f"{integrator} is not an explicit Runge–Kutta method")
    ones = np.ones(scheme.stages)
    coefficients = [1.0]
    power = ones
    for _ in range(scheme.stages):
        coefficients.append(float(scheme.b @ power))
        power = scheme.A @ power
    return np.array(coefficients)


def step_matrix(integrator: str, h: float, k_s: float, k_d: float) -> np.ndarray:
    """(2, 2): one step of the linearized constraint error (C, Ċ) under ``integrator`` with step h (s).

    k_s : 1/s², k_d : 1/s.
    """
    if integrator == "symplectic-euler":
        return np.array([[1.0 - h * h * k_s, h * (1.0 - h * k_d)], [-h * k_s, 1.0 - h * k_d]])
    hA = h * np.array([[0.0, 1.0], [-k_s, -k_d]])
    result, power = np.zeros((2, 2)), np.eye(2)
    for c in stability_polynomial(integrator):
        result += c * power
        power = power @ hA
    return result


def spectral_radius(integrator: str, h: float, k_s: float, k_d: float) -> float:
    """ρ of :func:`step_matrix`: the factor the constraint error grows by per step (asymptotically)."""
    return float(np.abs(np.linalg.eigvals(step_matrix(integrator, h, k_s, k_d))).max())


def theory_stable(integrator: str, h: float, k_s: float, k_d: float) -> bool:
    return spectral_radius(integrator, h, k_s, k_d) <= 1.0 + RHO_SLACK


def largest_stable_dt(integrator: str, k_s: float, k_d: float, h_max: float = 10.0) -> float | None:
    """s: the largest h with ρ ≤ 1 (on the connected stable range from h → 0), to 1e-6 relative.

    None when even the smallest h is unstable (k_d = 0 with Euler: |1 + iωh| > 1 for every h).
    """
    if integrator not in INTEGRATORS:
        return None
    scale = 1.0 / max(math.sqrt(k_s), k_d, 1e-12)  # the feedback's own time scale
    h = 1e-4 * scale
    if not theory_stable(integrator, h, k_s, k_d):
        return None
    lo = h
    hi = lo
    while theory_stable(integrator, hi, k_s, k_d):
        lo, hi = hi, hi * 1.5
        if hi > h_max:
            return h_max
    while hi / lo > 1 + 1e-6:
        mid = math.sqrt(lo * hi)
        if theory_stable(integrator, mid, k_s, k_d):
            lo = mid
        else:
            hi = mid
    return lo


def critical_limit(integrator: str) -> float:
    """h·√k_s at the stability limit for critical damping (k_d = 2√k_s), from the theory (dimensionless)."""
    return largest_stable_dt(integrator, 1.0, 2.0)


# -- the measured grid -------------------------------------------------------------------------


@dataclass(frozen=True)
class GainMapPlan:
    """scene : a SceneSpec of the suite; integrators; dt (s); k_s (1/s²) and k_d (1/s) grids, ascending."""

    scene: Any
    integrators: tuple[str, ...]
    dt: float
    k_s: tuple[float, ...]
    k_d: tuple[float, ...]
    theory_points: int = 121
    sample_interval: float | None = None


def plan_gainmap(suite: Suite) -> GainMapPlan | None:
    """The suite's ``[gainmap]`` table, validated; None when the suite has none.

    Keys: ``scene`` (an id of the suite), ``integrators`` (default all four),
    ``dt`` (s), ``k_s`` and ``k_d`` as {from, to, per_decade} sweeps or lists,
    ``theory_points`` (resolution of the theory grid per axis, default 121),
    ``sample_interval`` (s, default the suite's).
    """
    table, reader = suite_table(suite, "gainmap", GAINMAP_KEYS)
    if table is None:
        return None
    for key in ("scene", "dt", "k_s", "k_d"):
        if key not in table:
            raise reader.error("gainmap", f"missing {key}; see compare/stability/gainmap.py for the keys")
    known = {s.id: s for s in suite.scenes}
    if table["scene"] not in known:
        raise reader.error("gainmap.scene", f"unknown scene id {table['scene']!r}; this suite's are: {', '.join(known)}")
    integrators = table.get("integrators", list(INTEGRATORS))
    if not isinstance(integrators, list) or not integrators or any(i not in INTEGRATORS for i in integrators):
        raise reader.error("gainmap.integrators", f"must be a list drawn from {', '.join(INTEGRATORS)}")
    dt = reader.number("gainmap.dt", table["dt"])
    scene = known[table["scene"]]
    if dt > scene.scene.duration:
        raise reader.error("gainmap.dt", f"{dt:g} s is longer than scene {scene.id!r}'s duration")
    grids = {}
    for key in ("k_s", "k_d"):
        value = table[key]
        if isinstance(value, dict):
            sweep = reader.table(f"gainmap.{key}", value, ("from", "to", "per_decade"))
            if set(sweep) != {"from", "to", "per_decade"}:
                raise reader.error(f"gainmap.{key}", "write {key} = { from = 1, to = 1e8, per_decade = 2 }")
            values = geometric_sweep(reader.number(f"gainmap.{key}.from", sweep["from"]),
                                     reader.number(f"gainmap.{key}.to", sweep["to"]),
                                     int(reader.number(f"gainmap.{key}.per_decade", sweep["per_decade"], integer=True)))
        elif isinstance(value, list) and value:
            values = [reader.number(f"gainmap.{key}[{k}]", v) for k, v in enumerate(value)]
        else:
            raise reader.error(f"gainmap.{key}", "must be a list of positive numbers or { from, to, per_decade }")
        grids[key] = tuple(sorted(values))
    points = int(reader.number("gainmap.theory_points", table.get("theory_points", 121), integer=True))
    interval = table.get("sample_interval")
    interval = None if interval is None else reader.number("gainmap.sample_interval", interval)
    return GainMapPlan(scene, tuple(integrators), dt, grids["k_s"], grids["k_d"], points, interval)


def theory_grid(plan: GainMapPlan, integrator: str) -> dict[str, Any]:
    """ρ on a fine log grid spanning the measured one, for drawing the ρ = 1 contour.

    log10_k_s (n,), log10_k_d (m,), log10_rho (m, n): rows are k_d, columns k_s (plotly's z layout).
    """
    xs = np.linspace(math.log10(plan.k_s[0]), math.log10(plan.k_s[-1]), plan.theory_points)
    ys = np.linspace(math.log10(plan.k_d[0]), math.log10(plan.k_d[-1]), plan.theory_points)
    rho = np.array([[spectral_radius(integrator, plan.dt, 10 ** x, 10 ** y) for x in xs] for y in ys])
    return {"log10_k_s": xs, "log10_k_d": ys, "log10_rho": np.log10(np.maximum(rho, 1e-300))}


def _engine(integrator: str, k_s: float, k_d: float) -> EngineSpec:
    engine, _ = load_engine("ours")
    variant = f"baumgarte-{integrator}"
    options = {"k_s": k_s, "k_d": k_d}
    return EngineSpec(f"ours/{variant}", f"ours/{variant}", variant, options, engine)


def run_gainmap(
    suite: Suite,
    output: str | Path,
    *,
    jobs: int | None = None,
    timeout: float | None = None,
    force: bool = False,
    on_cell: Callable[[int, int], None] | None = None,
) -> Path | None:
    """Measure every cell of the suite's ``[gainmap]``; write ``output/gainmap.json``; None without a table.

    on_cell(done, total) is called as cells finish (for progress).
    """
    plan = plan_gainmap(suite)
    if plan is None:
        return None
    target = check_output(output, FILE_NAME, force)
    timeout = timeout or suite.timeout
    cells = [(i, a, b) for i in plan.integrators for b in range(len(plan.k_d)) for a in range(len(plan.k_s))]

    def one(cell: tuple[str, int, int]):
        integrator, a, b = cell
        k_s, k_d = plan.k_s[a], plan.k_d[b]
        probe = run_probe(plan.scene, _engine(integrator, k_s, k_d), plan.dt, suite, timeout, plan.sample_interval)
        return cell, probe

    maps = {
        integrator: {
            "status": [[None] * len(plan.k_s) for _ in plan.k_d],
            "constraint_error": [[None] * len(plan.k_s) for _ in plan.k_d],
            "energy_drift": [[None] * len(plan.k_s) for _ in plan.k_d],
            "message": [[""] * len(plan.k_s) for _ in plan.k_d],
            "rho": [[spectral_radius(integrator, plan.dt, ks, kd) for ks in plan.k_s] for kd in plan.k_d],
            "critical_limit": critical_limit(integrator),
            "theory": theory_grid(plan, integrator),
        }
        for integrator in plan.integrators
    }
    done = 0
    with cf.ThreadPoolExecutor(max_workers=jobs or default_jobs()) as pool:
        for (integrator, a, b), probe in pool.map(one, cells):
            cell = maps[integrator]
            cell["status"][b][a] = probe.status
            cell["constraint_error"][b][a] = probe.constraint_error
            cell["energy_drift"][b][a] = probe.energy_drift
            cell["message"][b][a] = probe.message
            done += 1
            if on_cell is not None:
                on_cell(done, len(cells))
    document = {
        **document_head(suite, SCHEMA, SCHEMA_VERSION),
        "scene_id": plan.scene.id,
        "scene": {"name": plan.scene.name, "duration": plan.scene.scene.duration,
                  "length": plan.scene.scene.characteristic_length},
        "dt": plan.dt,
        "k_s": plan.k_s,
        "k_d": plan.k_d,
        "theory": "linearized constraint dynamics C'' + k_d C' + k_s C = 0; stable where the spectral radius "
                  "of the integrator's one-step matrix is <= 1 (docs/ours.md)",
        "maps": maps,
        "finished": now(),
    }
    write_document(target, document)
    return target


def load_gainmap(path: str | Path) -> dict[str, Any] | None:
    """The gain-map document in results directory ``path`` (None when it has none); UserError for another version."""
    return load_document(path, FILE_NAME, SCHEMA, SCHEMA_VERSION)
