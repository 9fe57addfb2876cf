"""ours' curve constraints (Line, Ellipse): C, J and J̇q̇ against finite differences, and the compiled loop.

The compiled loop's curve kinds (``ours.kernel``) must agree with the numpy
closed forms of ``ours.constraint`` (the dense λ formula), and an Ellipse with
a = b must give the Wire's trajectory to round-off, for every method and
integrator family.
"""

from __future__ import annotations

import numpy as np
import pytest

import ours
from engines.scene import catalog
from engines.ours.adapter import ENGINE
from engines.reference.reference import solve

CURVES = [
    ours.Line(0, (0.3, -0.2), (2.0, 1.0)),
    ours.Line(1, (0.0, 0.0), (1.0, 0.0)),
    ours.Ellipse(0, (0.1, -0.4), (1.3, 0.6)),
    ours.Ellipse(1, (0.0, 0.0), (0.7, 0.7)),
]


@pytest.mark.parametrize("constraint", CURVES, ids=lambda c: f"{type(c).__name__}-{c.particle}")
def test_jacobian_and_jdot_match_finite_differences(constraint):
    rng = np.random.default_rng(7)
    q, v = rng.normal(size=(2, 2)), rng.normal(size=(2, 2))
    h = 1e-6
    numeric = np.zeros_like(q)
    for p in range(2):
        for a in range(2):
            dq = np.zeros_like(q)
            dq[p, a] = h
            numeric[p, a] = (constraint.value(q + dq) - constraint.value(q - dq)) / (2 * h)
    np.testing.assert_allclose(constraint.jacobian(q), numeric, rtol=0, atol=1e-9)
    # J̇q̇ = d/dt (J(q + t v) · v) at t = 0.
    jv = lambda t: float((constraint.jacobian(q + t * v) * v).sum())  # noqa: E731
    assert constraint.jdot_qdot(q, v) == pytest.approx((jv(h) - jv(-h)) / (2 * h), abs=1e-8)


def test_curve_fields_are_validated_naming_the_field():
    with pytest.raises(ours.ModelError, match=r"^Line\.direction: must be a nonzero vector"):
        ours.Line(0, (0.0, 0.0), (0.0, 0.0))
    with pytest.raises(ours.ModelError, match=r"^Ellipse\.semi_axes\[1\]: must be a positive length in m, got 0\.0"):
        ours.Ellipse(0, (0.0, 0.0), (1.0, 0.0))
    with pytest.raises(ours.ModelError, match=r"curve constraints are planar \(2-D systems\); give 2 numbers"):
        ours.Line(0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    with pytest.raises(ours.ModelError, match=r"^method 'lagrangian' needs a planar \(2-D\) chain"):
        system = ours.System((1.0,), (0.0, -9.81), (ours.Line(0, (0.0, 0.0), (1.0, 0.0)),))
        ours.simulate(system, [[0.0, 0.0]], [[1.0, 0.0]], 1e-3, 10, method="lagrangian")


@pytest.mark.parametrize("k_s, k_d", [(0.0, 0.0), (100.0, 20.0)])
def test_compiled_curve_kinds_agree_with_the_numpy_closed_forms(k_s, k_d):
    """λ from the compiled banded solve against the dense numpy formula, off the curves (so that C and Ċ,
    fed back by Baumgarte, are not zero): the kernel's C, g, J̇q̇ and Ċ of each kind are the closed forms'."""
    rng = np.random.default_rng(3)
    systems = [
        ours.System((2.0, 1.0), (0.0, -9.81), (ours.Line(0, (0.1, -0.2), (1.0, 0.4)), ours.Rod(0, 1, 1.0))),
        ours.System((0.5,), (0.0, -9.81), (ours.Ellipse(0, (0.1, -0.4), (1.3, 0.6)),)),
        ours.System((1.0, 3.0), (0.0, -9.81), (ours.Ellipse(0, (0.0, 0.0), (0.8, 0.5)),
                                               ours.Line(1, (0.0, -1.0), (1.0, 0.0)))),
    ]
    for system in systems:
        for _ in range(5):
            q, v = rng.normal(size=(system.n_particles, 2)), rng.normal(size=(system.n_particles, 2))
            np.testing.assert_allclose(ours.multipliers(system, q, v, k_s, k_d),
                                       system.dense_multipliers(q, v, k_s, k_d), rtol=1e-12, atol=1e-12)


def test_dense_multipliers_are_the_general_formula():
    system = ours.System((2.0, 1.0), (0.0, -9.81), (ours.Line(0, (0.0, 0.0), (1.0, 0.0)), ours.Rod(0, 1, 1.0)))
    q = np.array([[0.2, 0.0], [0.2 + np.sin(0.5), -np.cos(0.5)]])
    v = np.array([[0.3, 0.0], [0.3 + 1.1 * np.cos(0.5), 1.1 * np.sin(0.5)]])
    lam = ours.multipliers(system, q, v)
    acc = (np.array(system.masses)[:, None] * np.array(system.gravity) + (system.jacobian(q).T @ lam).reshape(2, 2)) \
        / np.array(system.masses)[:, None]
    # The constrained acceleration satisfies C̈ = J a + J̇q̇ = 0 for both constraints.
    np.testing.assert_allclose(system.jacobian(q) @ acc.ravel() + system.jdot_qdot(q, v), 0.0, atol=1e-12)


@pytest.mark.parametrize(
    "variant",
    ["plain-rk4", "baumgarte-rk4", "projection-rk4", "rattle", "baumgarte-symplectic-euler", "projection-midpoint"],
)
def test_ellipse_with_equal_axes_runs_the_circle_bead_to_round_off(variant):
    for radius in (1.0, 0.7):
        bead = catalog.build("bead", {"radius": radius, "theta0": 60, "duration": 1})
        wire = catalog.build("bead-ellipse", {"a": radius, "b": radius, "theta0": 60, "duration": 1})
        circle, ellipse = ENGINE.simulate(bead, 1e-3, variant=variant), ENGINE.simulate(wire, 1e-3, variant=variant)
        np.testing.assert_allclose(ellipse.positions, circle.positions, rtol=0, atol=1e-13)
        np.testing.assert_allclose(ellipse.velocities, circle.velocities, rtol=0, atol=1e-13)
        np.testing.assert_allclose(ellipse.constraint_forces, circle.constraint_forces, rtol=0, atol=1e-12)


@pytest.mark.parametrize("variant, order", [("baumgarte-rk4", 4), ("projection-rk4", 4), ("rattle", 2)])
def test_curve_kinds_reach_each_integrators_order_on_the_ellipse(variant, order):
    scene = catalog.build("bead-ellipse", {"duration": 1})
    solution = solve(scene)
    errors = []
    for dt in (2e-2, 1e-2):
        run = ENGINE.simulate(scene, dt, variant=variant)
        errors.append(np.linalg.norm(run.positions - solution.at(run.t)[0], axis=2).max())
    assert np.log2(errors[0] / errors[1]) == pytest.approx(order, abs=0.35)
