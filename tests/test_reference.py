"""The reference against closed forms: elliptic-integral periods, normal modes, energy, rod tensions."""

import json
import math
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from engines.scene import catalog

from engines.reference import reference
from engines.reference.closed_form import normal_modes, pendulum_period
from engines.errors import Unsupported
from engines.scene.scene import Scene
from engines.scene.trajectory import constraint_errors, tensions, total_energy

ROOT = Path(__file__).resolve().parent.parent


def roots(f, t_end, n_grid=4000):
    """Times in (0, t_end] where the scalar function f(t) changes sign, refined with brentq."""
    grid = np.linspace(0.0, t_end, n_grid)
    values = np.array([f(t) for t in grid])
    found = []
    for i in np.nonzero(np.sign(values[1:]) != np.sign(values[:-1]))[0]:
        if values[i] == 0.0:
            continue
        found.append(brentq(f, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15))
    return np.array(found)


@pytest.mark.parametrize("theta0", [60.0, 120.0, 170.0])
def test_bead_period_matches_the_elliptic_integral(theta0):
    exact = pendulum_period(1.0, 9.81, math.radians(theta0))
    scene = catalog.build("bead", {"theta0": theta0, "duration": 1.2 * exact})
    solution = reference.solve(scene)
    # Released at rest, the angular velocity vanishes at T/2 and T.
    turning = roots(lambda t: solution.ode(t)[1], scene.duration)
    assert len(turning) == 2
    assert turning[1] == pytest.approx(exact, rel=1e-9)
    assert turning[0] == pytest.approx(exact / 2, rel=1e-9)


@pytest.mark.parametrize(
    "masses, lengths", [((1.0, 1.0), (1.0, 1.0)), ((3.0, 0.5), (0.7, 1.6)), ((0.2, 5.0), (2.0, 0.3))]
)
@pytest.mark.parametrize("mode", [0, 1])
def test_double_pendulum_normal_mode_frequency(masses, lengths, mode):
    omegas, shapes = normal_modes(masses, lengths, 9.81)
    amplitude = 1e-3  # rad: the nonlinear frequency shift ~ amplitude²/16 ≈ 6e-8 is far below 1e-4
    angles = amplitude * shapes[:, mode]
    period = 2 * math.pi / omegas[mode]
    scene = catalog.build(
        "double-pendulum",
        {"m1": masses[0], "m2": masses[1], "l1": lengths[0], "l2": lengths[1],
         "theta1": math.degrees(angles[0]), "theta2": math.degrees(angles[1]), "duration": 6 * period},
    )
    solution = reference.solve(scene)
    big = int(np.argmax(np.abs(angles)))
    crossings = roots(lambda t: solution.ode(t)[big], scene.duration)
    # Zero crossings of a pure mode are half a period apart.
    measured = math.pi * (len(crossings) - 1) / (crossings[-1] - crossings[0])
    assert measured == pytest.approx(omegas[mode], rel=1e-4)
    # And the motion stays in the mode's shape: the other angle follows in fixed ratio.
    t = np.linspace(0, scene.duration, 200)
    theta = solution.ode(t)[:2]
    np.testing.assert_allclose(theta[1 - big], theta[big] * angles[1 - big] / angles[big], atol=1e-3 * amplitude)


def test_reference_conserves_energy_of_the_default_double_pendulum_over_100_s():
    scene = catalog.build("double-pendulum", {"duration": 100.0})
    solution = reference.solve(scene)
    positions, velocities, _ = solution.at(np.linspace(0, 100, 20001))
    energy = total_energy(scene, positions, velocities)
    assert np.max(np.abs(energy - energy[0])) / scene.characteristic_energy < 1e-9
    assert constraint_errors(scene, positions).max() < 1e-12


def test_bead_tension_at_the_bottom_of_the_swing():
    # Energy gives v² = 2 g r (1 − cos θ0) at the bottom, so T = m g (3 − 2 cos θ0).
    theta0, m = 60.0, 2.0
    exact_period = pendulum_period(1.0, 9.81, math.radians(theta0))
    scene = catalog.build("bead", {"theta0": theta0, "m": m, "duration": exact_period})
    solution = reference.solve(scene)
    positions, _, forces = solution.at(np.array([0.0, exact_period / 4]))
    pull = tensions(scene, positions, forces)
    assert pull[1, 0] == pytest.approx(m * 9.81 * (3 - 2 * math.cos(math.radians(theta0))), rel=1e-9)
    # At release (at rest) only gravity's radial part is balanced: T = m g cos θ0.
    assert pull[0, 0] == pytest.approx(m * 9.81 * math.cos(math.radians(theta0)), rel=1e-9)


def test_chain_tensions_hanging_at_rest_carry_the_weight_below():
    scene = catalog.build("chain", {"n": 4, "theta0": 0.0, "mass": 0.5, "duration": 0.1})
    positions, _, forces = reference.solve(scene).at(np.array([0.05]))
    np.testing.assert_allclose(tensions(scene, positions, forces)[0], 0.5 * 9.81 * np.array([4, 3, 2, 1]), rtol=1e-12)
    # Each constraint's force acts on its first particle: the pin pulls particle 0 up, rod (0, 1) pulls it down.
    assert forces[0, 0, 2] > 0 and forces[0, 1, 2] < 0


def test_conical_spherical_pendulum_keeps_its_polar_angle():
    theta0 = 40.0
    rate = math.sqrt(9.81 / math.cos(math.radians(theta0)))  # conical pendulum: φ̇² = g / (r cos θ)
    scene = catalog.build("spherical-pendulum", {"theta0": theta0, "phi_dot0": rate, "duration": 5.0})
    positions, velocities, forces = reference.solve(scene).at(np.linspace(0, 5, 101))
    np.testing.assert_allclose(positions[:, 0, 2], -math.cos(math.radians(theta0)), atol=1e-10)
    energy = total_energy(scene, positions, velocities)
    assert np.max(np.abs(energy - energy[0])) / scene.characteristic_energy < 1e-10
    # The rod balances gravity vertically: T cos θ = m g.
    pull = tensions(scene, positions, forces)[:, 0]
    np.testing.assert_allclose(pull, 9.81 / math.cos(math.radians(theta0)), rtol=1e-9)


def test_spherical_pendulum_conserves_angular_momentum_about_the_vertical():
    scene = catalog.build("spherical-pendulum")
    positions, velocities, _ = reference.solve(scene).at(np.linspace(0, 10, 501))
    p, v = positions[:, 0], velocities[:, 0]
    lz = p[:, 0] * v[:, 1] - p[:, 1] * v[:, 0]
    np.testing.assert_allclose(lz, lz[0], rtol=1e-9)
    assert np.ptp(p[:, 2]) > 0.1  # it nutates: not a conical orbit in disguise


def test_reference_engine_samples_on_the_shared_schedule():
    scene = catalog.build("bead", {"duration": 1.0})
    trajectory = reference.ENGINE.simulate(scene, 1e-3)
    assert trajectory.info.status == "ok"
    np.testing.assert_allclose(trajectory.t, np.arange(101) * 0.01)
    assert trajectory.constraint_forces.shape == (101, 1, 3)


def test_reference_refuses_what_it_cannot_express():
    from engines.scene.scene import Particle, Pin, Rod, Scene

    # A triangle of rods is not a chain.
    a, b, c = (1, 0, 0), (2, 0, 0), (1.5, 0, math.sqrt(3) / 2)
    loop = Scene(
        "loop", (Particle(1, a), Particle(1, b), Particle(1, c)),
        (Pin(0, (0, 0, 0), 1.0), Rod(0, 1, 1.0), Rod(1, 2, 1.0), Rod(2, 0, 1.0)),
    )
    with pytest.raises(Unsupported, match="one constraint per particle"):
        reference.ENGINE.check(loop)


# -- kept across runs ----------------------------------------------------------------------------


@pytest.fixture
def kept_double_pendulum(tmp_path, monkeypatch):
    """(scene, times (101,) s, its (solution, bound) at rtol = atol = 1e-10, the kept file) in a cache
    directory of its own."""
    monkeypatch.setenv("XVAL_CACHE_DIR", str(tmp_path))
    scene = catalog.build("double-pendulum", {"duration": 1.0})
    solved = reference.solve_and_bound_kept(scene, 1e-10, 1e-10)
    [kept] = (tmp_path / "reference").glob("*.pickle")
    return scene, np.linspace(0.0, 1.0, 101), solved, kept


def test_a_kept_reference_is_the_solved_one_and_a_damaged_or_other_one_is_solved_again(kept_double_pendulum,
                                                                                       monkeypatch):
    # solve_and_bound_kept keeps each (scene, rtol, atol)'s solution under the user cache directory: the
    # second ask loads it (no solve), equal at every time to the first; another tolerance is another
    # solve; a damaged file is solved again and replaced.
    scene, times, (first, first_bound), kept = kept_double_pendulum

    solves = []
    real = reference.solve_and_bound
    monkeypatch.setattr(reference, "solve_and_bound", lambda *a: solves.append(a) or real(*a))
    again, again_bound = reference.solve_and_bound_kept(scene, 1e-10, 1e-10)
    assert solves == []
    for ours_, kept_ in zip(first.at(times), again.at(times)):
        np.testing.assert_array_equal(ours_, kept_)
    assert again_bound.reference_error == first_bound.reference_error

    reference.solve_and_bound_kept(scene, 1e-9, 1e-9)
    assert len(solves) == 1 and len(list(kept.parent.glob("*.pickle"))) == 2

    kept.write_bytes(b"not a pickle")
    repaired, _ = reference.solve_and_bound_kept(scene, 1e-10, 1e-10)
    assert len(solves) == 2
    np.testing.assert_array_equal(repaired.at(times)[0], first.at(times)[0])
    assert kept.read_bytes() != b"not a pickle"


#: In a fresh interpreter: a scene's kept reference, asked for at the sample times it was kept with,
#: and whether that imported scipy.integrate; then the same at other times (which must).
KEPT_PROBE = r"""
import json, sys
import numpy as np
from engines.scene import catalog
from engines.reference import reference
scene = catalog.build("double-pendulum", {"duration": 1.0})
times = np.linspace(0.0, 1.0, 101)
solution, _ = reference.solve_and_bound_kept(scene, 1e-10, 1e-10, sample_times=[times])
positions = solution.at(times)[0]
before = "scipy.integrate" in sys.modules
solution.at(times[:50] + 1e-3)
print(json.dumps({"positions": positions.tolist(), "before": before, "after": "scipy.integrate" in sys.modules}))
"""


def test_kept_samples_are_the_solution_at_those_times_and_need_no_scipy(kept_double_pendulum):
    # A run's reference is evaluated where its cases are sampled (one set of times per dt) and those
    # samples are kept with the solution: the next run finds them without unpickling scipy's dense
    # solution, so its parent never imports scipy.integrate. The samples are exactly the dense
    # solution's values; a set not kept yet is added and the file written again.
    scene, times, (solved, _), kept = kept_double_pendulum
    assert solved.samples == {}
    written = kept.stat().st_mtime_ns
    kept_, _ = reference.solve_and_bound_kept(scene, 1e-10, 1e-10, sample_times=[times])
    assert set(kept_.samples) == {times.tobytes()} and kept.stat().st_mtime_ns != written

    done = subprocess.run([sys.executable, "-c", KEPT_PROBE], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "XVAL_CACHE_DIR": str(kept.parent.parent)})
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert seen["before"] is False and seen["after"] is True
    np.testing.assert_array_equal(np.array(seen["positions"]), solved.at(times)[0])

    # Another run's set is added to the file, and the answer carries only the set asked for.
    other = np.linspace(0.0, 1.0, 51)
    asked, _ = reference.solve_and_bound_kept(scene, 1e-10, 1e-10, sample_times=[other])
    assert set(asked.samples) == {other.tobytes()}
    with kept.open("rb") as handle:
        on_file, _ = pickle.load(handle)
    assert set(on_file.samples) == {times.tobytes(), other.tobytes()}


def test_a_cache_file_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    # ours.files.atomic_write (every file xval writes): a write of the same file that fails (here its
    # rename) leaves the old file as it was and no temporary beside it.
    import ours.files
    from ours.files import atomic_write

    target = tmp_path / "kept.pickle"
    atomic_write(target, b"first")

    def failing_replace(source, destination):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ours.files.os, "replace", failing_replace)
    with pytest.raises(OSError):
        atomic_write(target, b"second")
    assert target.read_bytes() == b"first" and [p.name for p in tmp_path.iterdir()] == ["kept.pickle"]


def test_a_solution_keeps_at_most_the_latest_sample_sets():
    scene = catalog.build("bead", {"duration": 0.5})
    solution = reference.solve(scene, 1e-8, 1e-8)
    sets = [np.linspace(0.0, 0.5, n) for n in range(2, reference.MOST_SAMPLE_SETS + 4)]
    assert solution.sample(sets) is True
    assert list(solution.samples) == [t.tobytes() for t in sets[-reference.MOST_SAMPLE_SETS:]]
    assert solution.sample(sets[-1:]) is False  # already kept: nothing to write again


def test_the_kept_key_is_the_scenes_physics_and_running_out_of_memory_keeps_the_file(tmp_path, monkeypatch):
    # Keyed by Scene.content_hash: another duration is another file; the same physics under another
    # name is the same file. A MemoryError while reading (a case host at its limit) is raised, and the
    # file, which is fine, stays.
    monkeypatch.setenv("XVAL_CACHE_DIR", str(tmp_path))
    scene = catalog.build("bead", {"duration": 0.5})
    reference.solve_and_bound_kept(scene, 1e-8, 1e-8)
    reference.solve_and_bound_kept(catalog.build("bead", {"duration": 0.25}), 1e-8, 1e-8)
    assert len(list((tmp_path / "reference").glob("*.pickle"))) == 2
    renamed = Scene("renamed", scene.particles, scene.constraints, scene.gravity, scene.duration)
    assert reference.is_kept(renamed, 1e-8, 1e-8)

    def out_of_memory(handle):
        raise MemoryError

    monkeypatch.setattr(reference.pickle, "load", out_of_memory)
    with pytest.raises(MemoryError):
        reference.solve_and_bound_kept(scene, 1e-8, 1e-8)
    assert len(list((tmp_path / "reference").glob("*.pickle"))) == 2
