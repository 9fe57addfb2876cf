"""MuJoCo MJX adapter: the MuJoCo adapter's hinge model, stepped by MJX (MuJoCo in JAX) on the CPU.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/mjx/adapter.py``.
"""

from __future__ import annotations

import math
import time
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.errors import Unsupported, UserError
from engines.mjx import library

# MJX steps MuJoCo's own model: built and read by MuJoCo's public builder, with MuJoCo's one import of it.
from engines.mujoco.builder import (
    HINGE_INERTIA_RATIO,
    HingeModel,
    check_hinge,
    hinge_model,
    read_hinge_samples,
    tree_depth,
)
from engines.mujoco.library import mujoco
from engines.scene.scene import Scene

#: MJX's integrators that this adapter offers (MJX has no 'implicit').
MJX_INTEGRATORS = ("Euler", "RK4", "implicitfast")

#: Deepest body tree the adapter compiles by default. Measured CPU time of jit(mjx.step).lower().compile()
#: on a planar chain (mujoco-mjx 3.17.0, jax 0.10.2; scripts/peers_findings.py compile): 3.7 s at depth 2,
#: 5.7 s at 4, 11.9 s at 8, growing faster than the depth; and the compiled loop is rebuilt in every case's
#: process. Deeper scenes are left out with this reason unless max_depth is raised.
MAX_DEPTH = 8

#: Compiled stepping loops of this process, by (model structure, x64).
_compiled: dict[tuple, Any] = {}


class MJXEngine(Engine):
    """MuJoCo MJX (JAX, CPU): the mujoco/hinge model in float64 or float32."""

    name = "mjx"
    capabilities = frozenset({"3d", "constraint-forces"})
    options = {
        "precision": Option(
            "precision", "float64", "float64: JAX 64-bit mode on; float32: off (JAX's and MJX's default)",
            kind="str", choices=("float64", "float32"),
        ),
        "integrator": Option(
            "integrator", "Euler", "MJX integrator (Euler, semi-implicit, is MuJoCo's default)",
            kind="str", choices=MJX_INTEGRATORS,
        ),
        "inertia_ratio": Option(
            "inertia_ratio", 1e-9,
            "rotational inertia of each point-mass body, as a fraction of m·L² (mujoco/hinge's option; its "
            f"default is {HINGE_INERTIA_RATIO:g}, and MJX's figures in docs/findings.md were made at 1e-9)",
        ),
        "max_depth": Option(
            "max_depth", MAX_DEPTH,
            "deepest body tree compiled: MJX's jit compile grows steeply with the tree's depth on the CPU",
            kind="int",
        ),
    }
    variants = {
        "hinge": {},
        "hinge-f32": {"precision": "float32"},
        "hinge-rk4": {"integrator": "RK4"},
        "hinge-rk4-f32": {"integrator": "RK4", "precision": "float32"},
    }
    variant_docs = {
        "hinge": "mujoco/hinge's model stepped by MJX, float64 (jax x64), Euler",
        "hinge-f32": "as hinge, float32 (JAX's default precision)",
        "hinge-rk4": "mujoco/hinge-rk4's model stepped by MJX, float64, RK4",
        "hinge-rk4-f32": "as hinge-rk4, float32",
    }
    overrides = {
        "flag.contact": "disable (default enable): the scenes have nothing to collide",
        "jax_enable_x64": "on for float64 variants (JAX's default is off: float32)",
        "impl": "jax (put_model's default picks by device; JAX on a CPU)",
        "xla_cpu_use_fusion_emitters": "off (jaxlib's default on): their cost grows exponentially with the tree's depth",
    }

    def version(self) -> str:
        return f"{library.version()}, mujoco {mujoco.mj_versionString()}"

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        if settings["inertia_ratio"] <= 0:
            raise UserError(f"mjx: option inertia_ratio must be positive, got {settings['inertia_ratio']}")

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        check_hinge(scene, settings["integrator"], settings["inertia_ratio"])
        depth = tree_depth(scene)
        if depth > settings["max_depth"]:
            raise Unsupported(
                f"mjx: the body tree is {depth} deep and MJX's jit compile on the CPU grows steeply with depth "
                f"(11.9 s of CPU at depth 8, growing faster than the depth); set option max_depth = {depth} to run it anyway"
            )

    def jacobian(self, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                 wrt: list[str]) -> tuple[np.ndarray, str] | None:
        """Forward mode (jax.jvp) through the stepping loop, float64 or float32 (engines/mjx/gradients.py)."""
        from engines.mjx import gradients

        return gradients.jacobian(self, scene, variant, options, dt, wrt)

    def build(self, scene: Scene, dt: float, settings: Mapping[str, Any]) -> HingeModel:
        """The MuJoCo adapter's hinge model with this integrator and inertia."""
        return hinge_model(scene, dt, settings["integrator"], settings["inertia_ratio"])

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        jax, mjx = library.jax_mjx()
        hinge = self.build(scene, schedule.dt, settings)
        model, inertia = hinge.model, hinge.inertia
        data = mujoco.MjData(model)
        data.qvel[:] = hinge.qvel
        mujoco.mj_forward(model, data)
        x64 = settings["precision"] == "float64"
        strides = np.diff(schedule.sample_steps).astype(np.int32)
        # The compiled loop depends on the model's structure, not on dt (an array in MJX's model).
        key = (hinge.structure, x64)
        record: dict[str, Any] = {}
        with jax.enable_x64(x64):
            mx = mjx.put_model(model, impl="jax")
            dx = mjx.put_data(model, data, impl="jax")
            record["dtype"] = str(dx.qpos.dtype)
            compiled = _compiled.get(key)
            record["jit_cache_hit"] = compiled is not None
            t0 = time.perf_counter()
            if compiled is None:
                library.trace_in(jax, x64)
                compiled = _compiled[key] = library.compiled(jax, _advance, mx, dx, np.int32(1))
            record["jit_compile_time"] = 0.0 if record["jit_cache_hit"] else time.perf_counter() - t0
            outputs = []
            t0 = time.perf_counter()
            for stride in strides:
                dx = compiled(mx, dx, stride)
                outputs.append((dx.qpos, dx.qvel))
            jax.block_until_ready(dx)
            wall = time.perf_counter() - t0
            qpos = np.array([data.qpos] + [np.asarray(q, dtype=np.float64) for q, _ in outputs])
            qvel = np.array([data.qvel] + [np.asarray(v, dtype=np.float64) for _, v in outputs])
        finite = np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1)
        n = len(qpos) if finite.all() else int(np.argmin(finite)) + 1
        states = _full_states(model, qpos[:n], qvel[:n], schedule.times[:n])
        positions, velocities, forces = read_hinge_samples(scene, model, states)
        record["point_mass_inertia"] = [float(x) for x in inertia]  # the model's, MuJoCo's floor included
        taken = int(schedule.sample_steps[-1] if n == len(qpos) else schedule.sample_steps[n])
        record["precision_floor"] = precision_floor(record["dtype"], taken, scene.characteristic_length)
        record["stepping"] = "jit(fori_loop(mjx.step)) per sample interval"
        return RawRun(positions, velocities, forces, steps=taken,
                      wall_time=wall, settings=record)


def precision_floor(dtype: str, steps: int, length: float) -> float:
    """m, the error floor this precision declares after ``steps`` steps: eps · √steps · L, round-off of one
    unit per step adding up as a random walk. Measured (tests/test_consistency.py): float32 RK4 stops at
    0.15 (bead) to 0.63 (double pendulum) of it over 2 s at dt 1e-4 s; compare.results.consistency does
    not call a plateau under it inconsistent."""
    return float(np.finfo(np.dtype(dtype)).eps) * math.sqrt(max(steps, 1)) * length


def _advance(m, d, n):
    """``n`` MJX steps of ``d`` under model ``m`` (a fori_loop with a traced count: one compile for any n)."""
    jax, mjx = library.jax_mjx()
    return jax.lax.fori_loop(0, n, lambda _, x: mjx.step(m, x), d)


def _full_states(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(n, nstate) MuJoCo full-physics states for joint positions (n, nq) and velocities (n, nv) at times (n,) s."""
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.empty((len(qpos), mujoco.mj_stateSize(model, spec)))
    for s, (q, v, t) in enumerate(zip(qpos, qvel, times)):
        data.qpos[:], data.qvel[:], data.time = q, v, t
        mujoco.mj_getState(model, data, out[s], spec)
    return out


ENGINE = MJXEngine()
