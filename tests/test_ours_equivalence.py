"""ours' trajectories are today's as saved from main before the speed work (issue 20), to 1e-12 relative.

tests/golden/ours_trajectories.npz holds every ours variant × scene × dt of
scripts/ours_equivalence.py as computed by main at cf334d7. The double pendulum
runs through a kernel with every size a constant, the 8-link chain through the
per-dimension kernel and the spherical pendulum through a 3-D kernel, so each
path ours.specialize generates is held to the saved numbers. (The script checks
all five scenes: ``scripts/ours_equivalence.py check tests/golden/ours_trajectories.npz``.)
"""

from __future__ import annotations

import ours_equivalence as script  # scripts/ is on the tests' path (tests/conftest.py)
from conftest import ROOT


def test_trajectories_match_those_saved_from_main():
    count, worst, failures = script.compare(ROOT / "tests" / "golden" / "ours_trajectories.npz",
                                            scenes={"double-pendulum", "chain8", "spherical"})
    # 16 variants × 7 time steps on each planar scene; the 3-D one has no Lagrangian form (13 variants).
    assert count == 16 * 7 + 16 * 7 + 13 * 7
    assert failures == [], failures[:5]
    assert max(worst.values()) <= script.TOLERANCE
