"""Hidden dissipation: is an engine's energy loss its time step, or damping it adds on its own?

An integrator's energy error vanishes as dt → 0; damping an engine applies on
its own (a damping coefficient, a soft constraint's damper, a solver that
removes energy every step whatever the step) does not. So run one scene at
several time steps over a long horizon, measure the energy-loss rate at each,
and extrapolate the rate to dt → 0.

Details: docs/metrics.md, "Module notes", ``compare/stability/dissipation.py``.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from engines.scene.scene import Scene
from engines.scene.trajectory import Trajectory, total_energy

#: Below this extrapolated loss rate (E* per second) an engine's damping is immaterial.
RATE_FLOOR = 1e-6
#: Standard deviations the extrapolated rate must clear.
SIGMAS = 3.0
RULE = (f"hidden_dissipation = r0 - {SIGMAS:g}·sigma > {RATE_FLOOR:g} E*/s, where r0 is the energy-loss rate "
        "extrapolated to dt -> 0 (linear in dt) and sigma the larger of its standard error and its change when "
        "only the two smallest steps are used")
#: Time steps probed by default, s (from the largest down, halving).
DEFAULT_DTS = (4e-3, 2e-3, 1e-3, 5e-4)
#: Horizon probed by default, s: many swings of every catalog scene.
DEFAULT_DURATION = 20.0


@dataclass(frozen=True)
class RatePoint:
    """One run: dt (s), status, rate (E*/s lost; None unless ok), message."""

    dt: float
    status: str
    rate: float | None
    message: str = ""


@dataclass(frozen=True)
class Dissipation:
    """The probe's answer for one engine variant on one scene.

    rate : E*/s, the loss rate extrapolated to dt → 0 (None without enough ok runs).
    uncertainty : E*/s, σ of ``rate``. hidden_dissipation : by :data:`RULE` (None: no verdict).
    points : the runs, largest dt first. reason : why there is no verdict, else "".
    """

    engine: str
    scene: str
    duration: float
    options: Mapping[str, Any]
    rate: float | None
    uncertainty: float | None
    hidden_dissipation: bool | None
    points: tuple[RatePoint, ...]
    rule: str = RULE
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["options"] = dict(self.options)
        out["points"] = [asdict(p) for p in self.points]
        return out

    def to_file(self) -> dict[str, Any]:
        """The document ``xval probe --output DIR`` writes (``DIR/probe-<engine>-<variant>.json``): versioned."""
        return {"schema": PROBE_SCHEMA, "schema_version": PROBE_VERSION, **self.to_dict()}


#: What a stored probe file says it is, and the version of its fields (a reader refuses other versions).
PROBE_SCHEMA = "xval-probe"
PROBE_VERSION = 1


def load_probe_files(directory: str | Path) -> list[dict[str, Any]]:
    """The stored ``xval probe`` results in ``directory`` (``probe*.json``), each a dict with ``engine`` and
    ``hidden_dissipation``; files that cannot be read, or are not probe documents of this version, are passed
    over (the report leaves their marks out). A file from before versioning (no ``schema``) is version 1."""
    found: list[dict[str, Any]] = []
    for file in sorted(Path(directory).glob("probe*.json")):
        try:
            data = json.loads(file.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        for item in data if isinstance(data, list) else [data]:
            if not (isinstance(item, dict) and isinstance(item.get("engine"), str) and "hidden_dissipation" in item):
                continue
            if item.get("schema", PROBE_SCHEMA) == PROBE_SCHEMA and item.get("schema_version", 1) == PROBE_VERSION:
                found.append(item)
    return found


def loss_rate(scene: Scene, t: np.ndarray, positions: np.ndarray, velocities: np.ndarray) -> float:
    """E*/s (positive: lost): −slope of (E(t) − E(0))/E* against t (n,) s, least squares over every sample."""
    if len(t) < 3:
        raise ValueError("loss_rate needs at least 3 samples")
    energy = total_energy(scene, positions, velocities)
    relative = (energy - energy[0]) / scene.characteristic_energy
    slope = np.polyfit(np.asarray(t, float), relative, 1)[0]
    return float(-slope)


def extrapolate(dts: Sequence[float], rates: Sequence[float]) -> tuple[float, float]:
    """(r₀, σ) in E*/s: rate(dt) = r₀ + c·dt at dt → 0; needs ≥ 3 points (σ:
    docs/metrics.md, "Module notes")."""
    x, y = np.asarray(dts, float), np.asarray(rates, float)
    if len(x) < 3:
        raise ValueError("extrapolate needs at least 3 time steps")
    design = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    residual = y - design @ coef
    dof = len(x) - 2
    variance = float(residual @ residual) / dof
    covariance = variance * np.linalg.inv(design.T @ design)
    standard_error = math.sqrt(max(covariance[0, 0], 0.0))
    order = np.argsort(x)
    (x1, x2), (y1, y2) = x[order[:2]], y[order[:2]]
    richardson = y1 - (y2 - y1) / (x2 - x1) * x1
    return float(coef[0]), max(standard_error, abs(float(coef[0]) - richardson))


def hidden(rate: float, uncertainty: float) -> bool:
    """The verdict of :data:`RULE`."""
    return bool(rate - SIGMAS * uncertainty > RATE_FLOOR)


def measure(
    engine: str, scene: Scene, options: Mapping[str, Any], dts: Sequence[float],
    run_at: Callable[[float], Trajectory | tuple[str, str]],
) -> Dissipation:
    """Run ``run_at(dt)`` for each dt (a Trajectory, or (status, message) when none came back) and judge."""
    points = []
    for dt in sorted(dts, reverse=True):
        result = run_at(dt)
        if isinstance(result, tuple):
            points.append(RatePoint(dt, result[0], None, result[1]))
            continue
        status, message = result.info.status, result.info.message
        rate = loss_rate(scene, result.t, result.positions, result.velocities) if status == "ok" else None
        points.append(RatePoint(dt, status, rate, message))
    ok = [(p.dt, p.rate) for p in points if p.rate is not None]
    common = dict(engine=engine, scene=scene.name, duration=scene.duration, options=dict(options), points=tuple(points))
    if len(ok) < 3:
        bad = [f"dt={p.dt:g}: {p.status}" + (f" ({p.message})" if p.message else "") for p in points if p.rate is None]
        return Dissipation(rate=None, uncertainty=None, hidden_dissipation=None,
                           reason=f"only {len(ok)} of {len(points)} runs ended ok ({'; '.join(bad)}); "
                                  "an extrapolation needs 3: try smaller --dt", **common)
    rate, sigma = extrapolate([dt for dt, _ in ok], [r for _, r in ok])
    return Dissipation(rate=rate, uncertainty=sigma, hidden_dissipation=hidden(rate, sigma), **common)


def probe(
    engine_id: str, scene: Scene, options: Mapping[str, Any] | None = None, dts: Sequence[float] = DEFAULT_DTS,
    sample_interval: float = 0.01, timeout: float = 300.0, isolate: bool = True,
) -> Dissipation:
    """Probe ``engine_id`` (``name/variant``) on ``scene``; each run in the runner's case host."""
    from compare.run.isolation import CaseTask, execute
    from engines.adapter import parse_engine_id

    _name, variant = parse_engine_id(engine_id)
    options = dict(options or {})

    def run_at(dt: float):
        task = CaseTask(f"probe|{engine_id}|dt={dt:.12g}", engine_id, variant, options, scene, dt,
                        sample_interval, 1, timeout, isolate)
        outcome = execute(task)
        if outcome.trajectory is None:
            return outcome.status, outcome.message
        return outcome.trajectory

    return measure(engine_id, scene, options, dts, run_at)
