"""Gain map: one or more engine variants on one scene over a log-spaced grid of two numeric options.

The classic use is ours' Baumgarte gains (x = k_s, y = k_d), but any two
numeric options of any variant can be mapped. Measured, per cell: the run's
status under the suite's bounds (as in ``xval run``), constraint error (m)
and energy drift (E*). Where the engine has a linear stability theory of its
own (:meth:`engines.adapter.Engine.spectral_radius`), its spectral radius ρ
is computed per cell and on a fine grid, and the report draws the ρ = 1
boundary; a cell whose ρ is only slightly above 1 may stay inside the
bounds for the run's duration (ρⁿ must lift a tiny error past the bound), so
the measured boundary lies a little outside the theory's.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from compare.results.store import now
from compare.run.runner import default_jobs
from compare.stability.trial import check_output, document_head, load_document, run_trial, timed_retry, write_document
from compare.suite.plans import GainMapPlan
from compare.suite.reader import EngineSpec, Suite

FILE_NAME = "gainmap.json"
SCHEMA = "xval-gainmap"
SCHEMA_VERSION = 2


def plan_gainmap(suite: Suite) -> GainMapPlan | None:
    """The suite's typed ``[gainmap]`` plan (validated when the suite was read); None when it has none."""
    return suite.gainmap


def _cell_engine(engine: EngineSpec, x: str, x_value: float, y: str, y_value: float) -> EngineSpec:
    options = {**engine.options, x: x_value, y: y_value}
    return replace(engine, label=f"{engine.label}[{x}={x_value:g},{y}={y_value:g}]", options=options)


def _rho(engine: EngineSpec, plan: GainMapPlan, x_value: float, y_value: float) -> float | None:
    """The engine's own spectral radius at this cell (None: it has no theory)."""
    if engine.engine is None:
        return None
    return engine.engine.spectral_radius(engine.variant, {**engine.options, plan.x: x_value, plan.y: y_value}, plan.dt)


def theory_grid(plan: GainMapPlan, engine: EngineSpec) -> dict[str, Any] | None:
    """ρ on a fine log grid spanning the measured one, for drawing the ρ = 1 contour; None without a theory.

    log10_x (n,), log10_y (m,), log10_rho (m, n): rows are y, columns x (plotly's z layout).
    """
    if _rho(engine, plan, plan.x_values[0], plan.y_values[0]) is None:
        return None
    xs = np.linspace(math.log10(plan.x_values[0]), math.log10(plan.x_values[-1]), plan.theory_points)
    ys = np.linspace(math.log10(plan.y_values[0]), math.log10(plan.y_values[-1]), plan.theory_points)
    rho = np.array([[_rho(engine, plan, 10 ** x, 10 ** y) for x in xs] for y in ys])
    return {"log10_x": xs, "log10_y": ys, "log10_rho": np.log10(np.maximum(rho, 1e-300))}


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
    nx, ny = len(plan.x_values), len(plan.y_values)
    cells = [(k, a, b) for k in range(len(plan.engines)) for b in range(ny) for a in range(nx)]

    def one(cell: tuple[int, int, int]):
        k, a, b = cell
        engine = _cell_engine(plan.engines[k], plan.x, plan.x_values[a], plan.y, plan.y_values[b])
        trial = timed_retry(lambda dt, limit: run_trial(plan.scene, engine, dt, suite, limit, plan.sample_interval),
                            timeout)
        return cell, trial(plan.dt)

    maps: dict[str, dict[str, Any]] = {}
    for engine in plan.engines:
        rho = [[_rho(engine, plan, xv, yv) for xv in plan.x_values] for yv in plan.y_values]
        maps[engine.label] = {
            "status": [[None] * nx for _ in range(ny)],
            "constraint_error": [[None] * nx for _ in range(ny)],
            "energy_drift": [[None] * nx for _ in range(ny)],
            "message": [[""] * nx for _ in range(ny)],
            "rho": None if rho[0][0] is None else rho,
            "theory": theory_grid(plan, engine),
        }
    done = 0
    with cf.ThreadPoolExecutor(max_workers=jobs or default_jobs()) as pool:
        for (k, a, b), trial in pool.map(one, cells):
            cell = maps[plan.engines[k].label]
            cell["status"][b][a] = trial.status
            cell["constraint_error"][b][a] = trial.constraint_error
            cell["energy_drift"][b][a] = trial.energy_drift
            cell["message"][b][a] = trial.message
            done += 1
            if on_cell is not None:
                on_cell(done, len(cells))
    document = {
        **document_head(suite, SCHEMA, SCHEMA_VERSION),
        "scene_id": plan.scene.id,
        "scene": {"name": plan.scene.name, "duration": plan.scene.scene.duration,
                  "length": plan.scene.scene.characteristic_length},
        "dt": plan.dt,
        "x": plan.x,
        "y": plan.y,
        "x_values": plan.x_values,
        "y_values": plan.y_values,
        "theory": "the engine's own linear stability theory: stable where the spectral radius of its "
                  "linearized one-step matrix is <= 1 (for ours' Baumgarte feedback, docs/ours.md)",
        "maps": maps,
        "finished": now(),
    }
    write_document(target, document)
    return target


def load_gainmap(path: str | Path) -> dict[str, Any] | None:
    """The gain-map document in results directory ``path`` (None when it has none); UserError for another version."""
    return load_document(path, FILE_NAME, SCHEMA, SCHEMA_VERSION)
