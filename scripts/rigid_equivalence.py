"""ours' rigid-body trajectories before and after a change of the kernel: save them, or check today's.

The rigid-body twin of scripts/ours_equivalence.py. Runs ``ours.rigid.simulate`` for every method ×
integrator pair on the compound double pendulum, a 6-link chain, a branching tree of every joint kind
(revolute, ball, prismatic, fixed) and the KUKA iiwa (pybullet_data, translated by engines/ours/model.py), at
dt 1e-3 and 1e-2 s for 0.5 s (a sample every 0.05 s), and stores the states, steps taken and status.

    .venv/bin/python scripts/rigid_equivalence.py save tests/golden/rigid_trajectories.npz
    .venv/bin/python scripts/rigid_equivalence.py check tests/golden/rigid_trajectories.npz

``check`` prints the largest relative difference of the states (max |new − old| / max |old| over a run)
and exits 1 when it exceeds TOLERANCE or a status or step count differs. A kernel that only reorders
independent operations reproduces the file bit for bit; one that regroups sums (a triangular solve
instead of a full one) differs in round-off, which the chaotic arm amplifies over the run's 500 steps.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))

from ours.rigid import Mechanism, initial_state, simulate, valid_pairs  # noqa: E402
from ours_equivalence import _rel, save_or_check  # noqa: E402  (_rel: max |new − old| / max |old|, NaN = NaN)
from rigid_support import branching_tree, chain, compound_double_pendulum  # noqa: E402

DTS = (1e-3, 1e-2)
DURATION = 0.5
SAMPLE = 0.05
#: Round-off amplified over a run: 1e-16 per step grows by the arm's Lyapunov factor over 0.5 s.
TOLERANCE = 1e-9
STATUS = ("ok", "non-finite", "singular", "not-converged")


def tree() -> tuple[Mechanism, np.ndarray]:
    """A root with three branches of every joint kind (tests/rigid_support.py), moving."""
    mech = branching_tree(np.random.default_rng(3))
    return mech, initial_state(mech, {"j0": 0.4, "j2": 0.1, "j4": -0.3}, {"j0": 1.0, "j2": -0.5, "j4": 2.0})


def kuka() -> tuple[Mechanism, np.ndarray]:
    """The KUKA iiwa from pybullet_data, q = 0.3 rad at every joint, at rest (bench/bench_rigid.py's start)."""
    from engines.ours.model import translate
    from engines.model.source import resolve
    from engines.model.urdf import read

    description = read(resolve("pybullet_data:kuka_iiwa/model.urdf"))
    mech = translate(description).mechanism
    return mech, initial_state(mech, {j.name: 0.3 for j in description.moving_joints})


def scenes() -> dict[str, tuple[Mechanism, np.ndarray]]:
    double = compound_double_pendulum()
    six = chain(6)
    return {"double": (double, initial_state(double, {"shoulder": 1.0, "elbow": -0.5}, {"elbow": 2.0})),
            "chain6": (six, initial_state(six, {f"j{i}": 0.1 for i in range(6)})),
            "tree": tree(), "kuka": kuka()}


def runs(names=None):
    """Yield (key, arrays) for every scene (of ``names``, default all) × method × integrator × dt."""
    for name, (mech, y0) in scenes().items():
        if names is not None and name not in names:
            continue
        for method, integrator in valid_pairs():
            for dt in DTS:
                n = int(round(DURATION / dt))
                r = simulate(mech, y0, dt, n, max(1, int(round(SAMPLE / dt))), method=method, integrator=integrator)
                yield f"{name}|{method}-{integrator}|{dt:g}", {"y": r.y, "meta": np.array([r.steps, STATUS.index(r.status)])}


def compare(path, names=None) -> tuple[int, float, int, list[str]]:
    """(runs checked, largest relative difference, runs bit-identical, failures) against the file at ``path``."""
    old = np.load(path)
    worst, identical, count, failures = 0.0, 0, 0, []
    for key, arrays in runs(names):
        count += 1
        if not np.array_equal(arrays["meta"], old[f"{key}|meta"]):
            failures.append(f"{key}: steps/status {arrays['meta'].tolist()} != {old[f'{key}|meta'].tolist()}")
        rel = _rel(arrays["y"], old[f"{key}|y"])
        worst = max(worst, rel)
        identical += rel == 0.0
        if rel > TOLERANCE:
            failures.append(f"{key}: y differs by {rel:.3g} (relative)")
    return count, worst, identical, failures


def _check(path: str) -> tuple[str, list[str]]:
    count, worst, identical, failures = compare(path)
    return (f"checked {count} runs; {identical} bit-identical; largest relative difference of the states "
            f"{worst:.3g} (tolerance {TOLERANCE:g})"), failures


def main(argv: list[str]) -> int:
    return save_or_check(argv, __doc__ or "", runs, _check)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
