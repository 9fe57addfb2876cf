"""Record the timing samples of real runs as a test fixture: what tests/test_verdict_stability.py feeds the verdict.

    .venv/bin/python scripts/cost_samples.py RESULTS_DIR [RESULTS_DIR ...] > tests/fixtures/cost_samples.json

Per run, per case of the chosen variants (ok cases only): scene, variant, dt, max position error (m), the
reference's error bar (m), L (m), steps and the CPU time of each repeat (s). Each run directory is one
entry, so the fixture holds the run-to-run noise of a shared machine as it was.
"""

from __future__ import annotations

import json
import sys

from compare.results.cost import cpu_times, steps
from compare.run.results import load_results

#: The variants the fixture keeps: the ones the default suite's headline picks among.
VARIANTS = ("ours/lagrangian-rk4", "ours/projection-rk4", "ours/plain-rk4", "ours/lagrangian-midpoint",
            "mujoco/hinge-rk4", "mujoco/hinge", "pybullet/multibody", "pybullet/p2p-dantzig", "pymunk/pin-bias0")


def samples(directory: str) -> list[dict[str, object]]:
    """The kept cases of one results directory."""
    rows = []
    for record in load_results(directory).records:
        if record.case.engine not in VARIANTS or not record.ok or not cpu_times(record):
            continue
        rows.append({
            "scene": record.case.scene_id, "engine": record.case.engine, "dt": record.case.dt,
            "error": record.metric("position_error_linf"),
            "reference_error": (record.reference or {}).get("reference_error"),
            "length": record.characteristic.length, "steps": steps(record), "cpu_times": cpu_times(record),
        })
    return rows


def main(directories: list[str]) -> None:
    runs = [",\n".join(json.dumps(row) for row in samples(d)) for d in directories]
    sys.stdout.write('{"runs": [\n[\n' + "\n],\n[\n".join(runs) + "\n]\n]}\n")  # a case per line


if __name__ == "__main__":
    main(sys.argv[1:])
