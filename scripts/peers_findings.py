"""Measure the peers' findings quoted in docs/findings.md ("The peers: Drake and MuJoCo MJX").

Run: ``.venv/bin/python scripts/peers_findings.py`` (needs ``pip install 'xval[all]'``; a
few minutes, most of it MJX's jit compiles and ours' dt sweep; name sections to run only
those: ``discrete mjx accuracy ours compile``). Prints five Markdown tables:

1. Drake RK3 at accuracy 1e-6 against ours' most accurate variant and dt whose cost
   (stepping wall time per simulated second, the best of 3 repeats) is no larger: bead
   (θ0 = 60°, 10 s), double pendulum (2 s), 32-link chain (L = 1 m, 2 s).
2. MJX float32 against float64 (bead, 2 s): the error floor where RK4's truncation error
   falls below round-off, with jit compile time and stepping cost beside MuJoCo C's.
3. Drake's discrete plant against mujoco/hinge (dt = 1e-3, 2 s): trajectory difference with
   each engine's default point-mass inertia, and with the same inertia (1e-9), and cost.
4. Drake's error-controlled integrators on the double pendulum (2 s): error and steps
   against the accuracy setting, 1e-4 to 1e-10 (dt = 1e-2, the largest step).
5. MJX's jit compile time of one step on chains of 2, 4 and 8 links (why deeper trees are
   left out, engines/mjx/adapter.py).

Errors are max over samples of the largest particle distance from the reference (DOP853,
rtol = atol = 1e-12), in metres. Costs are ratios measured in this run, never absolutes.
"""

from __future__ import annotations

import sys

import numpy as np

from engines.scene import catalog
from engines.drake.adapter import ENGINE as DRAKE
from engines.mjx.adapter import ENGINE as MJX
from engines.mujoco.adapter import ENGINE as MUJOCO
from engines.ours.adapter import ENGINE as OURS
from engines.reference.reference import solve

SCENES = {
    "bead": catalog.build("bead", {"theta0": 60, "duration": 10}),
    "double-pendulum": catalog.build("double-pendulum", {"duration": 2}),
    "chain-32": catalog.build("chain", {"n": 32, "length": 1 / 32, "mass": 1 / 32, "duration": 2}),
}
#: ours' variants that can be most accurate per unit cost (every RK4 form, RATTLE, the midpoints).
OURS_VARIANTS = ["lagrangian-rk4", "projection-rk4", "baumgarte-rk4", "plain-rk4", "rattle",
                 "projection-midpoint", "lagrangian-midpoint"]
OURS_DTS = [1e-2 * 10 ** (-k / 3) for k in range(7)]  # 1e-2 .. 1e-4, three per decade
REPEATS = 3


def run(engine, scene, dt, variant, options=None, repeats=REPEATS):
    """(trajectory, cost s per simulated s: the best of ``repeats`` stepping wall times)."""
    best, trajectory = np.inf, None
    for _ in range(repeats):
        trajectory = engine.simulate(scene, dt, variant=variant, options=options)
        best = min(best, trajectory.info.wall_time)
    return trajectory, best / scene.duration


def error(trajectory, reference) -> float:
    if trajectory.info.status != "ok":
        return float("nan")
    positions, _, _ = reference.at(trajectory.t)
    return float(np.linalg.norm(trajectory.positions - positions, axis=2).max())


def drake_against_ours() -> None:
    print("\n### Drake RK3 at accuracy 1e-6 against ours' best at no more cost\n")
    print("| scene | drake/rk3 error (m) | its steps | ours' best at ≤ its cost | dt (s) | its error (m) "
          "| cost ours / drake | ours' error at dt = 1e-4 (m) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, scene in SCENES.items():
        reference = solve(scene)
        drake, drake_cost = run(DRAKE, scene, 1e-2, "rk3", {"accuracy": 1e-6})
        drake_error = error(drake, reference)
        best = None
        finest = np.inf
        for variant in OURS_VARIANTS:
            try:
                OURS.check(scene, variant)
            except Exception:  # noqa: BLE001 - a variant that cannot express the scene is not a candidate
                continue
            for dt in OURS_DTS:
                ours, cost = run(OURS, scene, dt, variant)
                e = error(ours, reference)
                if dt == OURS_DTS[-1]:
                    finest = min(finest, e)
                if cost <= drake_cost and np.isfinite(e) and (best is None or e < best[2]):
                    best = (variant, dt, e, cost)
        if best is None:
            print(f"| {name} | {drake_error:.1e} | {drake.info.steps} | none as cheap | - | - | - | {finest:.1e} |")
            continue
        variant, dt, e, cost = best
        print(f"| {name} | {drake_error:.1e} | {drake.info.steps} | ours/{variant} | {dt:.2g} | {e:.1e} "
              f"| {cost / drake_cost:.2f} | {finest:.1e} |")


def mjx_precision() -> None:
    print("\n### MJX float32 against float64 (bead, θ0 = 60°, 2 s)\n")
    scene = catalog.build("bead", {"theta0": 60, "duration": 2})
    reference = solve(scene)
    dts = [1e-2, 2.5e-3, 1e-3, 2.5e-4]
    print("| variant | " + " | ".join(f"error at dt = {dt:g} (m)" for dt in dts)
          + " | jit compile (s) | cost / mujoco C's at dt = 1e-3 |")
    print("|---|" + "---|" * len(dts) + "---|---|")
    for variant, c_variant in (("hinge", "hinge"), ("hinge-f32", "hinge"), ("hinge-rk4", "hinge-rk4"),
                               ("hinge-rk4-f32", "hinge-rk4")):
        errors, compile_time, ratio = [], 0.0, np.nan
        for dt in dts:
            trajectory, cost = run(MJX, scene, dt, variant, repeats=1 if dt != 1e-3 else REPEATS)
            compile_time = max(compile_time, trajectory.info.settings["jit_compile_time"])
            errors.append(error(trajectory, reference))
            if dt == 1e-3:
                _, c_cost = run(MUJOCO, scene, dt, c_variant)
                ratio = cost / c_cost
        print(f"| mjx/{variant} | " + " | ".join(f"{e:.1e}" for e in errors)
              + f" | {compile_time:.1f} | {ratio:.0f} |")


def drake_discrete_against_mujoco() -> None:
    print("\n### Drake's discrete plant against mujoco/hinge (dt = 1e-3, 2 s)\n")
    print("| scene | position difference, default inertias (m) | same inertia 1e-9 (m) "
          "| force difference, same inertia (N) | drake/discrete error (m) | cost drake / mujoco |")
    print("|---|---|---|---|---|---|")
    for name, params in (("bead", {}), ("double-pendulum", {}), ("chain-8", {"n": 8})):
        scene = catalog.build(name.split("-8")[0] if name == "chain-8" else name, {"duration": 2, **params})
        reference = solve(scene)
        mujoco, m_cost = run(MUJOCO, scene, 1e-3, "hinge")
        default, d_cost = run(DRAKE, scene, 1e-3, "discrete")
        same, _ = run(DRAKE, scene, 1e-3, "discrete", {"inertia_ratio": 1e-9}, repeats=1)
        print(f"| {name} | {np.abs(default.positions - mujoco.positions).max():.1e} "
              f"| {np.abs(same.positions - mujoco.positions).max():.1e} "
              f"| {np.abs(same.constraint_forces - mujoco.constraint_forces).max():.1e} "
              f"| {error(default, reference):.1e} | {d_cost / m_cost:.1f} |")


def drake_accuracy() -> None:
    print("\n### Drake's error-controlled integrators: error (m) and steps against accuracy (double pendulum, 2 s)\n")
    scene = SCENES["double-pendulum"]
    reference = solve(scene)
    accuracies = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    print("| variant | " + " | ".join(f"{a:g}" for a in accuracies) + " |")
    print("|---|" + "---|" * len(accuracies))
    for variant in ("rk3", "bs3", "rk5", "radau3"):
        cells = []
        for accuracy in accuracies:
            trajectory = DRAKE.simulate(scene, 1e-2, variant=variant, options={"accuracy": accuracy})
            cells.append(f"{error(trajectory, reference):.1e} ({trajectory.info.steps})")
        print(f"| drake/{variant} | " + " | ".join(cells) + " |")


def mjx_compile_time() -> None:
    """CPU time of jit(mjx.step).lower().compile() on planar chains of growing depth (float64, Euler)."""
    import time

    import mujoco

    from engines.mjx.library import jax_mjx

    jax, mjx = jax_mjx()  # imported as the adapter does (quiet about the absent warp)

    print("\n### MJX jit compile of one step against the depth of the body tree (chain, float64, Euler)\n")
    print("| links | compile CPU (s) | compile wall (s) |")
    print("|---|---|---|")
    for n in (2, 4, 8):
        scene = catalog.build("chain", {"n": n, "duration": 1})
        model = MJX.build(scene, 1e-3, MJX.resolve("hinge")).model
        with jax.enable_x64(True):
            jax.clear_caches()
            mx, dx = mjx.put_model(model, impl="jax"), mjx.put_data(model, mujoco.MjData(model), impl="jax")
            cpu, wall = time.process_time(), time.perf_counter()
            jax.jit(mjx.step).lower(mx, dx).compile()
            print(f"| {n} | {time.process_time() - cpu:.1f} | {time.perf_counter() - wall:.1f} |")


SECTIONS = {
    "discrete": drake_discrete_against_mujoco,
    "mjx": mjx_precision,
    "accuracy": drake_accuracy,
    "ours": drake_against_ours,
    "compile": mjx_compile_time,
}


def main(argv: list[str]) -> None:
    """Print every section, or those named on the command line (discrete, mjx, accuracy, ours, compile)."""
    print(f"drake {DRAKE.version()}; {MJX.version()}")
    for name in argv or list(SECTIONS):
        SECTIONS[name]()


if __name__ == "__main__":
    main(sys.argv[1:])
