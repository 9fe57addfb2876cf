"""ours' rigid-body trajectories are those saved from the kernel before it was reshaped for speed, to round-off.

tests/golden/rigid_trajectories.npz holds every method × integrator of scripts/rigid_equivalence.py on the
compound double pendulum, a 6-link chain, a branching tree of every joint kind and the KUKA iiwa, at dt
1e-3 and 1e-2 s, as the kernel computed them before it was reshaped for small fixed blocks. The reshaped
kernel regroups sums (triangular solves, fused multiply-adds), so it differs in round-off: here the tree and
the KUKA are held to it (the script checks all four scenes:
``scripts/rigid_equivalence.py check tests/golden/rigid_trajectories.npz``).
"""

from __future__ import annotations

import rigid_equivalence as script  # scripts/ is on the tests' path (tests/conftest.py)
from conftest import ROOT


def test_rigid_trajectories_match_those_saved_before_the_speed_work():
    count, worst, _, failures = script.compare(ROOT / "tests" / "golden" / "rigid_trajectories.npz",
                                               names={"tree", "kuka"})
    assert count == 2 * 12 * 2  # two scenes × 3 methods × 4 integrators × 2 time steps
    assert failures == [], failures[:5]
    assert worst <= script.TOLERANCE
