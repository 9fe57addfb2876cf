"""Mechanisms shared by the rigid-body tests and scripts, and an independent reduced-coordinate
double pendulum (its Lagrangian written out by hand, integrated by scipy's DOP853)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from ours.rigid import Body, Joint, Mechanism, rotation_of

G = 9.81
#: The compound double pendulum: two links hinged about y, hanging along −z; link i has mass m,
#: COM c below its joint, inertia I (about y through the COM); the second joint is l1 below the first.
DOUBLE = dict(m1=1.0, c1=0.25, I1=0.02, l1=0.5, m2=0.8, c2=0.2, I2=0.012)


def compound_double_pendulum(p=DOUBLE) -> Mechanism:
    bodies = (Body("link1", p["m1"], [0.0, 0.0, -p["c1"]], np.diag([p["I1"] * 1.1, p["I1"], 0.003])),
              Body("link2", p["m2"], [0.0, 0.0, -p["c2"]], np.diag([p["I2"] * 1.2, p["I2"], 0.002])))
    joints = (Joint("shoulder", "revolute", -1, 0, [0.0, 0.0, 0.0], np.eye(3), [0.0, 1.0, 0.0]),
              Joint("elbow", "revolute", 0, 1, [0.0, 0.0, -p["l1"]], np.eye(3), [0.0, 1.0, 0.0]))
    return Mechanism(bodies, joints, [0.0, 0.0, -G])


def reduced_double_pendulum(theta, omega, t_end, times, p=DOUBLE):
    """Joint frames' origins (len(times), 2, 3) m from the reduced equations in absolute angles
    φ1 = θ1, φ2 = θ1 + θ2 (rad), the joint angles θ and rates ω given."""
    m1, c1, I1, l1, m2, c2, I2 = (p[k] for k in ("m1", "c1", "I1", "l1", "m2", "c2", "I2"))

    def rhs(_, s):
        f1, f2, w1, w2 = s
        cd, sd = np.cos(f1 - f2), np.sin(f1 - f2)
        M = np.array([[m1 * c1 ** 2 + I1 + m2 * l1 ** 2, m2 * l1 * c2 * cd], [m2 * l1 * c2 * cd, m2 * c2 ** 2 + I2]])
        b = np.array([-m2 * l1 * c2 * sd * w2 ** 2 - (m1 * c1 + m2 * l1) * G * np.sin(f1),
                      m2 * l1 * c2 * sd * w1 ** 2 - m2 * c2 * G * np.sin(f2)])
        return [w1, w2, *np.linalg.solve(M, b)]

    s0 = [theta[0], theta[0] + theta[1], omega[0], omega[0] + omega[1]]
    sol = solve_ivp(rhs, (0.0, t_end), s0, method="DOP853", rtol=1e-13, atol=1e-14, t_eval=times)
    f1 = sol.y[0]
    out = np.zeros((len(times), 2, 3))
    out[:, 1, 0], out[:, 1, 2] = -l1 * np.sin(f1), -l1 * np.cos(f1)
    return out


def chain(n: int, kind: str = "revolute") -> Mechanism:
    """n identical links (1 kg, 0.1 m) hung from the world, each hinged about y below the previous."""
    bodies = tuple(Body(f"link{i}", 1.0, [0.0, 0.0, -0.05], np.diag([1e-3, 1e-3, 2e-4])) for i in range(n))
    joints = tuple(Joint(f"j{i}", kind, i - 1, i, [0.0, 0.0, 0.0 if i == 0 else -0.1], np.eye(3), [0.0, 1.0, 0.0])
                   for i in range(n))
    return Mechanism(bodies, joints, [0.0, 0.0, -G])


def branching_tree(rng: np.random.Generator) -> Mechanism:
    """A root with three branches of every joint kind (revolute, ball, prismatic, fixed) at random frames and
    masses drawn from ``rng`` (tests/test_ours_rigid.py's dense-solve check, scripts/rigid_equivalence.py)."""
    kinds = ["revolute", "ball", "prismatic", "fixed", "revolute", "ball"]
    parents = [-1, 0, 0, 1, 0, 4]
    bodies = tuple(Body(f"b{i}", 0.5 + i * 0.1, rng.normal(size=3) * 0.1, np.diag([0.01, 0.02, 0.025]) * (1 + i))
                   for i in range(6))
    joints = tuple(Joint(f"j{i}", kinds[i], parents[i], i, rng.normal(size=3) * 0.3, rotation_of(rng.normal(size=4)),
                         rng.normal(size=3)) for i in range(6))
    return Mechanism(bodies, joints)
