"""Properties over random valid scenes (hypothesis): the catalog's geometry, serialization and the
reference's reduced coordinates agree with each other for any parameters, not just the defaults."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engines.scene import catalog
from engines.reference.reference import chain_model
from engines.scene.scene import Scene
from engines.scene.trajectory import constraint_errors

angles = st.floats(-179.0, 179.0)
lengths = st.floats(1e-3, 1e2)
masses = st.floats(1e-3, 1e3)
rates = st.floats(-20.0, 20.0)


@settings(max_examples=200, deadline=None)
@given(m1=masses, m2=masses, l1=lengths, l2=lengths, theta1=angles, theta2=angles, omega1=rates, omega2=rates)
def test_double_pendulum_round_trips_through_json_and_reduced_coordinates(m1, m2, l1, l2, theta1, theta2, omega1, omega2):
    scene = catalog.build("double-pendulum", {"m1": m1, "m2": m2, "l1": l1, "l2": l2, "theta1": theta1,
                                              "theta2": theta2, "omega1": omega1, "omega2": omega2})
    # Built on its constraints, whatever the scale.
    assert constraint_errors(scene, scene.initial_positions[None]).max() <= 1e-12 * (l1 + l2)
    again = Scene.from_dict(scene.to_dict())
    assert again == scene and again.content_hash == scene.content_hash
    # The reference reads back exactly the angles and rates the catalog was given.
    chain = chain_model(scene)
    state = chain.initial_state(scene)
    expected = [math.radians(theta1), math.radians(theta2), omega1, omega2]
    np.testing.assert_allclose(state, expected, rtol=1e-9, atol=1e-9)
    # And its forward map returns the catalog's positions and velocities.
    positions, velocities, _ = chain.evaluate(scene, state[None])
    np.testing.assert_allclose(positions[0], scene.initial_positions, rtol=0, atol=1e-12 * (l1 + l2))
    np.testing.assert_allclose(velocities[0], scene.initial_velocities, rtol=0,
                               atol=1e-12 * (l1 + l2) * (1 + abs(omega1) + abs(omega2)))


@settings(max_examples=50, deadline=None)
@given(m=masses, radius=lengths, theta0=angles, omega0=rates, g=st.floats(0.0, 100.0))
def test_content_hash_changes_with_every_physical_parameter(m, radius, theta0, omega0, g):
    base = {"m": m, "radius": radius, "theta0": theta0, "omega0": omega0, "g": g}
    reference = catalog.build("bead", base).content_hash
    for name, value in base.items():
        changed = dict(base, **{name: value + 0.25 + 0.5 * abs(value)})  # never a fixed point
        assert catalog.build("bead", changed).content_hash != reference, name
