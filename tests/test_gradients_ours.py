"""ours' own derivatives (ours/sensitivity.py, engines/ours/gradients.py): its tangent-linear step for every
parameter (initial conditions, g, masses, lengths), self-consistent with differences of its own rollouts for every
cure and integrator, and correct against the reference where the step is. (tests/test_ours_tangent.py holds the
tangent-linear step to the complex step.)"""

from __future__ import annotations

import numpy as np
import pytest

import ours
from compare.gradients.measure import engine_case
from engines import registry
from engines.gradients import finite_difference_jacobian
from engines.reference.sensitivity import relative_error
from engines.scene.catalog import build
from ours.constraint import Pin, Rod
from ours.sensitivity import complex_step_sensitivities, forward_sensitivities

SCENES = {"bead": ("bead", {"duration": 1.0}, ["theta0", "omega0"]),
          "double-pendulum": ("double-pendulum", {"duration": 1.0}, ["theta1", "omega2"]),
          "chain-8": ("chain", {"n": 8, "duration": 1.0}, ["theta0"])}
#: The physical parameters of each scene (the model moves, not only the state).
PHYSICAL = {"bead": ["g", "radius", "m"], "double-pendulum": ["g", "m1", "m2", "l1", "l2"],
            "chain-8": ["g", "length", "mass"]}
#: Every cure with each of its integrators (ours.valid_pairs), lagrangian aside (its own kernel, not differentiated).
VARIANTS = [name for name in registry.resolve("ours/rattle")[0].variants if not name.startswith("lagrangian")]


def _own_and_rollouts(variant: str, key: str, dt: float = 1e-3, wrt: list[str] | None = None
                      ) -> tuple[np.ndarray, str, np.ndarray]:
    name, parameters, initial = SCENES[key]
    wrt = wrt or initial
    scene = build(name, parameters)
    engine, _ = registry.resolve(f"ours/{variant}")
    answer = engine.jacobian(scene, variant, None, dt, wrt)
    assert answer is not None
    return answer[0], answer[1], finite_difference_jacobian(engine, scene, variant, None, dt, wrt).jacobian


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_cure_and_integrator_is_self_consistent_on_the_double_pendulum(variant):
    """The tangent-linear step's Jacobian against central differences (with Richardson) of ours' own rollouts at dt 1e-3
    over 1 s: ≤ 1e-6, the issue's bar for an engine's own derivatives."""
    own, method, differences = _own_and_rollouts(variant, "double-pendulum")
    assert method == "analytic"
    assert relative_error(own, differences) <= 1e-6


@pytest.mark.parametrize("key", ["bead", "chain-8"])
@pytest.mark.parametrize("variant", ["baumgarte-rk4", "projection-symplectic-euler", "rattle"])
def test_self_consistent_on_the_bead_and_a_chain_of_8(key, variant):
    own, _, differences = _own_and_rollouts(variant, key)
    assert relative_error(own, differences) <= 1e-6


@pytest.mark.parametrize("key", list(SCENES))
@pytest.mark.parametrize("variant", ["baumgarte-rk4", "plain-midpoint", "projection-euler", "rattle"])
def test_physical_parameters_are_self_consistent(key, variant):
    """g, masses and lengths, which move ours' model as well as its state, by its own derivative: against
    differences of its own rollouts ≤ 1e-6 (measured 2e-12 to 3e-10)."""
    own, method, differences = _own_and_rollouts(variant, key, wrt=PHYSICAL[key])
    assert method == "analytic"
    assert relative_error(own, differences) <= 1e-6


def test_the_complex_run_is_the_real_run_bit_for_bit():
    """The real parts of the complex run are ours.simulate's final state exactly: the derivative is that of the
    run itself, every branch taken as there."""
    system = ours.System((1.0, 2.0), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0), Rod(0, 1, 0.5)))
    q0, v0 = np.array([[1.0, 0.0], [1.0, -0.5]]), np.array([[0.0, 0.3], [0.1, 0.0]])
    for method, integrator in (("baumgarte", "rk4"), ("projection", "euler"), ("rattle", "rattle")):
        run = ours.simulate(system, q0, v0, 2e-3, 300, 300, method=method, integrator=integrator)
        for sensitivities in (forward_sensitivities, complex_step_sensitivities):
            carried = sensitivities(system, q0, v0, np.ones((1, 2, 2)), np.zeros((1, 2, 2)), 2e-3, 300,
                                    method=method, integrator=integrator)
            assert carried.status == "ok"
            assert np.array_equal(carried.q, run.q[-1]) and np.array_equal(carried.v, run.v[-1])


@pytest.mark.parametrize("variant", ["baumgarte-rk4", "projection-rk4", "rattle"])
def test_ours_own_derivatives_are_correct_against_the_reference(variant):
    """Through engine_case: method analytic (g by the tangent-linear step too), self-consistency ≤ 1e-6, and the
    class correct: RK4 within 1e-6 of the reference, RATTLE (order 2) converging."""
    engine, _ = registry.resolve(f"ours/{variant}")
    case = engine_case(engine, variant, None, build("double-pendulum", {"duration": 1.0}), 1e-3,
                       ["theta1", "omega2", "g"])
    assert case.method == "analytic" and case.self_consistency is not None and case.self_consistency <= 1e-6
    assert case.klass == "correct"
    if variant.endswith("rk4"):
        assert case.error <= 1e-6


def test_the_complex_step_refuses_the_lagrangian_method_which_the_tangent_step_covers():
    system = ours.System((1.0,), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0),))
    with pytest.raises(ours.OursError, match="method 'lagrangian' .* use plain, baumgarte, projection or rattle"):
        complex_step_sensitivities(system, [[1.0, 0.0]], [[0.0, 0.0]], np.zeros((1, 1, 2)), np.zeros((1, 1, 2)),
                                   1e-3, 10, method="lagrangian")
    engine, _ = registry.resolve("ours/lagrangian-rk4")
    answer = engine.jacobian(build("bead", {}), "lagrangian-rk4", None, 1e-3, ["theta0"])
    assert answer is not None and answer[1] == "analytic"


@pytest.mark.parametrize("key", list(SCENES))
@pytest.mark.parametrize("variant", ["lagrangian-euler", "lagrangian-midpoint", "lagrangian-rk4"])
def test_the_lagrangian_method_is_self_consistent_for_every_parameter(key, variant):
    """Its tangent-linear step in link angles (ours/lagrangian_tangent.py), the directions taken into angles and
    back in closed form: against differences of its own rollouts ≤ 1e-6 (measured 2e-12 to 5e-10), initial
    conditions and physical parameters together; its real state is ours.simulate's bit for bit."""
    own, method, differences = _own_and_rollouts(variant, key, wrt=SCENES[key][2] + PHYSICAL[key])
    assert method == "analytic"
    assert relative_error(own, differences) <= 1e-6
    system = ours.System((1.0, 2.0), (0.0, -9.81), (Pin(0, (0.0, 0.0), 1.0), Rod(0, 1, 0.5)))
    q0, v0 = np.array([[1.0, 0.0], [1.0, -0.5]]), np.array([[0.0, 0.3], [0.1, 0.0]])
    integrator = variant.split("-")[1]
    run = ours.simulate(system, q0, v0, 2e-3, 300, 300, method="lagrangian", integrator=integrator)
    carried = forward_sensitivities(system, q0, v0, np.ones((1, 2, 2)), np.zeros((1, 2, 2)), 2e-3, 300,
                                    method="lagrangian", integrator=integrator)
    assert np.array_equal(carried.q, run.q[-1]) and np.array_equal(carried.v, run.v[-1])
