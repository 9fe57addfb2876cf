"""Banded Cholesky factorization and solve for symmetric positive-definite matrices.

Storage: ``band[i, k]`` holds A[i, i − k] for k = 0..b (the lower band, row by
row); entries with i − k < 0 are unused. Factor and solve cost O(n·b²) and
O(n·b): for a chain of pins and rods J W Jᵀ is tridiagonal (b = 1), so a
solve is O(n). With b = n − 1 this is the ordinary dense Cholesky, which the
Lagrangian form uses for its mass matrix.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit


def _has_nrt_switch() -> bool:
    """Whether this numba accepts ``_nrt`` (checked on its option table: probing by compiling
    a function would cost a compilation at every import)."""
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # pragma: no cover - a numba that moved its options
        return False
    return hasattr(CPUTargetOptions, "_nrt")


#: The decorator of every compiled function in ours: cached on disk, and without
#: reference counting of arrays. With it, every call between compiled functions
#: increfs and decrefs each array argument (atomic operations), which measured
#: about 2x slower per step on the double pendulum. The price: compiled code must
#: not allocate, so callers pass in preallocated scratch arrays. ``_nrt`` is
#: numba's switch for this (an underscored option of numba 0.68's ``njit``),
#: passed as a dict: numba's type stubs leave the underscored option out. Without
#: it (another numba), the same results: the compiled code allocates nothing either way.
_NO_RUNTIME: dict[str, Any] = {"_nrt": False} if _has_nrt_switch() else {}
#: No C-callable wrapper (numba builds one per function, for calls through a function pointer, which
#: ours never makes: a sizeable part of a cold compile), and ``forceinline`` given explicitly: left
#: unset, a function would inherit it from whichever caller compiled it first.
_OPTIONS: dict[str, Any] = {"cache": True, "no_cfunc_wrapper": True, **_NO_RUNTIME}
compiled = njit(forceinline=False, **_OPTIONS)
#: ``inlined``: the same, but numba pastes the function's body into each caller (for the small
#: per-constraint functions called inside the step, where a call would copy every array argument).
inlined = njit(inline="always", forceinline=False, **_OPTIONS)
#: ``llvm_inlined``: compiled (typed) once, and LLVM pastes the machine-level body into every
#: caller (``alwaysinline``): no call copying every field of every array argument, for the price of
#: optimising each paste, which costs far less than ``inlined``'s typing of each paste again.
llvm_inlined = njit(forceinline=True, **_OPTIONS)
#: The same three with ``contract``: LLVM may fuse a multiply and the add that follows into one FMA
#: instruction where the CPU has one (one rounding instead of two), which moves results by round-off and
#: saves instructions. ours.rigid's kernel uses these (its trajectories stay within 3e-13 of the unfused
#: ones: scripts/rigid_equivalence.py); the particle kernel keeps the unfused ones, bit for bit.
_CONTRACT: dict[str, Any] = {"fastmath": {"contract"}, "error_model": "numpy"}
compiled_fma = njit(forceinline=False, **_CONTRACT, **_OPTIONS)
inlined_fma = njit(inline="always", forceinline=False, **_CONTRACT, **_OPTIONS)
llvm_inlined_fma = njit(forceinline=True, **_CONTRACT, **_OPTIONS)


@compiled
def cholesky_banded(band, n, b):
    """Factor A = L Lᵀ in place (L in ``band``); False when A is not positive definite.

    band : (n, b + 1) the lower band of A; n : its rows; b : bandwidth. (n is an
    argument so that a caller that knows it as a constant gets the loops unrolled.)
    """
    for i in range(n):
        lo = max(0, i - b)
        for j in range(lo, i + 1):
            s = band[i, i - j]
            # L[i, k] and L[j, k] are both inside the band only for k ≥ i − b.
            for k in range(lo, j):
                s -= band[i, i - k] * band[j, j - k]
            if j == i:
                # .real and np.sqrt, not math.sqrt: the same code on complex entries (ours.sensitivity's
                # complex step, whose real parts are this run's own), with no comparison on a perturbed part.
                if not s.real > 0.0:
                    return False
                band[i, 0] = np.sqrt(s)
            else:
                band[i, i - j] = s / band[j, 0]
    return True


@compiled
def solve_banded(band, n, b, x):
    """Solve L Lᵀ x = r in place (``x`` holds r on entry, n entries) with L from :func:`cholesky_banded`."""
    for i in range(n):
        s = x[i]
        for k in range(max(0, i - b), i):
            s -= band[i, i - k] * x[k]
        x[i] = s / band[i, 0]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, min(n, i + b + 1)):
            s -= band[k, k - i] * x[k]
        x[i] = s / band[i, 0]
