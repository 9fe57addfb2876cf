"""The one import of MJX (and JAX) in xval: ``jax_mjx()`` imports them on first use, and their versions.

`xval engines` lists this engine without paying for JAX's import; only whether both are installed is
checked here.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.metadata
import importlib.util
import io
import os
from typing import Any

from ours.files import cache_dir

if importlib.util.find_spec("jax") is None:
    raise ImportError("No module named 'jax' (MJX runs on JAX)")
if importlib.util.find_spec("mujoco.mjx") is None:
    raise ImportError("No module named 'mujoco.mjx' (the mujoco-mjx package)")


@functools.cache
def jax_mjx() -> tuple[Any, Any]:
    """(jax, mjx), imported on first use, JAX on the CPU unless JAX_PLATFORMS says otherwise."""
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    import jax

    _persistent_cache(jax)

    with contextlib.redirect_stdout(io.StringIO()):  # "Failed to import warp: ..." without warp-lang
        from mujoco import mjx
    return jax, mjx


def _persistent_cache(jax) -> None:
    """Keep JAX's compiled executables in ``<cache>/jax`` (xval's user cache directory, ``ours.files``),
    so a later process loads a stepping loop instead of compiling it again (3.7-11.9 s of CPU each).

    Every compile is kept, however quick (JAX's default keeps only those over 1 s). An explicit
    ``JAX_COMPILATION_CACHE_DIR`` in the environment wins. Called by :func:`jax_mjx`, once per process, before
    the first compile.
    """
    if not os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        jax.config.update("jax_compilation_cache_dir", str(cache_dir() / "jax"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


#: XLA options of every MJX compile here (:func:`compiled`). XLA's CPU fusion emitters (on by default in jaxlib
#: 0.10) make MJX's step cost grow exponentially with the body tree's depth: RK4 float64 steps of a planar
#: chain took 0.05 ms at 4 links, 5 ms at 6 and about 1 s at 8 with them (a one-second run of the chain of 8:
#: a quarter of an hour), and 0.18 ms at 8 without, whose compile is shorter too
#: (scripts/mjx_chain_gradients.py prints both).
COMPILER_OPTIONS: dict[str, Any] = {"xla_cpu_use_fusion_emitters": False}


def compiled(jax, function, *args) -> Any:
    """``jax.jit(function)`` lowered for ``args`` and compiled with COMPILER_OPTIONS (JAX's persistent cache
    keys on them too)."""
    return jax.jit(function).lower(*args).compile(COMPILER_OPTIONS)


#: The x64 mode JAX last traced in, in this process (trace_in).
_last_trace_x64: list[bool] = []


def trace_in(jax, x64: bool) -> None:
    """Call before a trace in this x64 mode (the adapter's stepping loop, gradients.py's forward mode): JAX's trace
    caches outlive a change of x64 mode, and an inner jit (MJX's RK4 calls jnp.tril) traced in float64 is
    reused in float32 and fails to lower, so the traces start afresh when the mode changes."""
    if _last_trace_x64 and _last_trace_x64[-1] != x64:
        jax.clear_caches()
    _last_trace_x64[:] = [x64]


def version() -> str:
    """``mujoco-mjx X, jax Y`` from the installed distributions' metadata."""
    return f"mujoco-mjx {importlib.metadata.version('mujoco-mjx')}, jax {importlib.metadata.version('jax')}"
