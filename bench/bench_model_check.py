"""What `xval model check` of a 7-joint arm costs (target: at most 10 s at 100 states across all engines).

1. The whole command, `xval model check pybullet_data:kuka_iiwa/model.urdf --states 100
   --format json`, in a fresh process (engine imports included): wall time and CPU time
   (user + system of the child), median of REPEATS runs, with the machine's load.
2. In one process, engines already imported: per engine the time to load the file and to
   evaluate M, bias and forward dynamics at the 100 states, against Pinocchio's evaluation of
   the same states in the same run (the peer): the ratio says which engine's calls cost most.
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from compare.model.parity import evaluate, read_description, sample_states  # noqa: E402
from engines.model.importers import ENGINES, REFERENCE, importer  # noqa: E402

MODEL = "pybullet_data:kuka_iiwa/model.urdf"
STATES = 100
REPEATS = 3
XVAL = str(Path(sys.executable).parent / "xval")


def whole_command() -> None:
    walls, cpus = [], []
    for _ in range(REPEATS):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run([XVAL, "model", "check", MODEL, "--states", str(STATES), "--format", "json"],
                       check=True, capture_output=True)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    print(f"xval model check {MODEL} --states {STATES} (all engines), {REPEATS} runs, load {os.getloadavg()[0]:.1f}:")
    print(f"  wall s: median {statistics.median(walls):.2f} (runs {', '.join(f'{w:.2f}' for w in walls)})")
    print(f"  CPU s:  median {statistics.median(cpus):.2f} (runs {', '.join(f'{c:.2f}' for c in cpus)})")


def per_engine() -> None:
    source, model = read_description(MODEL)
    reference = importer(REFERENCE).load(source, model)
    states = sample_states(model, reference, STATES, 0)
    start = time.process_time()
    evaluate(reference, states)
    peer = time.process_time() - start
    print(f"\nper engine, {STATES} states, CPU s (ratio to Pinocchio's evaluation, {peer * 1e3:.1f} ms, this run):")
    print("| engine | load | evaluate | evaluate / Pinocchio |\n|---|---|---|---|")
    for name in ENGINES:
        module = importer(name)
        start = time.process_time()
        loaded = module.load(source, model)
        load = time.process_time() - start
        start = time.process_time()
        evaluate(loaded, states)
        spent = time.process_time() - start
        print(f"| {name} | {load * 1e3:.1f} ms | {spent * 1e3:.1f} ms | {spent / peer:.1f} |")


if __name__ == "__main__":
    whole_command()
    per_engine()
