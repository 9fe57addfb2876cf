"""What ``xval run`` does before it imports numpy, scipy, numba or an engine.

Both measured with ``bench/bench_harness.py`` (the CPU a run costs around the physics).

Details: docs/running.md, "Module notes", ``compare/run/startup.py``.
"""

from __future__ import annotations

import gc
import os
import sys

#: Read by OpenBLAS when it loads (the only builds numpy and scipy ship on PyPI for Linux).
THREAD_VARIABLE = "OPENBLAS_NUM_THREADS"
#: Any of these set by the user is their choice of BLAS threads, kept (OpenBLAS reads each).
USER_VARIABLES = (THREAD_VARIABLE, "GOTO_NUM_THREADS", "OMP_NUM_THREADS")

#: Whether :func:`defer_collection` turned the collector off (so resume_collection turns it on).
_deferred = False


def load_blas_single_threaded() -> None:
    """Import numpy and scipy.linalg with OpenBLAS limited to one thread, unless already imported
    (then nothing changes) or the user chose a number of threads."""
    if "numpy" in sys.modules or any(name in os.environ for name in USER_VARIABLES):
        return
    os.environ[THREAD_VARIABLE] = "1"
    try:
        import numpy  # noqa: F401
        import scipy.linalg  # noqa: F401 - numba loads it (its np.linalg calls scipy's BLAS and LAPACK)
    finally:
        del os.environ[THREAD_VARIABLE]


def defer_collection() -> None:
    """Turn the garbage collector off until :func:`resume_collection` (a collector already off,
    by the program's own choice, is left as it is)."""
    global _deferred
    if gc.isenabled():
        gc.disable()
        _deferred = True


def resume_collection() -> None:
    """Turn the collector back on if :func:`defer_collection` turned it off."""
    global _deferred
    if _deferred:
        _deferred = False
        gc.enable()
