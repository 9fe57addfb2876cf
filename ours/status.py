"""Why a compiled loop stopped: codes shared by ``ours.kernel`` and ``ours.lagrangian`` (no numba here)."""

#: 0 = ran to the end; the others stop the run early (the samples up to then are kept).
OK, NON_FINITE, SINGULAR, NOT_CONVERGED = 0, 1, 2, 3

STATUS_TEXT = {OK: "ok", NON_FINITE: "non-finite", SINGULAR: "singular", NOT_CONVERGED: "not-converged"}
