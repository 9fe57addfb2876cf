"""ours, library level: the closed forms, the banded solve, and bad input. No engines/ import."""


import numpy as np
import pytest

import ours
from ours import InvalidPair, ModelError, OursError, Pin, Rod, System, Wire, simulate

G = 9.81


def planar_chain(n: int, seed: int, length: float = 0.25):
    """A chain of n links hung from the origin in 2-D at random angles and rates (on the constraints)."""
    rng = np.random.default_rng(seed)
    masses = rng.uniform(0.2, 2.0, n)
    theta, omega = rng.uniform(-np.pi, np.pi, n), rng.uniform(-3.0, 3.0, n)
    step = length * np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    rate = length * omega[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    q, v = np.cumsum(step, axis=0), np.cumsum(rate, axis=0)
    constraints = (Pin(0, (0.0, 0.0), length),) + tuple(Rod(k - 1, k, length) for k in range(1, n))
    return System(tuple(masses), (0.0, -G), constraints), q, v


def test_bead_closed_form_equals_the_general_solve():
    # λ = (−f·x − m ẋ·ẋ)/(x·x) against the banded J W Jᵀ solve, on states on and off the wire.
    rng = np.random.default_rng(3)
    for _ in range(20):
        m, r = rng.uniform(0.1, 5.0), rng.uniform(0.2, 3.0)
        centre = rng.normal(size=2)
        x = centre + rng.uniform(0.9, 1.1) * r * np.array([np.cos(a := rng.uniform(0, 6.3)), np.sin(a)])
        v = rng.normal(size=2)
        bead = System((m,), (0.0, -G), (Wire(0, tuple(centre), r),))
        general = ours.multipliers(bead, [x], [v])[0]
        closed = ours.bead_multiplier(x - centre, v, m, (0.0, -m * G))
        assert general == pytest.approx(closed, rel=1e-14, abs=1e-14)


def test_chain_solve_is_tridiagonal_and_equals_a_dense_solve():
    system, q, v = planar_chain(16, seed=1)
    assert system.packed.bandwidth == 1  # J W Jᵀ of a chain in order is tridiagonal
    banded = ours.multipliers(system, q, v)
    dense = system.dense_multipliers(q, v)
    np.testing.assert_allclose(banded, dense, rtol=1e-11, atol=1e-11 * np.abs(dense).max())


def test_feedback_terms_match_a_dense_solve_off_the_constraints():
    system, q, v = planar_chain(8, seed=2)
    q = q + np.random.default_rng(5).normal(scale=1e-2, size=q.shape)  # off C = 0 and Ċ = 0
    banded = ours.multipliers(system, q, v, k_s=100.0, k_d=20.0)
    dense = system.dense_multipliers(q, v, k_s=100.0, k_d=20.0)
    np.testing.assert_allclose(banded, dense, rtol=1e-11, atol=1e-11 * np.abs(dense).max())


def test_a_branched_3d_system_uses_a_wider_band_and_still_matches_dense():
    # A triangle of rods hung by two pins: constraints 0 and 4 share particle 0, so the band is 4 wide.
    q = np.array([[1.0, 0.0, -1.0], [0.0, 1.0, -1.2], [-0.5, -0.3, -1.6]])
    v = np.array([[0.1, 0.2, 0.0], [0.0, -0.3, 0.4], [0.2, 0.1, -0.1]])
    dist = lambda a, b: float(np.linalg.norm(q[a] - q[b]))
    constraints = (Pin(0, (0.0, 0.0, 0.0), float(np.linalg.norm(q[0]))), Rod(0, 1, dist(0, 1)),
                   Rod(1, 2, dist(1, 2)), Pin(2, (0.0, 0.0, 0.0), float(np.linalg.norm(q[2]))),
                   Rod(2, 0, dist(2, 0)))
    system = System((1.0, 2.0, 0.5), (0.0, 0.0, -G), constraints)
    assert system.packed.bandwidth == 4
    np.testing.assert_allclose(ours.multipliers(system, q, v), system.dense_multipliers(q, v), rtol=1e-11)


def test_constraint_closed_forms_match_finite_differences():
    system, q, v = planar_chain(3, seed=4)
    h = 1e-6
    J = system.jacobian(q)
    numeric = np.array([(system.values(q + h * e.reshape(q.shape)) - system.values(q - h * e.reshape(q.shape))) / (2 * h)
                        for e in np.eye(q.size)]).T
    np.testing.assert_allclose(J, numeric, atol=1e-8)  # central differences: error O(h²) ≈ 1e-12
    # J̇q̇ = d/dt (J q̇) along q̇ with q̇ held fixed.
    jdot = ((system.jacobian(q + h * v) - system.jacobian(q - h * v)) / (2 * h)) @ v.ravel()
    np.testing.assert_allclose(system.jdot_qdot(q, v), jdot, rtol=1e-8, atol=1e-8)


def test_every_integrator_states_order_and_symplecticity():
    expected = {"euler": (1, False), "symplectic-euler": (1, True), "midpoint": (2, False),
                "rk4": (4, False), "rattle": (2, True)}
    for name, (order, symplectic) in expected.items():
        scheme = ours.get_integrator(name)
        assert (scheme.order, scheme.symplectic) == (order, symplectic)
        assert scheme.doc.startswith(f"Order {order}, {'symplectic' if symplectic else 'not symplectic'}")


@pytest.mark.parametrize(
    "method, integrator, match",
    [
        ("rattle", "rk4", "its own integrator"),
        ("baumgarte", "rattle", "use it with method='rattle'"),
        ("lagrangian", "symplectic-euler", "not be symplectic"),
    ],
)
def test_invalid_pairs_are_errors_not_fallbacks(method, integrator, match):
    bead = System((1.0,), (0.0, -G), (Wire(0, (0.0, 0.0), 1.0),))
    with pytest.raises(InvalidPair, match=match):
        simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 1e-3, 10, method=method, integrator=integrator)


def test_valid_pairs_cover_every_method():
    pairs = ours.valid_pairs()
    assert ("rattle", "rattle") in pairs and ("lagrangian", "rk4") in pairs
    assert len(pairs) == 4 + 4 + 4 + 1 + 3


def test_bad_input_names_the_field_and_the_fix():
    bead = System((1.0,), (0.0, -G), (Wire(0, (0.0, 0.0), 1.0),))
    with pytest.raises(ModelError, match=r"q0: expected shape \(1, 2\)"):
        simulate(bead, [[1.0, 0.0, 0.0]], [[0.0, 0.0]], 1e-3, 10)
    with pytest.raises(OursError, match="dt: must be positive.*such as 1e-3"):
        simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], -1.0, 10)
    with pytest.raises(OursError, match="method: unknown 'shake'; choose one of: plain, baumgarte"):
        simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 1e-3, 10, method="shake")
    with pytest.raises(OursError, match="k_d: must be ≥ 0"):
        simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 1e-3, 10, k_d=-1.0)
    with pytest.raises(ModelError, match="masses: every mass must be positive"):
        System((0.0,), (0.0, -G))
    with pytest.raises(ModelError, match="Rod: a and b must be different"):
        Rod(1, 1, 1.0)
    with pytest.raises(ModelError, match="particle 3 is out of range"):
        System((1.0,), (0.0, -G), (Rod(0, 3, 1.0),))
    assert issubclass(OursError, ValueError)


def test_lagrangian_refuses_a_system_that_is_not_a_chain():
    loop = System((1.0, 1.0), (0.0, -G), (Rod(0, 1, 1.0),))
    with pytest.raises(ModelError, match="planar .* chain.*constraint 0 must fix particle 0|1 constraints for 2"):
        simulate(loop, [[0.0, 0.0], [1.0, 0.0]], np.zeros((2, 2)), 1e-3, 10, method="lagrangian")


def test_samples_include_the_last_step_and_the_status():
    bead = System((1.0,), (0.0, -G), (Wire(0, (0.0, 0.0), 1.0),))
    run = simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 1e-3, 25, 10, method="rattle")
    np.testing.assert_allclose(run.t, [0.0, 0.01, 0.02, 0.025], rtol=0, atol=1e-15)
    assert run.status == "ok" and run.steps == 25 and run.wall_time > 0
    assert run.q.shape == (4, 1, 2) and run.forces.shape == (4, 1, 2)


def test_a_run_that_blows_up_stops_and_says_why():
    # Explicit Euler with Baumgarte gains far past its stability limit (h·√k_s = 30).
    bead = System((1.0,), (0.0, -G), (Wire(0, (0.0, 0.0), 1.0),))
    run = simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 0.03, 10_000, method="baumgarte", integrator="euler",
                   k_s=1e6)
    assert run.status in ("non-finite", "singular") and run.steps < 10_000
    assert "smaller dt" in run.message or "singular" in run.message
