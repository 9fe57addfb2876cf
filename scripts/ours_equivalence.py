"""ours' trajectories before and after a change: save them, or check today's against a saved file.

Runs ``ours.simulate`` for every variant of the ours adapter on the bead, the
double pendulum, chains of 4 and 8 links and the spherical pendulum (3-D), at
every time step of the default suite (1e-1 … 1e-4 s, two per decade), for 2 s
with a sample every 0.25 s (``OURS_EQ_SAMPLE``), and stores positions, velocities, multipliers,
steps taken and the status.

    .venv/bin/python scripts/ours_equivalence.py save tests/golden/ours_trajectories.npz
    .venv/bin/python scripts/ours_equivalence.py check tests/golden/ours_trajectories.npz

``check`` prints the largest relative difference per quantity (max |new − old| /
max |old| over a run, NaN where both are NaN counting as equal) and exits 1
when any exceeds 1e-12 or a status or step count differs.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import ours  # noqa: E402
from engines.scene import catalog  # noqa: E402
from engines.adapter import Schedule  # noqa: E402
from engines.ours.adapter import ENGINE, _to_system  # noqa: E402

SCENES = {
    "bead": ("bead", {"theta0": 60}),
    "double-pendulum": ("double-pendulum", {}),
    "chain4": ("chain", {"n": 4}),
    "chain8": ("chain", {"n": 8}),
    "spherical": ("spherical-pendulum", {}),
}
DTS = [10.0 ** (-k / 2) for k in range(2, 9)]
DURATION = 2.0
SAMPLE = float(os.environ.get("OURS_EQ_SAMPLE", "0.25"))  # s between stored samples
TOLERANCE = 1e-12


def runs(scenes=None):
    """Yield (key, arrays) for every scene (of ``scenes``, default all) × variant × dt."""
    for scene_id, (name, params) in SCENES.items():
        if scenes is not None and scene_id not in scenes:
            continue
        scene = catalog.build(name, {**params, "duration": DURATION})
        system, q0, v0, _ = _to_system(scene)
        for variant, settings in ENGINE.variants.items():
            if settings["method"] == "lagrangian" and system.why_not_a_chain() is not None:
                continue
            if settings["method"] == "lagrangian" and system.dim != 2:
                continue
            for dt in DTS:
                s = Schedule.make(DURATION, dt, SAMPLE)
                r = ours.simulate(system, q0, v0, s.dt, s.n_steps, s.stride, **settings)
                key = f"{scene_id}|{variant}|{dt:.6g}"
                yield key, {"q": r.q, "v": r.v, "lam": r.multipliers,
                            "meta": np.array([r.steps, ["ok", "non-finite", "singular", "not-converged"].index(r.status)])}


def _rel(new: np.ndarray, old: np.ndarray) -> float:
    if new.shape != old.shape:
        return np.inf
    same = (new == old) | (np.isnan(new) & np.isnan(old))
    with np.errstate(invalid="ignore"):
        diff = np.where(same, 0.0, np.abs(new - old))
    if np.isnan(diff).any():
        return np.inf
    finite = np.abs(old[np.isfinite(old)])
    scale = finite.max() if finite.size else 1.0
    return float(diff.max() / max(scale, 1e-300)) if diff.size else 0.0


def compare(path, scenes=None) -> tuple[int, dict[str, float], list[str]]:
    """(runs checked, largest relative difference per quantity, failures) against the file at ``path``."""
    old = np.load(path)
    worst = {"q": 0.0, "v": 0.0, "lam": 0.0}
    failures = []
    count = 0
    for key, arrays in runs(scenes):
        count += 1
        if not np.array_equal(arrays["meta"], old[f"{key}|meta"]):
            failures.append(f"{key}: steps/status {arrays['meta'].tolist()} != {old[f'{key}|meta'].tolist()}")
        for name in worst:
            rel = _rel(arrays[name], old[f"{key}|{name}"])
            worst[name] = max(worst[name], rel)
            if rel > TOLERANCE:
                failures.append(f"{key}: {name} differs by {rel:.3g} (relative)")
    return count, worst, failures


def save(path, runs) -> None:
    """Write every (key, arrays) of ``runs`` to the .npz at ``path`` (as ``key|name``) and say how many."""
    data, count = {}, 0
    for key, arrays in runs:
        count += 1
        data.update({f"{key}|{name}": a for name, a in arrays.items()})
    np.savez_compressed(path, **data)
    print(f"saved {count} runs to {path}")


def save_or_check(argv: list[str], usage: str, runs: Callable[[], Iterable[tuple[str, dict]]],
                  check: Callable[[str], tuple[str, list[str]]]) -> int:
    """The command line of an equivalence script: ``save PATH`` writes ``runs()`` to PATH (:func:`save`), exit 0;
    ``check PATH`` prints ``check(PATH)``'s summary line and its first 20 failures, exit 1 when there is one;
    anything else prints ``usage``, exit 2."""
    if len(argv) != 2 or argv[0] not in ("save", "check"):
        print(usage)
        return 2
    mode, path = argv
    if mode == "save":
        save(path, runs())
        return 0
    summary, failures = check(path)
    print(summary)
    for line in failures[:20]:
        print("  " + line)
    return 1 if failures else 0


def _check(path: str) -> tuple[str, list[str]]:
    count, worst, failures = compare(path)
    return (f"checked {count} runs; largest relative difference: "
            + ", ".join(f"{k} {v:.3g}" for k, v in worst.items())), failures


def main(argv: list[str]) -> int:
    return save_or_check(argv, __doc__ or "", runs, _check)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
