"""A "solver" whose code can be made less accurate without changing its id, options or version.

``SOLVER`` is the reference integrated at rtol = atol = 1e-6; with the
environment variable ``XVAL_TEST_SOLVER_REGRESSION=1`` it silently uses 1e-3,
as a careless edit of an internal constant would. The gate must catch that:
the case keys (scene, engine, variant, options, dt) and the engine version
are unchanged, only the numbers moved.
"""

from __future__ import annotations

import os
from typing import Any, Mapping

from engines.adapter import RawRun, Schedule
from engines.reference.reference import ReferenceEngine
from engines.scene.scene import Scene

#: Set to "1" to make SOLVER less accurate (read in the worker, so forked cases see it).
REGRESSION = "XVAL_TEST_SOLVER_REGRESSION"


class Solver(ReferenceEngine):
    name = "test-solver"
    options = {}
    variants = {"default": {}}
    variant_docs = {"default": "DOP853 at 1e-6 (1e-3 with XVAL_TEST_SOLVER_REGRESSION=1)"}

    def version(self) -> str:
        return "1.0"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        tolerance = 1e-3 if os.environ.get(REGRESSION) == "1" else 1e-6
        return super()._run(scene, schedule, {"rtol": tolerance, "atol": tolerance})


SOLVER = Solver()
