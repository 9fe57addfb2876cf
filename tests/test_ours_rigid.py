"""ours on rigid bodies: every joint's rows against finite differences, the tree solve against a dense
one, and the physics: a torque-free body's flip, the compound pendulum's period, and the compound
double pendulum against an independent reduced-coordinate solution (tests/rigid_support.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ours import InvalidPair, ModelError, OursError
from ours.rigid import (
    ROWS, Body, Joint, Mechanism, angular_momentum, energy, frames, initial_state, joint_coordinates, pack,
    rotation_of, simulate, workspace,
)
from rigid_support import DOUBLE, G, branching_tree, chain, compound_double_pendulum, reduced_double_pendulum


def _two_links(kind: str, seed: int = 1) -> tuple[Mechanism, np.ndarray]:
    """Two bodies, joints world→a and a→b of ``kind`` at random frames, and a random state (off the manifold)."""
    rng = np.random.default_rng(seed)
    bodies = (Body("a", 1.3, rng.normal(size=3) * 0.1, np.diag([0.1, 0.2, 0.25])),
              Body("b", 0.7, rng.normal(size=3) * 0.1, np.diag([0.05, 0.06, 0.08])))
    joints = tuple(Joint(f"j{k}", kind, k - 1, k, rng.normal(size=3), rotation_of(rng.normal(size=4)),
                         rng.normal(size=3)) for k in range(2))
    y = rng.normal(size=26)
    for b in range(2):
        y[13 * b + 3:13 * b + 7] /= np.linalg.norm(y[13 * b + 3:13 * b + 7])
    return Mechanism(bodies, joints), y


def _rows(mech, y):
    from ours.rigid import kernel

    model, work = pack(mech), workspace(mech, 1)
    kernel.rotations(y, len(mech.bodies), work[0])
    kernel.joint_rows(y, model, work[0], work[1], work[2], work[3], work[4])
    return work[1].copy(), work[2].copy(), work[3].copy(), work[4].copy()


def _kinematic_rate(y):
    """ẏ's position part: (v, ½ (0, ω) ⊗ Q) per body, velocities held."""
    d = np.zeros_like(y)
    for o in range(0, y.size, 13):
        w, Q = y[o + 10:o + 13], y[o + 3:o + 7]
        d[o:o + 3] = y[o + 7:o + 10]
        d[o + 3] = -0.5 * w @ Q[1:]
        d[o + 4:o + 7] = 0.5 * (Q[0] * w + np.cross(w, Q[1:]))
    return d


def _J_times(mech, JA, JB, y):
    out = np.zeros((len(mech.joints), 6))
    for k, j in enumerate(mech.joints):
        out[k] = JB[k] @ y[13 * j.child + 7:13 * j.child + 13]
        if j.parent >= 0:
            out[k] += JA[k] @ y[13 * j.parent + 7:13 * j.parent + 13]
    return out


@pytest.mark.parametrize("kind", sorted(ROWS))
def test_rows_jacobian_and_velocity_product_match_finite_differences(kind):
    mech, y = _two_links(kind)
    m = ROWS[kind]
    C, JA, JB, gam = _rows(mech, y)
    e, d = 1e-6, _kinematic_rate(y)
    plus, minus = _rows(mech, y + e * d), _rows(mech, y - e * d)
    dC = (plus[0] - minus[0]) / (2 * e)
    assert np.abs(dC - _J_times(mech, JA, JB, y))[:, :m].max() < 1e-8  # Ċ = J u
    dJu = (_J_times(mech, plus[1], plus[2], y) - _J_times(mech, minus[1], minus[2], y)) / (2 * e)
    assert np.abs(dJu - gam)[:, :m].max() < 1e-8  # J̇u
    assert np.abs(gam[:, :m]).max() > 0.1  # not trivially zero


@pytest.mark.parametrize("kind", ["revolute", "prismatic"])
def test_initial_state_is_on_the_constraints_and_reads_back(kind):
    mech, _ = _two_links(kind, seed=2)
    y = initial_state(mech, {"j0": 0.3, "j1": -0.2}, {"j0": 0.5, "j1": 0.7})
    C, JA, JB, _ = _rows(mech, y)
    assert np.abs(C).max() < 1e-14 and np.abs(_J_times(mech, JA, JB, y)).max() < 1e-14
    q, v = joint_coordinates(mech, y)
    np.testing.assert_allclose(q, [0.3, -0.2], atol=1e-14)
    np.testing.assert_allclose(v, [0.5, 0.7], atol=1e-14)


def test_tree_solve_equals_a_dense_solve_on_a_branching_tree():
    """A root with three branches of mixed kinds: the O(n) elimination against numpy's dense KKT solve."""
    from ours.rigid import kernel

    rng = np.random.default_rng(3)
    mech = branching_tree(rng)
    bodies = mech.bodies
    y = initial_state(mech, {"j0": 0.4, "j2": 0.1, "j4": -0.3}, {"j0": 1.0, "j2": -0.5, "j4": 2.0})
    for b in range(6):  # spin the ball joints' children too: J u = 0 is not needed for the solve
        y[13 * b + 10:13 * b + 13] += rng.normal(size=3) * 0.1
    model, work = pack(mech), workspace(mech, 1)
    ydot = np.zeros_like(y)
    assert kernel.derivative(y, model, work, 3.0, 4.0, ydot) == 0
    C, JA, JB, gam = _rows(mech, y)
    rows = [(k, r) for k, j in enumerate(mech.joints) for r in range(ROWS[j.kind])]
    J = np.zeros((len(rows), 36))
    for n, (k, r) in enumerate(rows):
        j = mech.joints[k]
        J[n, 6 * j.child:6 * j.child + 6] = JB[k, r]
        if j.parent >= 0:
            J[n, 6 * j.parent:6 * j.parent + 6] = JA[k, r]
    _, R = frames(mech, y)
    M, f, u = np.zeros((36, 36)), np.zeros(36), np.zeros(36)
    for b, body in enumerate(bodies):
        Iw = R[b] @ body.inertia @ R[b].T
        w = y[13 * b + 10:13 * b + 13]
        M[6 * b:6 * b + 3, 6 * b:6 * b + 3] = body.mass * np.eye(3)
        M[6 * b + 3:6 * b + 6, 6 * b + 3:6 * b + 6] = Iw
        f[6 * b:6 * b + 3] = body.mass * mech.gravity
        f[6 * b + 3:6 * b + 6] = -np.cross(w, Iw @ w)
        u[6 * b:6 * b + 6] = y[13 * b + 7:13 * b + 13]
    c = np.array([-gam[k, r] - 3.0 * C[k, r] for k, r in rows]) - 4.0 * J @ u
    kkt = np.block([[M, J.T], [J, np.zeros((len(rows), len(rows)))]])
    dense = np.linalg.solve(kkt, np.concatenate([f, c]))[:36]
    ours = np.concatenate([ydot[13 * b + 7:13 * b + 13] for b in range(6)])
    np.testing.assert_allclose(ours, dense, rtol=0, atol=1e-11 * np.abs(dense).max())


# --- physics ------------------------------------------------------------------------------------

def _spinner():
    """A free body spun about its intermediate axis (moments 1, 2, 3 kg·m²), no gravity."""
    mech = Mechanism((Body("box", 1.0, np.zeros(3), np.diag([1.0, 2.0, 3.0])),), (), np.zeros(3))
    y0 = np.zeros(13)
    y0[3], y0[10:13] = 1.0, [0.01, 1.0, 0.0]
    return mech, y0


def test_torque_free_body_flips_about_its_intermediate_axis():
    mech, y0 = _spinner()
    run = simulate(mech, y0, 1e-3, 20_000, 100, method="plain", integrator="rk4")
    _, R = frames(mech, run.y)
    w_body = np.einsum("sji,sj->si", R[:, 0], run.y[:, 10:13])
    # growth rate sqrt((I2 − I1)(I3 − I2)/(I1 I3)) ω = 0.577/s: from 0.01 the flip comes within ~10 s
    assert w_body[:, 1].max() > 0.999 and w_body[:, 1].min() < -0.999
    assert np.abs(energy(mech, run.y) - energy(mech, y0)).max() < 1e-12
    assert np.abs(angular_momentum(mech, run.y) - angular_momentum(mech, y0)).max() < 1e-12


@pytest.mark.parametrize("integrator, order", [("euler", 1), ("symplectic-euler", 1), ("midpoint", 2), ("rk4", 4)])
def test_torque_free_body_conserves_energy_and_momentum_to_the_integrators_order(integrator, order):
    """Over the flip (10 s): angular momentum's error falls as dtᵖ; energy's at least as fast
    (midpoint's falls as dt³ on this problem)."""
    mech, y0 = _spinner()
    dts = [2e-2, 1e-2, 5e-3] if order == 4 else [4e-3, 2e-3, 1e-3]
    errors = []
    for dt in dts:
        n = int(round(10.0 / dt))
        end = simulate(mech, y0, dt, n, n, method="plain", integrator=integrator).y[-1]
        errors.append((abs(energy(mech, end) - energy(mech, y0)),
                       np.linalg.norm(angular_momentum(mech, end) - angular_momentum(mech, y0))))
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(slopes[:, 1] - order) < 0.3), slopes
    assert np.all(slopes[:, 0] > order - 0.3), slopes


@pytest.mark.parametrize("method", ["plain", "baumgarte", "projection"])
def test_compound_pendulum_small_oscillation_period(method):
    """T = 2π √((I_c + m d²)/(m g d)); at 1e-3 rad the amplitude correction (θ₀²/16) is 6e-8."""
    m, d, ic = 2.0, 0.3, 0.05
    body = Body("bob", m, [0.0, 0.0, -d], np.diag([ic, ic, 0.01]))
    mech = Mechanism((body,), (Joint("hinge", "revolute", -1, 0, axis=[0.0, 1.0, 0.0]),), [0.0, 0.0, -G])
    period = 2 * math.pi * math.sqrt((ic + m * d * d) / (m * G * d))
    dt = 1e-3
    run = simulate(mech, initial_state(mech, {"hinge": 1e-3}), dt, int(3 * period / dt), method=method)
    theta = joint_coordinates(mech, run.y)[0][:, 0]
    down = np.where((theta[:-1] > 0) & (theta[1:] <= 0))[0]
    crossings = run.t[down] + theta[down] / (theta[down] - theta[down + 1]) * dt
    assert len(crossings) >= 3
    assert np.diff(crossings).mean() == pytest.approx(period, rel=3e-7)


def _double_pendulum_errors(method, integrator, dts):
    mech = compound_double_pendulum()
    theta, omega = [0.9, -0.6], [0.3, 1.1]
    y0 = initial_state(mech, {"shoulder": theta[0], "elbow": theta[1]}, {"shoulder": omega[0], "elbow": omega[1]})
    times = np.linspace(0.0, 2.0, 51)
    reference = reduced_double_pendulum(theta, omega, 2.0, times)
    errors, joint_gap = [], []
    for dt in dts:
        n = int(round(2.0 / dt))
        run = simulate(mech, y0, dt, n, n // 50, method=method, integrator=integrator)
        assert run.status == "ok"
        origins, R = frames(mech, run.y)
        errors.append(np.linalg.norm(origins - reference, axis=-1).max())
        # the elbow's anchor on link 1 against link 2's frame origin (m)
        elbow_on_1 = origins[:, 0] + R[:, 0] @ np.array([0.0, 0.0, -DOUBLE["l1"]])
        joint_gap.append(np.linalg.norm(elbow_on_1 - origins[:, 1], axis=-1).max())
    return np.array(errors), np.array(joint_gap)


@pytest.mark.parametrize("method", ["baumgarte", "projection"])
def test_double_pendulum_rk4_matches_the_reduced_solution_to_fourth_order(method):
    errors, gap = _double_pendulum_errors(method, "rk4", [4e-3, 2e-3, 1e-3])
    assert errors[-1] <= 1e-9  # m, at dt 1e-3 over 2 s
    assert np.all(np.abs(np.log2(errors[:-1] / errors[1:]) - 4) < 0.3), errors
    if method == "projection":
        assert gap.max() <= 1e-10


def test_projection_holds_the_joints_with_symplectic_euler():
    errors, gap = _double_pendulum_errors("projection", "symplectic-euler", [2e-3, 1e-3])
    assert gap.max() <= 1e-10
    assert abs(np.log2(errors[0] / errors[1]) - 1) < 0.3


# --- bad input ----------------------------------------------------------------------------------

def test_rattle_and_lagrangian_are_refused_with_the_reason():
    mech = chain(2)
    y0 = initial_state(mech)
    with pytest.raises(InvalidPair, match="RATTLE is not offered for rigid bodies: its drift step needs a constant mass"):
        simulate(mech, y0, 1e-3, 1, method="rattle")
    with pytest.raises(InvalidPair, match="method 'lagrangian' .* does not apply to rigid bodies"):
        simulate(mech, y0, 1e-3, 1, method="lagrangian")
    with pytest.raises(OursError, match="integrator: unknown 'rk5'"):
        simulate(mech, y0, 1e-3, 1, integrator="rk5")


def test_bad_models_are_refused_naming_the_field():
    with pytest.raises(ModelError, match="body b: mass must be positive"):
        Body("b", -1.0)
    with pytest.raises(ModelError, match="body b: inertia must be positive definite"):
        Body("b", 1.0, inertia=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ModelError, match="joint j: kind 'screw' is not one of revolute, prismatic, fixed, ball"):
        Joint("j", "screw", -1, 0)
    body = Body("b", 1.0)
    twice = (Joint("j0", "fixed", -1, 0), Joint("j1", "fixed", -1, 0))
    with pytest.raises(ModelError, match="body b is already the child of joint j0; loops are not supported"):
        Mechanism((body,), twice)
    with pytest.raises(ModelError, match=r"q\.elbo: no revolute or prismatic joint of that name"):
        initial_state(compound_double_pendulum(), {"elbo": 0.1})


def test_a_free_spin_about_a_hinge_reads_back_unwrapped():
    """No gravity: the hinge turns at its initial rate, so θ(t) = θ₀ + ω t past several turns."""
    body = Body("wheel", 2.0, [0.0, 0.0, -0.1], np.diag([0.03, 0.05, 0.02]))
    mech = Mechanism((body,), (Joint("hinge", "revolute", -1, 0, axis=[0.0, 1.0, 0.0]),), np.zeros(3))
    run = simulate(mech, initial_state(mech, {"hinge": 0.5}, {"hinge": 10.0}), 1e-3, 2000, 10, method="projection")
    q, v = joint_coordinates(mech, run.y)
    np.testing.assert_allclose(q[:, 0], 0.5 + 10.0 * run.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v[:, 0], 10.0, rtol=0, atol=1e-9)


def test_written_out_blocks_are_what_their_generator_writes():
    """ours/rigid/blocks.py is generated (python -m ours.rigid.generate): an edit by hand, or a generator
    changed without rewriting the file, fails here."""
    from ours.rigid import generate, kernel

    assert generate.TARGET.read_text(encoding="utf-8") == generate.source()
    assert kernel.BLOCKS_DIGEST == generate.digest(generate.source())  # numba's cache of the kernel follows


def test_paired_folds_give_the_single_folds_results_bit_for_bit():
    """The elimination folds two independent joints at once (ours.rigid.generate's fold_pair): on a free body
    with two siblings of every kind, and two grandchildren on different parents, every joint is folded in a
    pair, and the derivative (u̇ and λ) is the one the single folds give, bit for bit."""
    from ours.banded import compiled_fma
    from ours.rigid import blocks, kernel

    @compiled_fma
    def single_folds(y, model, work, ks, kd, ydot):
        """kernel.derivative with every joint folded alone, in the same order."""
        nb, kind, parent, child, order, free = model[0].shape[0], model[4], model[5], model[6], model[12], model[13]
        kernel.rotations(y, nb, work[0])
        kernel.joint_rows(y, model, work[0], work[1], work[2], work[3], work[4])
        kernel.forces(y, model, work)
        kernel.row_targets(y, model, work, ks, kd)
        kernel.assemble(model, work)
        JA, JB, D, X, x = work[2], work[3], work[5], work[6], work[7]
        for idx in range(order.shape[0]):
            k = order[idx]
            A, B, t = parent[k], child[k], kind[k]
            if t == kernel.REVOLUTE:
                blocks.fold_sweep_revolute(D, X, JA, JB, x, nb, k, A, B)
            elif t == kernel.PRISMATIC:
                blocks.fold_sweep_prismatic(D, X, JA, JB, x, nb, k, A, B)
            elif t == kernel.BALL:
                blocks.fold_sweep_ball(D, X, JA, JB, x, nb, k, A, B)
            else:
                blocks.fold_sweep_fixed(D, X, JA, JB, x, nb, k, A, B)
        for idx in range(free.shape[0]):
            b = free[idx]
            kernel._cholesky(D, b, 6)
            kernel._forward(D, b, 6, x, b, 0)
            kernel._backward(D, b, 6, x, b, 0)
        kernel.sweep_up(model, work, x)
        kernel.rates(y, model, work, ydot)

    rng = np.random.default_rng(7)
    kinds = ["revolute", "revolute", "ball", "ball", "prismatic", "prismatic", "fixed", "fixed", "revolute", "revolute"]
    parents = [0, 0, 0, 0, 0, 0, 0, 0, 1, 2]
    bodies = tuple(Body(f"b{i}", 0.5 + i * 0.1, rng.normal(size=3) * 0.1, np.diag([0.01, 0.02, 0.025]) * (1 + i))
                   for i in range(11))
    joints = tuple(Joint(f"j{i}", kinds[i], parents[i], i + 1, rng.normal(size=3) * 0.3,
                         rotation_of(rng.normal(size=4)), rng.normal(size=3)) for i in range(10))
    mech = Mechanism(bodies, joints)
    model = pack(mech)
    order, parent, child = model[12], model[5], model[6]
    assert [kinds[k] for k in order] == ["revolute"] * 2 + kinds[:8]  # deepest first, siblings side by side
    assert all(parent[order[i]] != child[order[i + 1]] for i in range(0, 10, 2))  # so every joint is in a pair
    y = initial_state(mech, {"j0": 0.4, "j4": 0.1, "j8": -0.3}, {"j0": 1.0, "j5": -0.5, "j9": 2.0})
    y[10:13] += rng.normal(size=3)  # the free root turns
    paired, single = np.zeros_like(y), np.zeros_like(y)
    work = workspace(mech, 1)
    assert kernel.derivative(y, model, work, 3.0, 4.0, paired) == 0
    lam = work[8].copy()
    work = workspace(mech, 1)
    single_folds(y, model, work, 3.0, 4.0, single)
    assert np.array_equal(paired, single) and np.array_equal(lam, work[8])
    assert np.abs(paired).max() > 0 and np.abs(lam).max() > 0
