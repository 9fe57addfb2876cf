"""Point-mass inertia: PyBullet's multibody and MuJoCo's hinge model are one scheme, and the inertia is their floor.

Both step reduced coordinates with semi-implicit Euler; the only model
difference is the tiny rotational inertia each gives a point mass
(engines/pybullet/adapter.py, engines/mujoco/adapter.py, scripts/inertia_floor.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from compare.results.metrics import position_error
from engines.scene import catalog
from engines.mujoco.adapter import ENGINE as MUJOCO
from engines.pybullet.adapter import ENGINE as PYBULLET
from engines.reference.reference import solve

#: A mild double pendulum: small enough angles that 2 s of semi-implicit Euler is in its asymptotic range.
MILD = {"theta1": 30.0, "theta2": 20.0, "duration": 2.0}


@pytest.fixture(scope="module")
def mild():
    scene = catalog.build("double-pendulum", MILD)
    return scene, solve(scene)


def test_multibody_and_hinge_are_the_same_scheme_at_equal_inertia(mild):
    scene, _ = mild
    options = {"inertia_ratio": 1e-9}
    a = PYBULLET.simulate(scene, 1e-3, variant="multibody", options=options)
    b = MUJOCO.simulate(scene, 1e-3, variant="hinge", options=options)
    assert a.info.status == b.info.status == "ok"
    # Same semi-implicit Euler on the same model: round-off apart (measured 9e-16 m over 2 s).
    assert position_error(a.positions, b.positions).max() < 1e-12


def test_multibody_and_hinge_agree_at_their_defaults(mild):
    scene, reference = mild
    a = PYBULLET.simulate(scene, 1e-3, variant="multibody")
    b = MUJOCO.simulate(scene, 1e-3, variant="hinge")
    # Their defaults differ only in the inertia ratio (1e-9 against 1e-12): the floor is
    # ~18·ratio m on the double pendulum in 2 s (measured 8e-9 m), far below either's own
    # first-order error (1.3e-3 m): the two must report the same error to 1e-5 of it.
    between = position_error(a.positions, b.positions).max()
    assert between < 5e-8
    exact = reference.at(a.t)[0]
    err_a = position_error(a.positions, exact).max()
    err_b = position_error(b.positions, exact).max()
    assert abs(err_a / err_b - 1) < 1e-4


def test_multibody_is_first_order_on_the_mild_double_pendulum(mild):
    # At the former default (inertia 1e-4·m·L²) the inertia's own error (~7e-4 m here) masks the
    # integrator's below dt = 1e-3 and the observed order over this sweep falls to 0.33; at 1e-9
    # it is the scheme's 1.00 (MuJoCo hinge's too).
    scene, reference = mild
    dts = np.array([1e-3, 5e-4, 2.5e-4])
    errors = []
    for dt in dts:
        run = PYBULLET.simulate(scene, dt, variant="multibody")
        errors.append(position_error(run.positions, reference.at(run.t)[0]).max())
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert abs(slope - 1.0) < 0.15, f"observed order {slope:.2f}"


def test_a_millimetre_scene_gets_the_least_inertia_mujoco_compiles():
    # 1e-12 · m · L² is 1e-18 kg·m² for a 1 mm bead of 1 kg, below MuJoCo's absolute floor
    # (mjMINVAL = 1e-15): the adapter raises it to the floor instead of failing the run.
    scene = catalog.build("bead", {"radius": 1e-3, "duration": 0.2})
    run = MUJOCO.simulate(scene, 1e-4, variant="hinge-rk4")
    assert run.info.status == "ok", run.info.message
    assert min(run.info.settings["point_mass_inertia"]) > 1e-15
    reference = solve(scene).at(run.t)[0]
    # A ratio of ~1e-9 at this scale: the floor is ~2.6e-9 L (2.6e-12 m); RK4's own error is far below.
    assert position_error(run.positions, reference).max() < 1e-10
