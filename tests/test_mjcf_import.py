"""MJCF as users bring it: includes relative to the file that names them, several joints in one body (a
planar walker's root), static worldbody geoms. Each fixture (tests/fixtures/mjcf/) against a computation
written out here (kinetic energy from the links' centres of mass, by hand), and each engine real.
DART is left out of the static-geom file: its MJCF parser segfaults on it (measured, dartpy 6.20)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from compare.model.parity import check, read_description
from engines.model import source as sources
from engines.model.description import ModelError
from engines.model.importers import importer

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "mjcf"


def verdicts(path, engines) -> dict[str, bool]:
    return {e.engine: e.agrees for e in check(str(path), engines=engines, states=10).engines}


def test_an_include_is_found_relative_to_the_file_that_names_it(tmp_path, monkeypatch):
    """main.xml includes parts/arm.xml, which includes common/forearm.xml relative to itself; run from
    elsewhere, the text every engine loads is whole and MuJoCo, Drake and the reference agree on it."""
    monkeypatch.chdir(tmp_path)
    path = FIXTURES / "include_main.xml"
    text, notes = sources.resolve(str(path)).engine_text()
    assert "<include" not in text and notes == ("2 <include> elements inlined (each file found relative to the "
                                                "file that names it)",)
    assert re.search(rf'meshdir="{re.escape(str(FIXTURES))}"', text)
    _, model = read_description(str(path))
    assert [j.name for j in model.moving_joints] == ["shoulder", "elbow"]
    assert model.body("fore").inertial.mass == 0.8
    assert verdicts(path, ("mujoco", "drake")) == {"mujoco": True, "drake": True}


def test_a_missing_include_names_the_file_and_where_it_was_looked_for(tmp_path):
    (tmp_path / "m.xml").write_text('<mujoco><worldbody><include file="gone.xml"/></worldbody></mujoco>')
    with pytest.raises(ModelError, match=r'^<include file="gone.xml">: no such file next to .* give a path '
                                         r'relative to the file that includes it$'):
        read_description(str(tmp_path / "m.xml"))


def rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def planar_kinetic_energy(q: np.ndarray, v: np.ndarray) -> float:
    """planar_root.xml by hand: torso at (x, 0, 1.2 + z) pitched θ about its anchor (0, 0, 0.1), the thigh
    hung at (0, 0, -0.3) and swung φ; centres of mass differentiated numerically; ω along y only."""
    def coms(q):
        x, z, theta, phi = q
        origin, anchor = np.array([x, 0.0, 1.2 + z]), np.array([0.0, 0.0, 0.1])
        torso = origin + anchor + rot_y(theta) @ (np.array([0.05, 0.0, 0.02]) - anchor)
        hip = origin + anchor + rot_y(theta) @ (np.array([0.0, 0.0, -0.3]) - anchor)
        return torso, hip + rot_y(theta + phi) @ np.array([0.0, 0.0, -0.2])

    h = 1e-6
    ahead, behind = coms(q + h * v), coms(q - h * v)
    speeds = [(a - b) / (2 * h) for a, b in zip(ahead, behind)]
    return (0.5 * 2.0 * speeds[0] @ speeds[0] + 0.5 * 1.0 * speeds[1] @ speeds[1]
            + 0.5 * 0.2 * v[2] ** 2 + 0.5 * 0.02 * (v[2] + v[3]) ** 2)


def test_three_joints_in_one_body_are_a_chain_whose_kinetic_energy_is_the_links():
    """slide x, slide z, hinge y in one body: two massless links between them; ½vᵀMv of the reference equals
    the links' kinetic energy by hand, the slides carry the whole 3 kg; MuJoCo and Drake agree; PyBullet and
    DART load it (their MJCF inertias differ, and the diagnosis says how)."""
    path = FIXTURES / "planar_root.xml"
    _, model = read_description(str(path))
    assert [(j.name, j.parent, j.child) for j in model.moving_joints] == [
        ("rootx", "world", "torso/rootx"), ("rootz", "torso/rootx", "torso/rootz"), ("rooty", "torso/rootz", "torso"),
        ("hip", "torso", "thigh")]
    assert model.moving_links == ("torso", "thigh")
    reference = importer("pinocchio").load(*read_description(str(path)))
    rng = np.random.default_rng(0)
    for _ in range(3):
        q, v = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
        m = reference.mass_matrix(q)
        assert 0.5 * v @ m @ v == pytest.approx(planar_kinetic_energy(q, v), rel=1e-8)
        np.testing.assert_allclose(m[:2, :2], 3.0 * np.eye(2), atol=1e-12)
    report = check(str(path), states=10)
    rows = {e.engine: e for e in report.engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "pybullet": False, "drake": True,
                                                                 "dart": False}
    assert rows["pybullet"].loaded and rows["dart"].loaded
    assert any("pybullet drops the inertia" in line for line in rows["pybullet"].diagnosis)
    assert any("dart gives it 1 kg" in line for line in rows["dart"].diagnosis)


def test_static_geoms_are_not_bodies_and_pybullets_floating_root_is_welded_back(tmp_path):
    """PyBullet's loadMJCF makes the floor a body and floats the root: xval takes the multibody and the
    fixed-base block. Its M, bias and accelerations are then the reference's with the links' inertias
    dropped (PyBullet's MJCF habit), to its float32 round-off."""
    path = FIXTURES / "static_geoms.xml"
    assert verdicts(path, ("mujoco", "pybullet", "drake")) == {"mujoco": True, "pybullet": False, "drake": True}
    source, model = read_description(str(path))
    assert model.moving_links == ("arm", "fore")
    pybullet = importer("pybullet").load(source, model)
    assert pybullet.base == 6
    dropped = tmp_path / "dropped.xml"
    dropped.write_text(re.sub(r'diaginertia="[^"]*"', 'diaginertia="1e-14 1e-14 1e-14"', path.read_text()))
    reference = importer("pinocchio").load(*read_description(str(dropped)))
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v, tau = rng.uniform(-1, 1, (3, 2))
        np.testing.assert_allclose(pybullet.mass_matrix(q), reference.mass_matrix(q), atol=1e-6)
        np.testing.assert_allclose(pybullet.bias(q, v), reference.bias(q, v), atol=1e-5)
        np.testing.assert_allclose(pybullet.forward(q, v, tau), reference.forward(q, v, tau), atol=1e-4)


def test_an_empty_limit_range_locks_no_joint_in_the_check_as_in_simulate():
    """<limit lower=0 upper=0> locks a joint in PyBullet unless limits are off; check and simulate both turn
    them off (the same 'no limit' range), and the note says so. Every engine then agrees."""
    path = FIXTURES.parent / "urdf" / "zero_range.urdf"
    report = check(str(path), states=10)
    assert {e.engine: e.agrees for e in report.engines} == {"mujoco": True, "pybullet": True, "drake": True,
                                                             "dart": True}
    pybullet = next(e for e in report.engines if e.engine == "pybullet")
    assert any(note.startswith("joint limits off: every <limit> given lower 1 > upper -1") for note in pybullet.notes)
