"""Drake's own derivatives: its plant converted by ``ToAutoDiffXd`` and stepped by the variant's fixed-step
integrator under ``Simulator_[AutoDiffXd]``.

The state x = (q, v) is seeded with ``InitializeAutoDiff`` (one derivative per state entry), so ``ExtractGradient``
of the final state is d x(T) / d x(0), forward-mode through every step of the integrator; the chain rule
(engines.gradients.chained_jacobian, with the adapter's own readout of the float plant) turns it into
d outputs(T) / d p for initial-condition parameters. g, masses and lengths change the plant, and get
central differences of rollouts. Error-controlled and discrete variants are left to differences of rollouts.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from engines.drake import library as drake
from engines.gradients import chained_jacobian, finite_difference_jacobian, is_initial_condition
from engines.scene.parameters import outputs_of
from engines.scene.scene import Scene


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str], schemes: Mapping[str, str]) -> tuple[np.ndarray, str] | None:
    """(J (6P, k), "autodiff") for a continuous fixed-step variant, else None. ``engine`` : Drake's adapter;
    schemes : its integrator option -> Drake's scheme name (ResetIntegratorFromFlags)."""
    if scene.is_model:  # a model's own derivatives are not chained here yet: differences of rollouts
        return None
    settings = engine.resolve(variant, options)
    if settings["plant"] != "continuous" or settings["error_control"]:
        return None
    initial = [name for name in wrt if is_initial_condition(scene, name)]
    if not initial:
        return None
    model = engine.build(scene, 0.0, settings)
    context = model.plant.CreateDefaultContext()
    model.set_initial_state(context)
    x0 = np.asarray(model.plant.GetPositionsAndVelocities(context), dtype=float)
    plant = model.plant.ToAutoDiffXd()
    simulator = drake.Simulator_[drake.AutoDiffXd](plant)
    ad_context = simulator.get_mutable_context()
    plant.SetPositionsAndVelocities(ad_context, drake.InitializeAutoDiff(x0))
    integrator = drake.ResetIntegratorFromFlags(simulator, schemes[settings["integrator"]], dt)
    integrator.set_fixed_step_mode(True)
    simulator.Initialize()
    simulator.AdvanceTo(max(1, round(scene.duration / dt)) * dt)
    end = plant.GetPositionsAndVelocities(ad_context)
    transition = np.asarray(drake.ExtractGradient(end), dtype=float)
    x_end = np.asarray(drake.ExtractValue(end), dtype=float).ravel()

    def readout(x: np.ndarray) -> np.ndarray:
        positions, velocities, _ = model.read(x[None, :])
        return outputs_of(positions[0], velocities[0])

    columns = dict(zip(initial, chained_jacobian(scene, initial, transition, readout, x0, x_end).T))
    physical = [name for name in wrt if name not in columns]
    if physical:
        differences = finite_difference_jacobian(engine, scene, variant, options, dt, physical).jacobian
        columns.update(zip(physical, differences.T))
    return np.array([columns[name] for name in wrt]).T, "autodiff"
