"""Per-step cost on the KUKA iiwa (7 revolute joints) in each engine that imports it, against MuJoCo's.

    .venv/bin/python bench/bench_models.py [--steps 2000] [--repeats 5]

No engine steps a model file through xval yet (the model scenes are still to
come), so a "step" here is what one explicit step of the arm costs in each
engine: one forward-dynamics evaluation a(q, v, tau) through xval's import of
the file (``engines.model.<engine>.load(...).forward``, the call ``xval model
check`` makes), followed by a symplectic-Euler update of (q, v) in numpy,
``--steps`` times from a sampled state with tau = 0. The time is thread CPU,
minimum of ``--repeats``; the ratio is to MuJoCo's in the same run. It
includes each engine's Python binding (setting the state, reading the
accelerations), which for one arm dominates the dynamics themselves.
Pinocchio (the reference of ``xval model check``) is printed beside.
ours is left out: it has no rigid-body model import yet (issue 35).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from compare.model.parity import read_description, sample_states  # noqa: E402
from engines.model.importers import ENGINES, REFERENCE, importer  # noqa: E402
from engines.model.loaded import Refused  # noqa: E402

MODEL = "pybullet_data:kuka_iiwa/model.urdf"
DT = 1e-3


def steps_seconds(loaded, q0: np.ndarray, v0: np.ndarray, steps: int, repeats: int) -> float:
    """Least thread CPU seconds of ``steps`` symplectic-Euler steps through ``loaded.forward``."""
    tau = np.zeros_like(q0)
    best = float("inf")
    for _ in range(repeats):
        q, v = q0.copy(), v0.copy()
        start = time.thread_time()
        for _ in range(steps):
            v = v + DT * loaded.forward(q, v, tau)
            q = q + DT * v
        best = min(best, time.thread_time() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    source, description = read_description(MODEL)
    reference = importer(REFERENCE).load(source, description)
    states = sample_states(description, reference, 1, 0)
    q0, v0 = states.q[0], states.v[0]
    print(f"{MODEL}: {len(q0)} joints; {args.steps} steps of dt {DT:g} s, thread CPU, least of {args.repeats}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    seconds: dict[str, float] = {}
    for name in (*ENGINES, REFERENCE):
        try:
            loaded = reference if name == REFERENCE else importer(name).load(source, description)
        except Refused as exc:
            print(f"  {name}: refused ({exc})")
            continue
        seconds[name] = steps_seconds(loaded, np.asarray(q0, float), np.asarray(v0, float), args.steps, args.repeats)
    peer = seconds.get("mujoco")
    print("| engine | µs per step | / mujoco |\n|---|---|---|")
    for name, s in seconds.items():
        ratio = f"{s / peer:.2f}" if peer else "–"
        print(f"| {name}{' (reference)' if name == REFERENCE else ''} | {s / args.steps * 1e6:.1f} | {ratio} |")
    print("| ours | – | – |  (no rigid-body model import yet: issue 35)")


if __name__ == "__main__":
    main()
