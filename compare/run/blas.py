"""Load the BLAS libraries of numpy and scipy with one thread each, before a run imports them.

OpenBLAS (numpy and scipy each bundle a copy) starts a thread per core as it
loads, and their start-up alone cost measurable CPU in every ``xval run``
(``bench/bench_harness.py``). A run has no use for them: its matrices are a
few rows, and its cores belong to the case hosts, whose timings other threads
would disturb. The limit is set through OpenBLAS's own environment variable
(it reads it only when it loads) for the duration of the imports, then the
environment is put back, so the programs a run starts (command engines) get
the one they were given. A limit the user set is kept.
"""

from __future__ import annotations

import os
import sys

#: Read by OpenBLAS when it loads (the only builds numpy and scipy ship on PyPI for Linux).
THREAD_VARIABLE = "OPENBLAS_NUM_THREADS"


def load_single_threaded() -> None:
    """Import numpy and scipy.linalg with OpenBLAS limited to one thread, unless already imported
    (then nothing changes) or the user chose a number of threads."""
    if "numpy" in sys.modules or THREAD_VARIABLE in os.environ:
        return
    os.environ[THREAD_VARIABLE] = "1"
    try:
        import numpy  # noqa: F401
        import scipy.linalg  # noqa: F401
    finally:
        del os.environ[THREAD_VARIABLE]
