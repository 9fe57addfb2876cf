"""RATTLE: velocity Verlet with SHAKE position projection and velocity projection.

Order 2, symplectic (with both projections). Point masses held by distance
constraints: a *pin* holds particle i at distance l from a fixed anchor, a
*rod* holds particles i and j at distance l. Knows nothing of xval: arrays
in, arrays out, SI units.

One step of size h (Andersen 1983; Hairer, Lubich & Wanner, GNI VII.1):

1. drift:  q* = q + h v + h²/2 g (gravity only);
2. SHAKE:  move q* along the constraint directions *at the start of the
   step* (r = qᵢ − qⱼ) until every |‖q*ᵢ − q*ⱼ‖² − l²| / 2l² < tolerance,
   one constraint at a time (Gauss–Seidel); v½ = (q* − q) / h;
3. kick:   v* = v½ + h/2 g;
4. RATTLE: move v* along the constraint directions at the new positions
   (d = qᵢ − qⱼ) until every |d · (vᵢ − vⱼ)| / (‖d‖ · speed) < tolerance.

Step 4 is what keeps energy bounded: without it the velocity keeps the
component along each rod that SHAKE removed from positions only, the kinetic
energy is off by O(h), and the energy error grows an order (try
``project_velocities=False``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Constraints:
    """Distance constraints, one row each.

    first : (C,) particle index; second : (C,) particle index, or -1 for a pin.
    anchors : (C, 3) m, a pin's fixed point (ignored for a rod); lengths : (C,) m.
    """

    first: np.ndarray
    second: np.ndarray
    anchors: np.ndarray
    lengths: np.ndarray


class Rattle:
    """The RATTLE stepper for point masses ``masses`` (P,) kg under gravity ``gravity`` (3,) m/s².

    tolerance : relative residual at which each projection stops (dimensionless).
    max_iterations : Gauss–Seidel sweeps per projection before giving up
        (the step goes on with the residual left; ``worst_residual`` keeps the largest).
    project_velocities : step 4 on (RATTLE) or off (SHAKE with a plain kick).
    """

    def __init__(self, masses: np.ndarray, constraints: Constraints, gravity: np.ndarray, *,
                 tolerance: float = 1e-12, max_iterations: int = 200, project_velocities: bool = True) -> None:
        self.w = 1.0 / np.asarray(masses, dtype=np.float64)  # inverse masses, 1/kg
        self.c = constraints
        self.g = np.asarray(gravity, dtype=np.float64)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.project_velocities = project_velocities
        self.worst_residual = 0.0
        # Python lists: per-constraint loops over small arrays are faster on scalars than on numpy rows.
        self._rows = [(int(i), int(j), self.w[i], self.w[j] if j >= 0 else 0.0, np.asarray(a), float(l))
                      for i, j, a, l in zip(constraints.first, constraints.second, constraints.anchors,
                                            constraints.lengths)]

    def forces_at(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(C, 3) N: the constraint forces on each constraint's first particle at the state q, v (P, 3).

        From the acceleration-level constraints J W Jᵀ λ = −J̇ v − J W m g, with
        Jacobian rows dₖ = qᵢ − qⱼ (C = ½(‖d‖² − l²)); the force on i is λₖ dₖ.
        The stepper needs none of this: it gives the t = 0 sample its forces.
        """
        n_p = len(self.w)
        jacobian = np.zeros((len(self._rows), n_p, 3))
        rhs = np.empty(len(self._rows))
        for k, (i, j, _, _, anchor, _) in enumerate(self._rows):
            d = q[i] - self._other(q, j, anchor)
            jacobian[k, i] += d
            dv = v[i].copy()
            if j >= 0:
                jacobian[k, j] -= d
                dv -= v[j]
            rhs[k] = -(dv @ dv)
        jacobian = jacobian.reshape(len(self._rows), 3 * n_p)
        w = np.repeat(self.w, 3)
        # Gravity accelerates every particle alike: J·g (per unit mass) is what is left after W m cancels.
        rhs -= jacobian @ np.tile(self.g, n_p)
        lam = np.linalg.solve((jacobian * w) @ jacobian.T, rhs)
        return np.array([lam[k] * (q[i] - self._other(q, j, a)) for k, (i, j, _, _, a, _) in enumerate(self._rows)])

    def _other(self, q: np.ndarray, j: int, anchor: np.ndarray) -> np.ndarray:
        return q[j] if j >= 0 else anchor

    def step(self, q: np.ndarray, v: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of size ``h`` (s) from q, v (P, 3) m, m/s.

        Returns the new q, v and the constraint forces (C, 3) N on each
        constraint's first particle at the end of the step (from the velocity
        projection; from SHAKE's correction when it is off).
        """
        q_new = q + h * v + 0.5 * h * h * self.g
        forces = np.zeros((len(self._rows), 3))
        for _ in range(self.max_iterations):
            worst = 0.0
            for k, (i, j, wi, wj, anchor, length) in enumerate(self._rows):
                r = q[i] - self._other(q, j, anchor)
                d = q_new[i] - self._other(q_new, j, anchor)
                residual = d @ d - length * length
                worst = max(worst, abs(residual) / (2 * length * length))
                gamma = residual / (2.0 * (wi + wj) * (d @ r))
                q_new[i] -= gamma * wi * r
                if j >= 0:
                    q_new[j] += gamma * wj * r
                # Used only without the velocity projection, where v still carries the normal
                # component −h/2·F/m it would have removed: SHAKE's m Δq is then the whole
                # step's h²·F, not h²/2·F.
                forces[k] -= gamma * r / (h * h)
            if worst < self.tolerance:
                break
        self.worst_residual = max(self.worst_residual, worst)
        v_new = (q_new - q) / h + 0.5 * h * self.g
        if not self.project_velocities:
            return q_new, v_new, forces
        forces[:] = 0.0
        speed = max(float(np.abs(v_new).max()), 1e-12)
        for _ in range(self.max_iterations):
            worst = 0.0
            for k, (i, j, wi, wj, anchor, length) in enumerate(self._rows):
                d = q_new[i] - self._other(q_new, j, anchor)
                dv = v_new[i] - (v_new[j] if j >= 0 else 0.0)
                along = d @ dv
                worst = max(worst, abs(along) / (length * speed))
                kappa = along / ((wi + wj) * (d @ d))
                v_new[i] -= kappa * wi * d
                if j >= 0:
                    v_new[j] += kappa * wj * d
                # v = v* + h/2 · F/m: the correction m Δv is h/2 · F.
                forces[k] -= 2.0 * kappa * d / h
            if worst < self.tolerance:
                break
        self.worst_residual = max(self.worst_residual, worst)
        return q_new, v_new, forces
