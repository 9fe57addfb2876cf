"""``make demo``: simulate every catalog scene with the reference and print a short summary.

(Until the suite runner exists; then it runs ``suites/default.toml``.)
"""

from __future__ import annotations

import numpy as np

from engines import catalog
from engines.reference import ENGINE as REFERENCE
from engines.trajectory import max_constraint_error, total_energy


def main() -> None:
    print(f"{'scene':<20} {'samples':>8} {'steps':>7} {'time/s':>8} {'energy drift/E*':>16} {'constraint err/m':>17}")
    for name in catalog.scene_names():
        scene = catalog.build(name)
        trajectory = REFERENCE.simulate(scene, 1e-2)
        energy = total_energy(scene, trajectory.positions, trajectory.velocities)
        drift = np.max(np.abs(energy - energy[0])) / scene.characteristic_energy
        error = max_constraint_error(scene, trajectory.positions).max()
        info = trajectory.info
        print(f"{name:<20} {trajectory.n_samples:>8} {info.steps:>7} {info.wall_time:>8.3f} {drift:>16.2e} {error:>17.2e}")


if __name__ == "__main__":
    main()
