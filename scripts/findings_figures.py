"""Every figure docs/findings.md quotes, measured on the cases of suites/stiff.toml and printed.

Run:  .venv/bin/python scripts/findings_figures.py      (a few minutes on 2 cores)

``make stiff`` runs the whole suite and draws the report; this script re-runs, in this
process, only the cases (and stability searches) each quoted figure needs, with the
suite's own settings: its scenes, its 35 engine variants, its bounds (a run is
``unstable`` past 1 E* of energy drift or 0.1 L of constraint error, checked on the
stored samples, 0.05 s apart as in ``xval run``) and the stability search of
``xval stability`` (samples 0.01 s apart, dt from 0.05 s down to 1e-4 s, 10 %
resolution). tests/test_docs_figures.py runs ``figures(quick=True)``, which leaves
out the groups in SLOW (long runs and searches over many variants).
"""

from __future__ import annotations

import functools
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Row, load_quotes, report  # noqa: E402

from compare.results.metrics import position_error  # noqa: E402
from compare.stability.trial import Trial  # noqa: E402
from compare.stability.search import search  # noqa: E402
from compare.suite.plans import SearchSettings  # noqa: E402
from compare.suite.reader import load_suite  # noqa: E402
from engines.reference.reference import solve  # noqa: E402
from ours.stability import RHO_SLACK  # noqa: E402  (the slack the gain map allows ρ = 1 for round-off)
from engines.scene.trajectory import max_constraint_error, total_energy  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SUITE = load_suite(ROOT / "suites" / "stiff.toml")
SCENES = {s.id: s.scene for s in SUITE.scenes}
ENGINES = {e.label: e for e in SUITE.engines if e.engine is not None}
SEARCH = SearchSettings(dt_max=0.05, dt_min=1e-4, sample_interval=0.01)


@functools.lru_cache(maxsize=None)
def case(scene_id: str, label: str, dt: float, sample_interval: float = 0.05) -> dict:
    """One case with the suite's bounds: status, energy drift (E*), constraint error (L), the run."""
    scene, spec = SCENES[scene_id], ENGINES[label]
    run = spec.engine.simulate(scene, dt, variant=spec.variant, options=dict(spec.options),
                               sample_interval=sample_interval)
    status = run.info.status
    drift = cerr = float("nan")
    if run.n_samples >= 2:
        energy = total_energy(scene, run.positions, run.velocities)
        drift = float(np.abs(energy - energy[0]).max() / scene.characteristic_energy)
        cerr = float(max_constraint_error(scene, run.positions).max() / scene.characteristic_length)
    if status == "ok" and not (drift <= SUITE.bounds.energy_drift and cerr <= SUITE.bounds.constraint_error):
        status = "unstable"
    return {"status": status, "drift": drift, "cerr": cerr, "run": run}


def ok_count(scene_id: str, dt: float) -> tuple[int, int]:
    """(ok cases, cases that ran: not skipped) over the suite's variants at ``dt``."""
    ran = [label for label, spec in ENGINES.items() if _expresses(spec, SCENES[scene_id])]
    return sum(case(scene_id, label, dt)["status"] == "ok" for label in ran), len(ran)


def _expresses(spec, scene) -> bool:
    try:
        spec.engine.check(scene, spec.variant, dict(spec.options))
        return True
    except Exception:
        return False


@functools.lru_cache(maxsize=None)
def largest_stable(scene_id: str, label: str) -> float:
    """s: the search's largest stable dt (inf when stable at 0.05 s, 0 when unstable at 1e-4 s)."""
    def trial(dt: float) -> Trial:
        return Trial(dt, case(scene_id, label, dt, SEARCH.sample_interval)["status"])
    verdict, largest, _, _ = search(trial, SEARCH)
    if verdict == "stable-at-largest":
        return math.inf
    return largest if largest is not None else 0.0


def stability_table(f: dict) -> None:
    for label, key in (("ours/baumgarte-rk4-ks1e6", "rk4"), ("ours/baumgarte-symplectic-euler-ks1e6", "se")):
        for scene_id in ("bead", "whirling-bead", "chain-32", "bead-1mm", "mass-ratio-1000"):
            f[f"stability.{key}.{scene_id}_ms"] = largest_stable(scene_id, label) * 1e3
    f["stability.theory.rk4_ms"], f["stability.theory.se_ms"] = 2.785, 2 * (math.sqrt(2) - 1)
    f["stability.rk4.bead_below_theory"] = 1 - f["stability.rk4.bead_ms"] / 2.785
    f["stability.se.bead_below_theory"] = 1 - f["stability.se.bead_ms"] / f["stability.theory.se_ms"]
    f["stability.rk4.whirling_below_theory"] = 1 - f["stability.rk4.whirling-bead_ms"] / 2.785


def gain_map(f: dict) -> None:
    """The suite's [gainmap] (ours/baumgarte on the bead at dt = 1 ms) against the linear theory, cell by cell.

    The theory is the engine's own (``Engine.spectral_radius``: ours' one-step matrix, docs/ours.md).
    """
    plan = SUITE.gainmap
    scene = plan.scene.scene
    interval = plan.sample_interval or SUITE.sample_interval
    for spec in plan.engines:
        agree = stable_but_theory_not = theory_but_not_stable = 0
        for x in plan.x_values:
            for y in plan.y_values:
                options = {**dict(spec.options), plan.x: x, plan.y: y}
                run = spec.engine.simulate(scene, plan.dt, variant=spec.variant, options=options,
                                           sample_interval=interval)
                ok = run.info.status == "ok" and run.n_samples >= 2
                if ok:
                    energy = total_energy(scene, run.positions, run.velocities)
                    drift = np.abs(energy - energy[0]).max() / scene.characteristic_energy
                    cerr = max_constraint_error(scene, run.positions).max() / scene.characteristic_length
                    ok = bool(drift <= SUITE.bounds.energy_drift and cerr <= SUITE.bounds.constraint_error)
                theory = spec.engine.spectral_radius(spec.variant, options, plan.dt) <= 1.0 + RHO_SLACK
                agree += ok == theory
                stable_but_theory_not += ok and not theory
                theory_but_not_stable += theory and not ok
        key = spec.variant.removeprefix("baumgarte-").replace("-", "_")
        f[f"gainmap.{key}.agree"] = agree
        f[f"gainmap.{key}.cells"] = len(plan.x_values) * len(plan.y_values)
        f[f"gainmap.{key}.ok_where_theory_unstable"] = stable_but_theory_not
        f[f"gainmap.{key}.unstable_where_theory_stable"] = theory_but_not_stable


def large_steps(f: dict) -> None:
    for scene_id in ("bead", "spherical", "upside-down", "whirling-bead"):
        f[f"large.{scene_id}.ok"], f[f"large.{scene_id}.ran"] = ok_count(scene_id, 0.05)


def whirling_limits(f: dict) -> None:
    for label in ("pymunk/pin-bias0", "pybullet/p2p", "pybullet/p2p-dantzig", "mujoco/connect-stiff", "pymunk/pin"):
        f[f"whirl.{label}_ms"] = largest_stable("whirling-bead", label) * 1e3
    for label in ("mujoco/connect", "mujoco/connect-rk4"):
        f[f"whirl.{label}.drift_at_1e-4"] = case("whirling-bead", label, 1e-4, 0.01)["drift"]


def mass_ratio(f: dict) -> None:
    for label in ("pybullet/p2p", "pybullet/p2p-iter500", "pybullet/p2p-dantzig", "pymunk/pin",
                  "pymunk/pin-bias0-iter50", "mujoco/connect"):
        for scene_id, tag in (("mass-ratio-1000", "heavy"), ("mass-ratio-0.001", "light")):
            c = case(scene_id, label, 5e-3)
            f[f"mass.{label}.{tag}"] = c["cerr"]
            f[f"mass.{label}.{tag}.unstable"] = float(c["status"] != "ok")
    heavy_over_light = [f[f"mass.{label}.heavy"] / f[f"mass.{label}.light"] for label in
                        ("pybullet/p2p", "pybullet/p2p-iter500", "pymunk/pin", "pymunk/pin-bias0-iter50", "mujoco/connect")]
    f["mass.heavy_over_light.min"], f["mass.heavy_over_light.max"] = min(heavy_over_light), max(heavy_over_light)
    f["mass.p2p_over_dantzig.heavy"] = f["mass.pybullet/p2p.heavy"] / f["mass.pybullet/p2p-dantzig.heavy"]
    f["mass.mujoco/connect-rk4-stiff.light"] = case("mass-ratio-0.001", "mujoco/connect-rk4-stiff", 5e-3)["cerr"]
    light = [label for label in ENGINES if "ks1e6" not in label and _expresses(ENGINES[label], SCENES["mass-ratio-0.001"])]
    f["mass.light.ok_default_gain"] = sum(case("mass-ratio-0.001", label, 5e-3)["status"] == "ok" for label in light)
    f["mass.light.default_gain_variants"] = len(light)


def mass_ratio_limits(f: dict) -> None:
    for label in ("ours/rattle", "ours/baumgarte-rk4", "mujoco/hinge-rk4"):
        f[f"mass.limit.{label}_ms"] = largest_stable("mass-ratio-1000", label) * 1e3


def chain128(f: dict) -> None:
    for label in ("pybullet/p2p", "pybullet/p2p-iter500", "pybullet/p2p-dantzig", "pybullet/p2p-dantzig-erp0.8"):
        c = case("chain-128", label, 5e-3)
        f[f"chain128.{label}.cerr"] = c["cerr"]
        f[f"chain128.{label}.ok"] = float(c["status"] == "ok")
    ok = [label for label in ENGINES if _expresses(ENGINES[label], SCENES["chain-128"])
          and case("chain-128", label, 5e-3)["status"] == "ok"]
    f["chain128.ok"] = len(ok)
    pymunk = [case("chain-128", label, 5e-3) for label in ENGINES if label.startswith("pymunk/")]
    f["chain128.pymunk.cerr.min"] = min(c["cerr"] for c in pymunk)
    f["chain128.pymunk.cerr.max"] = max(c["cerr"] for c in pymunk)
    f["chain128.pymunk.drift.min"] = min(c["drift"] for c in pymunk)
    f["chain128.pymunk.drift.max"] = max(c["drift"] for c in pymunk)
    f["chain128.plain-se.drift"] = case("chain-128", "ours/plain-symplectic-euler", 5e-3)["drift"]


def chain32_limits(f: dict) -> None:
    engines = [label for label in ENGINES if label.startswith(("mujoco/hinge", "pybullet/", "pymunk/"))]
    limits = [largest_stable("chain-32", label) for label in engines]
    f["chain32.engines.min_ms"], f["chain32.engines.max_ms"] = min(limits) * 1e3, max(limits) * 1e3
    euler = [largest_stable("chain-32", f"ours/{m}-euler") for m in ("baumgarte", "plain", "projection", "lagrangian")]
    f["chain32.ours_euler.min_ms"], f["chain32.ours_euler.max_ms"] = min(euler) * 1e3, max(euler) * 1e3


def scale(f: dict) -> None:
    for scene_id in ("bead-100m", "bead-1mm"):
        f[f"scale.{scene_id}.ok"], f[f"scale.{scene_id}.ran"] = ok_count(scene_id, 5e-3)


def scale_limits(f: dict) -> None:
    f["scale.1mm.plain-euler_ms"] = largest_stable("bead-1mm", "ours/plain-euler") * 1e3
    f["scale.1mm.hinge-rk4_ms"] = largest_stable("bead-1mm", "mujoco/hinge-rk4") * 1e3
    f["scale.1mm.projection-se.drift_at_50ms"] = case("bead-1mm", "ours/projection-symplectic-euler", 0.05, 0.01)["drift"]
    f["scale.1mm.lagrangian-rk4_ms"] = largest_stable("bead-1mm", "ours/lagrangian-rk4") * 1e3
    f["scale.1mm.connect.stretch_mm_at_1e-4"] = case("bead-1mm", "mujoco/connect", 1e-4, 0.01)["cerr"] * 1.0
    f["scale.1mm.connect-rk4.unstable_at_1e-4"] = float(case("bead-1mm", "mujoco/connect-rk4", 1e-4, 0.01)["status"] != "ok")


def long_horizon(f: dict, labels) -> None:
    for label in labels:
        c = case("bead-1000s", label, 5e-3)
        f[f"long.{label}.drift"] = c["drift"]
        f[f"long.{label}.cerr"] = c["cerr"]
        f[f"long.{label}.end_s"] = float(c["run"].t[-1])


LONG_QUICK = ("mujoco/hinge-rk4", "ours/lagrangian-rk4", "ours/baumgarte-rk4", "ours/rattle", "mujoco/hinge",
              "ours/baumgarte-symplectic-euler", "ours/plain-symplectic-euler", "ours/lagrangian-euler",
              "mujoco/connect", "ours/baumgarte-euler", "ours/plain-euler", "ours/projection-symplectic-euler",
              "ours/projection-euler")
LONG_SLOW = ("pymunk/pin-bias0", "pybullet/multibody", "pybullet/p2p")


def upside_down(f: dict) -> None:
    f["upside.ok_5ms"], f["upside.ran"] = ok_count("upside-down", 5e-3)
    f["upside.ok_50ms"], _ = ok_count("upside-down", 0.05)
    scene = SCENES["upside-down"]
    c = case("upside-down", "ours/baumgarte-euler", 5e-3)
    run = c["run"]
    e = position_error(run.positions, solve(scene).at(run.t)[0])
    above = np.nonzero(e > SUITE.delta * scene.characteristic_length)[0]
    f["upside.euler_departs_s"] = float(run.t[above[0]]) if len(above) else math.inf


def spherical(f: dict) -> None:
    f["spherical.ok_5ms"], f["spherical.ran"] = ok_count("spherical", 5e-3)
    f["spherical.ok_50ms"], _ = ok_count("spherical", 0.05)


QUICK_GROUPS = (stability_table, gain_map, large_steps, mass_ratio, scale, upside_down, spherical)
SLOW_GROUPS = (whirling_limits, mass_ratio_limits, chain128, chain32_limits, scale_limits)


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    for group in QUICK_GROUPS:
        group(f)
    long_horizon(f, LONG_QUICK)
    if not quick:
        for group in SLOW_GROUPS:
            group(f)
        long_horizon(f, LONG_SLOW)
    return {k: float(v) for k, v in f.items()}


D = "docs/findings.md"
ROWS = [
    Row(D, "ours/baumgarte-rk4, k_s = 1e6", ("stability.theory.rk4_ms", "stability.rk4.bead_ms",
        "stability.rk4.whirling-bead_ms", "stability.rk4.chain-32_ms", "stability.rk4.bead-1mm_ms",
        "stability.rk4.mass-ratio-1000_ms")),
    Row(D, "ours/baumgarte-symplectic-euler, k_s = 1e6", ("stability.theory.se_ms", "stability.se.bead_ms",
        "stability.se.whirling-bead_ms", "stability.se.chain-32_ms", "stability.se.bead-1mm_ms",
        "stability.se.mass-ratio-1000_ms")),
    Row(D, "pybullet/p2p (", ("mass.pybullet/p2p.heavy", "mass.pybullet/p2p.light")),
    Row(D, "pybullet/p2p-iter500", ("mass.pybullet/p2p-iter500.heavy", "mass.pybullet/p2p-iter500.light")),
    Row(D, "pybullet/p2p-dantzig (", ("mass.pybullet/p2p-dantzig.heavy", "mass.pybullet/p2p-dantzig.light")),
    Row(D, "pymunk/pin (", ("mass.pymunk/pin.heavy", "mass.pymunk/pin.light")),
    Row(D, "pymunk/pin-bias0-iter50", ("mass.pymunk/pin-bias0-iter50.heavy", "mass.pymunk/pin-bias0-iter50.light")),
    Row(D, "mujoco/connect (", ("mass.mujoco/connect.heavy", "mass.mujoco/connect.light")),
    Row(D, "mujoco/connect-rk4-stiff", (None, "mass.mujoco/connect-rk4-stiff.light")),
]
QUOTES = load_quotes(__file__)
_quick_groups_keys = None
SLOW = {q.key for q in QUOTES if q.key.startswith(("whirl.", "chain128.", "chain32.", "mass.limit.", "scale.1mm."))} | {
    f"long.{label}.{m}" for label in ("pymunk/pin-bias0", "pybullet/multibody", "pybullet/p2p") for m in ("drift", "cerr", "end_s")}


def main() -> None:
    report(figures(), QUOTES, ROWS)


if __name__ == "__main__":
    main()
