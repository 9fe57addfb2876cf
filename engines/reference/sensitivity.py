"""The reference's sensitivities: variational equations integrated beside its own solve with DOP853.

For a planar chain (bead, double pendulum, chain) the state is y = (θ, θ̇) (absolute link angles, rad,
rad/s) and f(y, π) depends on π = (masses kg, lengths m, g_x, g_z m/s²). A scene parameter p moves y(0)
and π along a direction (y0', π') read from the catalog (:func:`parameter_directions`); S = ∂y/∂p solves

    Ṡ = ∂f/∂y · S + ∂f/∂π · π',   S(0) = y0',

and d outputs / dp = ∂h/∂y · S(T) + ∂h/∂π · π' (outputs: the CSV's p_x..z v_x..z per particle). Each
Jacobian-direction product is a complex step, f(y + i h s, π + i h π').imag / h with h = 1e-30, through a
complex-capable copy of the reference's right-hand side: exact to round-off, all k directions in one batch.
Columns are per SI unit of their parameter (per radian for an angle given in degrees). A model file's
sensitivities to q0, v0 use Pinocchio's analytic derivatives instead (ModelDynamics.derivatives).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from engines.errors import Unsupported
from engines.reference.reference import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    MIN_RTOL,
    TIGHTER,
    ChainModel,
    _solve_ivp,
    chain_model,
)
from engines.scene.parameters import (
    central_difference,
    check_wrt,
    output_columns,
    outputs_of,
    perturbed,
    si_scale,
)
from engines.scene.scene import Scene

#: The complex step (any h ≪ √ε|x| works; the derivative is exact to round-off).
COMPLEX_STEP = 1e-30
#: The reference's Jacobian is trusted while its two solves (tolerance and TIGHTER times tighter) agree to
#: this relative Frobenius difference, three decades under the 1e-6 an engine's Jacobian is judged to
#: (compare/gradients/measure.py). Past it, on the default double pendulum, the difference grows about tenfold
#: per 1.5 s (measured: 8.9-12.5 s at 1e-9 for five choices of parameters over 20 s, 11-19 s at 1e-7).
JACOBIAN_HORIZON = 1e-9


# -- the parameters --------------------------------------------------------------


@dataclass(frozen=True)
class ChainPoint:
    """A chain's reduced initial state and physical parameters, as one vector each.

    y0 : (2n,) rad, rad/s; physics : (2n + 2,) masses kg, lengths m, (g_x, g_z) m/s².
    """

    y0: np.ndarray
    physics: np.ndarray

    @classmethod
    def of(cls, scene: Scene) -> "ChainPoint":
        model = chain_model(scene)
        return cls(model.initial_state(scene), np.concatenate([model.masses, model.lengths, model.gravity]))


#: Relative step of the differences that read a direction from the catalog (its maps are linear:
#: the step only sets the round-off, ε / step ≈ 2e-12).
_DIRECTION_STEP = 1e-4


def parameter_directions(scene: Scene, wrt: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(dy0/dp (2n, k), dπ/dp (2n + 2, k)) per SI unit of each parameter of ``wrt``.

    The catalog's chain builders are linear in every real parameter (an angle, a rate, a mass, a length,
    g each set one or more entries of y0 or π), so a central difference of the built scenes gives the
    direction to round-off.
    """
    check_wrt(scene, wrt)
    dy, dpi = [], []
    for name in wrt:
        value = float(scene.parameters[name]) * si_scale(scene.name, name)
        h = _DIRECTION_STEP * max(1.0, abs(value))
        up, down = ChainPoint.of(perturbed(scene, name, h)), ChainPoint.of(perturbed(scene, name, -h))
        dy.append((up.y0 - down.y0) / (2 * h))
        dpi.append((up.physics - down.physics) / (2 * h))
    return np.array(dy).T, np.array(dpi).T


# -- the chain, complex-capable and batched over directions -----------------------------------


def chain_rhs(y: np.ndarray, physics: np.ndarray) -> np.ndarray:
    """dy/dt (k, 2n) for states y (k, 2n) and parameters π (k, 2n + 2); real or complex.

    The same equations as :func:`engines.reference.kernels.chain_rhs` (M θ̈ = G − S θ̇², with
    M_ij = μ_ij l_i l_j cos(θ_i − θ_j)), written with numpy so that complex numbers pass through.
    """
    n = y.shape[1] // 2
    theta, theta_dot = y[:, :n], y[:, n:]
    masses, lengths, gx, gz = physics[:, :n], physics[:, n:2 * n], physics[:, 2 * n], physics[:, 2 * n + 1]
    tail = np.cumsum(masses[:, ::-1], axis=1)[:, ::-1]  # μ_i = Σ_{k ≥ i} m_k
    mu = tail[:, np.maximum.outer(np.arange(n), np.arange(n))]  # μ_ij = μ_max(i, j)
    inertia = mu * lengths[:, :, None] * lengths[:, None, :]
    d = theta[:, :, None] - theta[:, None, :]
    m = inertia * np.cos(d)
    weight = tail * lengths
    b = weight * (gx[:, None] * np.cos(theta) + gz[:, None] * np.sin(theta))
    b = b - np.einsum("kij,kj->ki", inertia * np.sin(d), theta_dot**2)
    theta_ddot = np.linalg.solve(m, b[:, :, None])[:, :, 0]
    return np.concatenate([theta_dot, theta_ddot], axis=1)


def chain_outputs(model: ChainModel, y: np.ndarray, physics: np.ndarray) -> np.ndarray:
    """(k, 6P) outputs (:func:`output_columns`) for states y (k, 2n) and parameters π (k, 2n + 2)."""
    n = y.shape[1] // 2
    theta, theta_dot, lengths = y[:, :n], y[:, n:], physics[:, n:2 * n]
    sin, cos = np.sin(theta), np.cos(theta)
    x = np.cumsum(lengths * sin, axis=1) + model.anchor[0]
    z = np.cumsum(-lengths * cos, axis=1) + model.anchor[2]
    vx = np.cumsum(lengths * theta_dot * cos, axis=1)
    vz = np.cumsum(lengths * theta_dot * sin, axis=1)
    k, p = y.shape[0], len(model.order)
    zero = np.zeros((k, n), dtype=y.dtype)
    per_link = np.stack([x, zero + model.anchor[1], z, vx, zero, vz], axis=-1)  # (k, n, 6), link order
    out = np.zeros((k, p, 6), dtype=y.dtype)
    out[:, model.order] = per_link
    return out.reshape(k, 6 * p)


# -- the solve -------------------------------------------------------------------


@dataclass(frozen=True)
class Sensitivity:
    """The reference's Jacobian of the outputs w.r.t. ``wrt``, dense in time.

    columns : output names (m); wrt : parameter names (k); rtol, atol : DOP853's.
    n_steps, nfev : accepted steps and right-hand-side calls of the augmented solve.
    """

    scene: Scene
    model: Any  # ChainModel, or ModelDynamics for a model scene
    columns: list[str]
    wrt: list[str]
    point: ChainPoint
    directions: np.ndarray
    ode: Any
    rtol: float
    atol: float
    n_steps: int
    nfev: int

    def states(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(y (n_t, 2n), S (n_t, 2n, k)) at ``times`` (n_t,) s."""
        dense = self.ode(np.asarray(times, dtype=float)).T
        n2, k = len(self.point.y0), len(self.wrt)
        return dense[:, :n2], dense[:, n2:].reshape(len(dense), n2, k)

    def jacobian(self, times: np.ndarray) -> np.ndarray:
        """(n_t, m, k) d outputs / d parameters (SI) at ``times`` (n_t,) s."""
        ys, ss = self.states(times)
        if self.scene.is_model:  # the outputs are the state (q, v) itself
            return ss
        n_t, n2, k = ss.shape
        # All samples and directions in one batch of n_t·k complex evaluations, sample-major.
        y = np.repeat(ys, k, axis=0) + 1j * COMPLEX_STEP * ss.transpose(0, 2, 1).reshape(n_t * k, n2)
        physics = np.broadcast_to(self.point.physics + 1j * COMPLEX_STEP * self.directions.T,
                                  (n_t, k, len(self.point.physics))).reshape(n_t * k, -1)
        tangent = chain_outputs(self.model, y, physics).imag / COMPLEX_STEP  # (n_t·k, m)
        return tangent.reshape(n_t, k, -1).transpose(0, 2, 1)


def solve_sensitivity(scene: Scene, wrt: Sequence[str], rtol: float = DEFAULT_RTOL,
                      atol: float = DEFAULT_ATOL) -> Sensitivity:
    """Integrate the reference's state and its sensitivities to ``wrt`` over the scene's duration (DOP853).

    Unsupported for a scene the chain form cannot read (the sensitivities cover planar chains);
    UserError for a name of ``wrt`` that is not a real parameter of the scene.
    """
    if scene.is_model:
        return _solve_model(scene, list(wrt), rtol, atol)
    refusal = Unsupported(f"the reference's sensitivities cover planar chains (bead, double pendulum, chain) "
                          f"and model files; {scene.name!r} is neither")
    if not scene.is_planar:
        raise refusal
    try:
        model = chain_model(scene)
    except Unsupported:
        raise refusal from None
    wrt = list(wrt)
    dy0, dpi = parameter_directions(scene, wrt)
    point = ChainPoint.of(scene)
    n2, k = len(point.y0), len(wrt)

    def rhs(_t: float, w: np.ndarray) -> np.ndarray:
        y, s = w[:n2], w[n2:].reshape(n2, k)
        # One batched complex evaluation: its real part is f(y, π) itself, its imaginary part the k columns of Ṡ.
        args = (np.broadcast_to(y, (k, n2)) + 1j * COMPLEX_STEP * s.T,
                np.broadcast_to(point.physics, (k, len(point.physics))) + 1j * COMPLEX_STEP * dpi.T)
        value = chain_rhs(*args)
        return np.concatenate([value[0].real, (value.imag / COMPLEX_STEP).T.ravel()])

    w0 = np.concatenate([point.y0, dy0.ravel()])
    result = _solve_ivp()(rhs, (0.0, scene.duration), w0, method="DOP853", rtol=rtol, atol=atol, dense_output=True)
    if not result.success:
        raise RuntimeError(f"reference sensitivity integration failed: {result.message}")
    return Sensitivity(scene, model, output_columns(scene), wrt, point, dpi, result.sol, rtol, atol,
                       len(result.t) - 1, result.nfev)


def _solve_model(scene: Any, wrt: list[str], rtol: float, atol: float) -> Sensitivity:
    """A model scene's sensitivities to its q0 and v0: Ṡ = ∂f/∂y · S with y = (q, v) in xval's coordinates (a
    quaternion's four entries included) and ∂f/∂y from ModelDynamics.derivatives (the configuration rate's exactly,
    q̈'s by Pinocchio's computeABADerivatives mapped from its tangent space); S(0) = dy(0)/dp from the scene moved
    along each parameter (:func:`model_directions`); the outputs are (q, v), so J = S."""
    from engines.model.dynamics import ModelDynamics

    check_wrt(scene, wrt)
    dynamics = ModelDynamics(scene)
    y0 = dynamics.initial_state(scene)
    n2, k = len(y0), len(wrt)
    s0 = model_directions(scene, wrt)

    def rhs(_t: float, w: np.ndarray) -> np.ndarray:
        rate, jacobian = dynamics.derivatives(w[:n2])
        return np.concatenate([rate, (jacobian @ w[n2:].reshape(n2, k)).ravel()])

    result = _solve_ivp()(rhs, (0.0, scene.duration), np.concatenate([y0, s0.ravel()]), method="DOP853", rtol=rtol,
                          atol=atol, dense_output=True)
    if not result.success:
        raise RuntimeError(f"reference sensitivity integration failed: {result.message}")
    return Sensitivity(scene, dynamics, output_columns(scene), wrt, ChainPoint(y0, np.zeros(0)), np.zeros((0, k)),
                       result.sol, rtol, atol, len(result.t) - 1, result.nfev)


def model_directions(scene: Any, wrt: Sequence[str]) -> np.ndarray:
    """(nconfig + nv, k) dy(0)/dp: a model scene's initial (q, v) moved along each parameter of ``wrt``, by central
    differences with one Richardson step of the moved scenes (a unit vector for an entry moved by itself; for a
    quaternion turned by q0.J.rx: ½ Q ⊗ (e_x, 0), its sine and cosine O(h⁴) ≈ 1e-12 off at h = 1e-3)."""

    def state(name: str, delta: float) -> np.ndarray:
        moved = perturbed(scene, name, delta)
        return np.concatenate([moved.initial_q, moved.initial_v])

    return np.array([central_difference(lambda delta, name=name: state(name, delta), _MODEL_DIRECTION_STEP)
                     for name in wrt]).T


#: rad or SI units: the step of :func:`model_directions` (truncation h⁴ ≈ 1e-12, round-off ε/h ≈ 2e-13).
_MODEL_DIRECTION_STEP = 1e-3


def relative_error(jacobian: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """‖J − J_ref‖_F / ‖J_ref‖_F over the last two axes of (…, m, k) arrays (inf or NaN where J is, silently:
    a Jacobian that blew up is a class of its own, not a warning)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        diff = np.linalg.norm(np.asarray(jacobian) - reference, axis=(-2, -1))
        return diff / np.linalg.norm(reference, axis=(-2, -1))


@dataclass(frozen=True)
class SensitivityBound:
    """The reference's Jacobian solved twice, and what the difference says.

    loose : the solve at the given tolerances; sensitivity : the tighter one, the better answer.
    t : (n,) s; difference : (n,) relative Frobenius difference of the two Jacobians;
    error : the difference at the last sample; horizon : s, first sample with difference above
    JACOBIAN_HORIZON, or None; growth : (n,) ‖J(t)‖_F of the tighter solve.
    """

    loose: Sensitivity
    sensitivity: Sensitivity
    t: np.ndarray
    difference: np.ndarray
    error: float
    horizon: float | None
    growth: np.ndarray


def bound_sensitivity(scene: Scene, wrt: Sequence[str], rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL,
                      times: np.ndarray | None = None) -> SensitivityBound:
    """:func:`solve_sensitivity` at (rtol, atol) and TIGHTER times tighter, compared at ``times``
    (default every 0.01 s, at most 2001 samples)."""
    if times is None:
        times = np.linspace(0.0, scene.duration, min(2001, max(2, round(scene.duration / 0.01) + 1)))
    loose = solve_sensitivity(scene, wrt, rtol, atol)
    tight = solve_sensitivity(scene, wrt, max(rtol / TIGHTER, MIN_RTOL), atol / TIGHTER)
    a, b = loose.jacobian(times), tight.jacobian(times)
    with np.errstate(invalid="ignore", divide="ignore"):
        difference = np.nan_to_num(relative_error(a, b), nan=0.0)
    above = np.nonzero(difference > JACOBIAN_HORIZON)[0]
    horizon = float(times[above[0]]) if len(above) else None
    return SensitivityBound(loose, tight, times, difference, float(difference[-1]), horizon,
                            np.linalg.norm(b, axis=(1, 2)))


def reference_jacobian(scene: Scene, wrt: Sequence[str], time: float,
                       rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> np.ndarray:
    """(m, k) d outputs(time) / d parameters from the reference at (rtol, atol)."""
    return solve_sensitivity(scene, wrt, rtol, atol).jacobian(np.array([float(time)]))[0]


def finite_difference_reference(scene: Scene, wrt: Sequence[str], time: float, steps: Mapping[str, float] | None = None,
                                rtol: float = MIN_RTOL, atol: float = 1e-15) -> np.ndarray:
    """(m, k) the same Jacobian by central differences of whole reference solves with one Richardson step.

    An independent check of :func:`solve_sensitivity`: no variational equations, no complex step, the
    scene rebuilt from the catalog at p ± h and p ± h/2 (h = 1e-3 SI units unless ``steps`` says).
    """
    from engines.reference.reference import solve

    def out(s: Scene) -> np.ndarray:
        positions, velocities, _ = solve(s, rtol, atol).at(np.array([float(time)]))
        return outputs_of(positions, velocities)[0]

    return np.array([central_difference(lambda delta, name=name: out(perturbed(scene, name, delta)),
                                        (steps or {}).get(name, 1e-3)) for name in wrt]).T
