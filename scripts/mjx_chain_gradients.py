"""MJX's forward-mode Jacobian on the chain of 8 links: its cost, its self-consistency, its error, and NaNs.

docs/gradients.md quotes what this prints. On the chain of 8 (catalog ``chain``, n = 8, 1 s), RK4 at dt 1e-3:

1. per precision (``mjx/hinge-rk4``, ``mjx/hinge-rk4-f32``): the Jacobian by theta0 from MJX's own forward
   mode (engines/mjx/gradients.py) against central differences of MJX's own rollouts (self-consistency) and
   against the reference's variational equations (error, at dt and dt/2, and the class ``xval grad`` gives:
   compare.gradients.measure.engine_case), the samples (every 0.01 s) whose Jacobian holds a
   NaN or an infinity, and the CPU time of the compile and of the run;
2. the cost of the choices made (float64 RK4): one MJX step of the chain of 4, 6 and 8 links compiled with
   XLA's CPU fusion emitters, and of 8 without them (engines/mjx/library.py's COMPILER_OPTIONS); the tangents
   of all 16 directions at once (``jax.jacfwd``) against one direction at a time (``jax.jvp``, what
   gradients.py does);
3. MuJoCo C's RK4 on the same question with MJX's point-mass inertia (1e-9 of m·L²) and its own (1e-12): where
   the float64 error's floor comes from (quick, checked by the quote test on every run).

MJX's figures are SLOW (minutes of XLA compiles on a CPU; one compile at a time): the quote test checks that
the doc still quotes them. Times are CPU seconds of this process (compiles, JAX's persistent cache off) and wall
milliseconds a step (runs, the fastest of REPEATS), on whatever machine and load it runs; they move with both.

    python scripts/mjx_chain_gradients.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from quoted import load_quotes, report  # noqa: E402

DT = 1e-3
WRT = ["theta0"]
VARIANTS = {"f64": "hinge-rk4", "f32": "hinge-rk4-f32"}
#: Steps timed with XLA's fusion emitters on (about 1 s each on the chain of 8) and off.
STEPS_SLOW, STEPS_FAST = 5, 1000
#: Timed runs of each compiled loop; the fastest is kept (a loaded machine only adds time).
REPEATS = 3


def _scene():
    from engines.scene.catalog import build

    return build("chain", {"n": 8, "duration": 1.0})


def measure_variant(variant: str) -> dict[str, float]:
    """Self-consistency, error (at dt and dt/2), class, non-finite samples and CPU times of MJX's own Jacobian."""
    from compare.gradients.measure import engine_case
    from engines import registry
    from engines.mjx import gradients

    scene = _scene()
    engine, _ = registry.resolve(f"mjx/{variant}")
    start = time.process_time()
    gradients.transition_over_time(engine, scene, variant, None, DT)  # compile, then run
    first = time.process_time() - start
    start = time.process_time()
    _, transition = gradients.transition_over_time(engine, scene, variant, None, DT)  # run only: compiled
    run = time.process_time() - start
    case = engine_case(engine, variant, None, scene, DT, WRT)  # as xval grad: at dt and dt/2, and its own rollouts
    finite = [bool(np.isfinite(p).all()) for p in transition.product]
    found = {"method_autodiff": float(case.method == "autodiff"), "self": float(case.self_consistency),
             "error": float(case.error), "error_half": float(case.error_half),
             "correct": float(case.klass == "correct"), "nonfinite_samples": float(len(finite) - sum(finite)),
             "samples": float(len(finite)), "compile_cpu": first - run, "run_cpu": run}
    print(f"mjx/{variant}: method {case.method}, self-consistency {found['self']:.1e}, error {found['error']:.1e} "
          f"(dt/2: {found['error_half']:.1e}), class {case.klass}, {found['nonfinite_samples']:.0f} of "
          f"{found['samples']:.0f} samples non-finite (first: {transition.first_nonfinite}), compile "
          f"{found['compile_cpu']:.0f} s CPU, run {run:.0f} s CPU", flush=True)
    return found


def _wall(jax, compiled, *args) -> float:
    """s of wall time of one call of ``compiled``."""
    start = time.perf_counter()
    jax.block_until_ready(compiled(*args))
    return time.perf_counter() - start


def _put(jax, mjx, links: int):
    """MJX's model and data of the float64 RK4 chain of ``links`` at rest at its catalog angle (in x64 mode)."""
    from engines import registry
    from engines.mujoco.library import mujoco
    from engines.scene.catalog import build

    engine, variant = registry.resolve("mjx/hinge-rk4")
    hinge = engine.build(build("chain", {"n": links, "duration": 1.0}), DT, engine.resolve(variant, None))
    data = mujoco.MjData(hinge.model)
    data.qvel[:] = hinge.qvel
    mujoco.mj_forward(hinge.model, data)
    return mjx.put_model(hinge.model, impl="jax"), mjx.put_data(hinge.model, data, impl="jax")


def measure_cost() -> dict[str, float]:
    """Float64 RK4: compile CPU s and wall ms a step of one MJX step of the chain of 4, 6 and 8 links with XLA's
    fusion emitters, and of 8 without; on 8 without them, of the tangents of all 16 directions at once (jacfwd)
    and of one direction (jvp; ``jvp.ms_per_jacobian_step``: 16 of them)."""
    from engines.mjx import library

    jax, mjx = library.jax_mjx()
    jnp = jax.numpy
    library.trace_in(jax, True)
    found = {}

    def loop(mx, dx, n):
        return jax.lax.fori_loop(0, n, lambda _, s: mjx.step(mx, s), dx)

    def advance(x, mx, dx, n):
        nq = dx.qpos.shape[0]
        d = jax.lax.fori_loop(0, n, lambda _, s: mjx.step(mx, s), dx.replace(qpos=x[:nq], qvel=x[nq:]))
        return jnp.concatenate([d.qpos, d.qvel])

    def jacfwd(mx, dx, x, n):
        return jax.jacfwd(lambda y: advance(y, mx, dx, n))(x)

    def jvp(mx, dx, x, e, n):
        return jax.jvp(lambda y: advance(y, mx, dx, n), (x,), (e,))

    with jax.enable_x64(True):
        put = {links: _put(jax, mjx, links) for links in (4, 6, 8)}
        mx, dx = put[8]
        x = jnp.concatenate([dx.qpos, dx.qvel])
        cases = {**{f"step_emitters_{links}": (loop, {}, put[links], steps)
                    for links, steps in ((4, STEPS_FAST), (6, 100), (8, STEPS_SLOW))},
                 "step": (loop, library.COMPILER_OPTIONS, (mx, dx), STEPS_FAST),
                 "jacfwd": (jacfwd, library.COMPILER_OPTIONS, (mx, dx, x), 100),
                 "jvp": (jvp, library.COMPILER_OPTIONS, (mx, dx, x, jnp.eye(len(x))[0]), 100)}
        for key, (function, options, args, steps) in cases.items():
            start = time.process_time()
            compiled = jax.jit(function).lower(*args, np.int32(1)).compile(options)
            found[f"{key}.compile_cpu"] = time.process_time() - start
            jax.block_until_ready(compiled(*args, np.int32(1)))  # a first call
            found[f"{key}.ms_per_step"] = min(_wall(jax, compiled, *args, np.int32(steps)) for _ in range(REPEATS)) / steps * 1e3
            print(f"{key}: compile {found[f'{key}.compile_cpu']:.0f} s CPU, {found[f'{key}.ms_per_step']:.2f} ms a step "
                  f"(over {steps} steps)", flush=True)
        found["jvp.ms_per_jacobian_step"] = len(x) * found["jvp.ms_per_step"]
    return found


SLOW = ({f"{p}.{k}" for p in VARIANTS for k in ("method_autodiff", "self", "error", "error_half", "correct",
                                                "nonfinite_samples", "samples", "compile_cpu", "run_cpu")}
        | {f"{c}.{k}" for c in ("step_emitters_4", "step_emitters_6", "step_emitters_8", "step", "jacfwd", "jvp")
           for k in ("compile_cpu", "ms_per_step")} | {"jvp.ms_per_jacobian_step"})


def measure_mujoco() -> dict[str, float]:
    """MuJoCo C's RK4 (``mujoco/hinge-rk4``, differences of its rollouts) on the same question, with MJX's
    point-mass inertia (1e-9 of m·L²) and with its own default (1e-12): errors at dt and dt/2 (quick: ~1 s)."""
    from compare.gradients.measure import engine_case
    from engines import registry

    engine, variant = registry.resolve("mujoco/hinge-rk4")
    found = {}
    for label, ratio in (("mujoco_1e-9", 1e-9), ("mujoco_1e-12", 1e-12)):
        case = engine_case(engine, variant, {"inertia_ratio": ratio}, _scene(), DT, WRT)
        found[f"{label}.error"], found[f"{label}.error_half"] = float(case.error), float(case.error_half)
        print(f"mujoco/hinge-rk4, inertia_ratio {ratio:g}: error {case.error:.2e} (dt/2: {case.error_half:.2e}), "
              f"class {case.klass}", flush=True)
    return found


def figures(quick: bool = False) -> dict[str, float]:
    """Every figure of the module docstring (only MuJoCo C's when ``quick``: MJX's are all SLOW)."""
    found = measure_mujoco()
    if quick:
        return found
    from engines.mjx import library

    jax, _ = library.jax_mjx()
    jax.config.update("jax_enable_compilation_cache", False)  # every compile timed is a compile, not a load
    for precision, variant in VARIANTS.items():  # one compile at a time
        found.update({f"{precision}.{k}": v for k, v in measure_variant(variant).items()})
    found.update(measure_cost())
    return found


QUOTES = load_quotes(__file__)
ROWS: list = []


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="MuJoCo C's figures only (seconds), not MJX's")
    report(figures(quick=parser.parse_args().quick), QUOTES, ROWS)


if __name__ == "__main__":
    main()
