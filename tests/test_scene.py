"""The scene language: construction rules (one test per rule), serialization, hashing, the catalog."""

import math

import numpy as np
import pytest

from engines.scene import catalog
from engines.errors import SceneError
from engines.scene.scene import Particle, Pin, Rod, Scene


def pendulum(mass=1.0, position=(1.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0), length=1.0, duration=1.0):
    return Scene("p", (Particle(mass, position, velocity),), (Pin(0, (0, 0, 0), length),), duration=duration)


@pytest.mark.parametrize("mass", [0.0, -1.0, math.nan, math.inf])
def test_mass_must_be_positive_and_finite(mass):
    with pytest.raises(SceneError, match=r"^mass: must be positive and finite"):
        Particle(mass, (0, 0, 0))


@pytest.mark.parametrize("length", [0.0, -2.0, math.nan])
def test_constraint_length_must_be_positive_and_finite(length):
    with pytest.raises(SceneError, match=r"^length: must be positive and finite"):
        Pin(0, (0, 0, 0), length)
    with pytest.raises(SceneError, match=r"^length: must be positive and finite"):
        Rod(0, 1, length)


@pytest.mark.parametrize("duration", [0.0, -1.0, math.inf])
def test_duration_must_be_positive_and_finite(duration):
    with pytest.raises(SceneError, match=r"^duration: must be positive and finite"):
        pendulum(duration=duration)


def test_position_must_be_three_finite_numbers():
    with pytest.raises(SceneError, match=r"^position: must be three numbers"):
        Particle(1.0, (0.0, 1.0))
    with pytest.raises(SceneError, match=r"^position: every component must be finite"):
        Particle(1.0, (0.0, math.nan, 0.0))


def test_particle_index_out_of_range():
    with pytest.raises(SceneError, match=r"constraints\[0\]: particle index 3 is out of range \(the scene has particles 0..0\)"):
        Scene("p", (Particle(1, (1, 0, 0)),), (Pin(3, (0, 0, 0), 1.0),))


def test_rod_needs_two_particles():
    with pytest.raises(SceneError, match=r"rod: a and b must be different particles"):
        Rod(1, 1, 1.0)


def test_initial_state_must_satisfy_the_constraint():
    with pytest.raises(SceneError, match=r"constraints\[0\] \(pin\): the initial distance is 1.1 m but the length is 1 m"):
        pendulum(position=(1.1, 0.0, 0.0))


def test_initial_velocity_must_be_tangent():
    with pytest.raises(SceneError, match=r"constraints\[0\] \(pin\): the initial velocity has a component along"):
        pendulum(velocity=(0.5, 0.0, 0.0))


def test_scene_needs_a_particle():
    with pytest.raises(SceneError, match=r"particles: a scene needs at least one particle"):
        Scene("empty", (), ())


def test_constraint_within_tolerance_is_accepted():
    scene = pendulum(position=(1.0 + 1e-12, 0.0, 0.0))
    assert scene.constraints[0].length == 1.0


@pytest.mark.parametrize("name", catalog.scene_names())
def test_catalog_scene_round_trips_through_json(name):
    scene = catalog.build(name)
    again = Scene.from_dict(scene.to_dict())
    assert again == scene
    assert again.content_hash == scene.content_hash
    assert again.requires == scene.requires


def test_content_hash_follows_physics_not_labels():
    a = catalog.build("bead")
    b = Scene("renamed", a.particles, a.constraints, a.gravity, a.duration, {"note": 1})
    c = catalog.build("bead", {"m": 2})
    assert a.content_hash == b.content_hash
    assert a.content_hash != c.content_hash
    assert len(a.content_hash) == 16


def test_planar_and_3d_scenes_declare_what_they_require():
    assert catalog.build("double-pendulum").requires == frozenset()
    assert catalog.build("spherical-pendulum").requires == {"3d"}
    assert catalog.build("spherical-pendulum", {"phi_dot0": 0}).requires == frozenset()


def test_catalog_geometry_follows_the_angle_convention():
    # theta from the downward vertical toward +x: 90° is horizontal, 180° straight up.
    scene = catalog.build("double-pendulum", {"theta1": 90, "theta2": 180, "omega1": 2.0, "l2": 0.5})
    q, v = scene.initial_positions, scene.initial_velocities
    np.testing.assert_allclose(q, [[1, 0, 0], [1, 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(v, [[0, 0, 2], [0, 0, 2]], atol=1e-15)
    chain = catalog.build("chain", {"n": 3, "length": 0.5})
    np.testing.assert_allclose(chain.initial_positions[:, 0], [0.5, 1.0, 1.5])
    assert chain.characteristic_length == pytest.approx(1.5)


def test_catalog_records_every_parameter_used():
    scene = catalog.build("bead", {"theta0": "30"})
    assert scene.parameters == {"m": 1.0, "radius": 1.0, "theta0": 30.0, "omega0": 0.0, "g": 9.81, "duration": 10.0}


@pytest.mark.parametrize(
    "name, overrides, message",
    [
        ("nosuch", {}, r"unknown scene 'nosuch'; choose one of: bead, double-pendulum, chain, spherical-pendulum"),
        ("bead", {"nosuch": 1}, r"bead: unknown parameter 'nosuch'; its parameters are: m, radius"),
        ("bead", {"theta0": "abc"}, r"bead: parameter theta0 must be a number, got 'abc'"),
        ("bead", {"m": "0"}, r"bead: parameter m must be positive, got '0'"),
        ("chain", {"n": "2.5"}, r"chain: parameter n must be an integer, got '2.5'"),
        ("bead", {"theta0": "nan"}, r"bead: parameter theta0 must be finite"),
        ("bead", {"g": "-1"}, r"bead: parameter g must be at least 0"),
    ],
)
def test_catalog_rejects_bad_parameters(name, overrides, message):
    with pytest.raises(SceneError, match=message):
        catalog.build(name, overrides)
