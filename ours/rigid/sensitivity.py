"""Forward sensitivities of a rigid-body run, d y(t) / d y(0) along given directions: by the tangent-linear step
(``forward_sensitivities``, ``ours.rigid.tangent``), and by complex step through the compiled step itself.

Each direction dy0 (13 nb,) starts ``ours.rigid.kernel.run`` (the real run's own loop and step, compiled a
second time for complex128 states and scratch; the model stays real) from y0 + i h dy0, h = 1e-30. Every
operation of the step is arithmetic that complex numbers carry (numpy's square root, sine and cosine; a pivot's
sign, a small angle and the projection's stop read real parts or magnitudes), so Im(y)/h is the derivative of
what the kernel computes, exact to round-off, with no difference taken; the real parts follow the real run
(every branch as there; they differ from it at most in the last bit, where a fused multiply-add meets a
complex product). Each direction costs one complex run; the tangent-linear step shares one real step among the
directions (ours' method), and this complex step is its independent check.

Both cover every method with every integrator. The projection's stop reads the real residual: along a direction
that pulls the joints apart, the derivative is that of the iterations the real run took.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ours.errors import OursError
from ours.method import DEFAULT_MAX_ITERATIONS
from ours.rigid.model import Mechanism
from ours.rigid.simulate import DEFAULT_TOLERANCE, Prepared, _kernel, pack, prepare, workspace
from ours.status import NON_FINITE, OK, STATUS_TEXT

#: The complex step's size: far under any round-off of the state, and with no difference taken it costs nothing.
STEP = 1e-30


@dataclass(frozen=True, eq=False)
class RigidSensitivities:
    """Samples of one run and its derivatives along k directions.

    t (S,) s; y (S, 13 nb) the states (ours.rigid.simulate's layout); dy (S, k, 13 nb) d y / d direction at
    each sample (per unit of the direction; NaN past an early stop); steps : steps taken; status : "ok", or why
    the run stopped early (as ours.rigid.simulate says)."""

    t: np.ndarray
    y: np.ndarray
    dy: np.ndarray
    steps: int
    status: str


def _prepared(mech: Mechanism, y0, dy0, dt: float, n_steps: int, sample_every: int, **options) -> tuple[Prepared, np.ndarray]:
    """The run's checked settings and the directions (k, 13 nb), checked."""
    run = prepare(mech, y0, dt, n_steps, sample_every, **options)
    directions = np.asarray(dy0, dtype=float)
    if directions.ndim != 2 or directions.shape[1] != run.y.size or len(directions) == 0 \
            or not np.isfinite(directions).all():
        raise OursError(f"dy0: expected k ≥ 1 directions of {run.y.size} finite numbers each, (k, 13 nb), "
                        f"got shape {directions.shape}")
    return run, directions


def _result(run: Prepared, y: np.ndarray, dy: np.ndarray, written: int, steps: int, status: int) -> RigidSensitivities:
    if status == OK and not (np.isfinite(y).all() and np.isfinite(dy[:written]).all()):
        status = NON_FINITE
    return RigidSensitivities(run.times(written), y, dy[:written], int(steps), STATUS_TEXT[int(status)])


def complex_step_sensitivities(mech: Mechanism, y0, dy0, dt: float, n_steps: int, sample_every: int = 1, *,
                          method: str = "baumgarte", integrator: str | None = None, k_s: float | None = None,
                          k_d: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
                          max_iterations: int = DEFAULT_MAX_ITERATIONS) -> RigidSensitivities:
    """:func:`forward_sensitivities` by complex step: one complex run per direction (its independent check)."""
    run, directions = _prepared(mech, y0, dy0, dt, n_steps, sample_every, method=method, integrator=integrator,
                                k_s=k_s, k_d=k_d, tolerance=tolerance, max_iterations=max_iterations)
    kernel, model = _kernel(), pack(mech)
    work = workspace(mech, run.stages, np.complex128)
    dy = np.full((run.n_samples, len(directions), run.y.size), np.nan)
    written, steps, status = 0, 0, OK
    for k, direction in enumerate(directions):
        z = run.y + 1j * STEP * direction
        out = np.full((run.n_samples, z.size), np.nan, dtype=complex)
        written, steps, status = kernel.run(*run.args, z, model, work, run.ks, run.kd, run.dt, run.n_steps,
                                            run.stride, run.tolerance, run.max_iterations, out)
        dy[:written, k] = out[:written].imag / STEP
    return _result(run, out[:written].real.copy(), dy, written, steps, status)


def forward_sensitivities(mech: Mechanism, y0, dy0, dt: float, n_steps: int, sample_every: int = 1, *,
                          method: str = "baumgarte", integrator: str | None = None, k_s: float | None = None,
                          k_d: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
                          max_iterations: int = DEFAULT_MAX_ITERATIONS) -> RigidSensitivities:
    """Run ``mech`` from y0 (13 nb,) as ours.rigid.simulate does with the same arguments, and carry the directions
    dy0 (k, 13 nb) along by the tangent-linear step (ours.rigid.tangent): one real run, each direction's derivative
    beside it, sampled as simulate samples. Every method and integrator."""
    run, directions = _prepared(mech, y0, dy0, dt, n_steps, sample_every, method=method, integrator=integrator,
                                k_s=k_s, k_d=k_d, tolerance=tolerance, max_iterations=max_iterations)
    from ours.rigid import tangent  # imports numba: only when a run needs it

    y, dy = run.y.copy(), directions.copy()
    work = workspace(mech, run.stages)
    tw = tangent.tangent_workspace(len(dy), len(mech.bodies), len(mech.joints), run.stages)
    out = np.full((run.n_samples, y.size), np.nan)
    dout = np.full((run.n_samples,) + dy.shape, np.nan)
    written, steps, status = tangent.run(*run.args, y, dy, pack(mech), work, tw, run.ks, run.kd, run.dt, run.n_steps,
                                         run.stride, run.tolerance, run.max_iterations, out, dout)
    return _result(run, out[:written], dout, written, steps, status)
