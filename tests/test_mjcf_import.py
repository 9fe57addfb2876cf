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


def test_the_reference_of_an_mjcf_is_mujoco_s_compiled_model_and_mujoco_and_drake_agree_with_it():
    """The acrobot's defaults give every geom 1 kg (<default><geom mass="1">): MuJoCo's compiler says each
    arm weighs 1 kg (the 0-kg decoration adds nothing), and so does the reference built from that compiled
    model; Pinocchio's own MJCF reader ignores the default and weighs the capsules (8.38 kg, measured), which
    made MuJoCo and Drake, agreeing with each other, disagree with the reference. At q = 0 the lower arm's
    moment about the elbow is its own about its centre plus m·(0.5 m)², m = 1 kg (parallel axes)."""
    path = FIXTURES.parent / "models" / "acrobot.xml"
    source, model = read_description(str(path))
    loaded = importer("pinocchio").load(source, model)
    assert {link: round(found.mass, 12) for link, found in loaded.link_inertias().items()} == \
        {"upper_arm": 1.0, "lower_arm": 1.0}
    assert any("MuJoCo's compiled model" in note for note in loaded.notes)
    own = model.body("lower_arm").inertial
    assert own.com == pytest.approx((0.0, 0.0, 0.5), abs=1e-12)
    assert loaded.mass_matrix(np.zeros(2))[1, 1] == pytest.approx(own.inertia_matrix[1, 1] + 1.0 * 0.5 ** 2, rel=1e-12)
    assert verdicts(path, ("mujoco", "drake")) == {"mujoco": True, "drake": True}


def test_armature_is_zeroed_on_a_body_whose_only_joints_are_slides():
    """The puck's M is its mass, 0.3 kg, on each slide (no coupling: the axes are orthogonal), with the file's
    0.04 armature set to 0 in MuJoCo as in every engine; MuJoCo once kept it (its compiler's constant mass of
    such a body), 0.34 kg."""
    path = FIXTURES / "slide_armature.xml"
    source, model = read_description(str(path))
    mass = importer("mujoco").load(source, model).mass_matrix(np.array([0.2, -0.1]))
    np.testing.assert_allclose(mass, 0.3 * np.eye(2), rtol=0, atol=1e-15)
    assert verdicts(path, ("mujoco", "drake")) == {"mujoco": True, "drake": True}


def test_an_mjcf_without_a_model_name_loads_in_drake_and_a_lone_free_body_checks():
    """A free capsule (6 velocities, no joint): MuJoCo and Drake agree with the reference once Drake's import
    names the model, and its note says so."""
    path = FIXTURES / "unnamed_free_body.xml"
    rows = {e.engine: e for e in check(str(path), engines=("mujoco", "drake"), states=10).engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "drake": True}
    assert any(note.startswith("<mujoco> has no model name; Drake's parser needs one") for note in rows["drake"].notes)


def test_the_medium_s_fluid_forces_are_left_out_of_mujoco_s_accelerations():
    """In a medium MuJoCo's q̈ carries drag and buoyancy; with density, viscosity and wind set to 0 (said in a
    note) it is the tree's, the reference's. Moving through still fluid, the drag would be of the order of
    ρ·v²·area ≈ 4000 · 1 · 0.03 N: far above the check's tolerance."""
    path = FIXTURES / "fluid.xml"
    rows = {e.engine: e for e in check(str(path), engines=("mujoco", "drake"), states=10).engines}
    assert {name: row.agrees for name, row in rows.items()} == {"mujoco": True, "drake": True}
    assert "the medium's density, viscosity and wind set to 0 (the file's fluid forces left out)" in rows["mujoco"].notes


def test_a_hinge_an_engine_puts_elsewhere_is_named_with_both_places():
    """Measured with Drake 1.51: of two hinges in one body at (0, 0, 1), its MJCF parser puts the first through
    the world's origin. M₀₀ (j1 about x at q = 0) is then I_xx + m·d² with d the COM's distance from that axis:
    0.01 + 0.2² + 0.7² = 0.54 instead of 0.01 + 0.2² + 0.3² = 0.14 (kg·m²), as the reference has it. The
    diagnosis names the joint and both places; MuJoCo agrees. If a later Drake places it right, its row agrees
    and this test says so."""
    path = FIXTURES / "two_hinges.xml"
    source, model = read_description(str(path))
    assert importer("pinocchio").load(source, model).mass_matrix(np.zeros(2))[0, 0] == pytest.approx(0.14, rel=1e-12)
    assert importer("drake").load(source, model).mass_matrix(np.zeros(2))[0, 0] == pytest.approx(0.54, rel=1e-12)
    rows = {e.engine: e for e in check(str(path), engines=("mujoco", "drake"), states=10).engines}
    assert rows["mujoco"].agrees and not rows["drake"].agrees
    assert rows["drake"].diagnosis == ("joint j1: drake puts its axis through (0, 0, 0) m at q = 0, the file "
                                       "through (0, 0, 1) m",)


def test_gymnasiums_ant_is_compared_in_four_engines_and_each_disagreement_names_its_links():
    """gymnasium's ant.xml (a free joint, geoms of density 5 kg/m³, four unnamed shins): MuJoCo and Drake agree
    with the reference. PyBullet's loadMJCF takes each geom at 1000 kg/m³ (200× the file's masses) with no
    inertia, splitting a body into a link per joint (``link1_N`` when unnamed) and one per geom: its links are
    summed back into the file's bodies and named so. DART's parser keeps the geoms' masses with identity
    moments of inertia."""
    import gymnasium

    path = Path(gymnasium.__file__).parent / "envs" / "mujoco" / "assets" / "ant.xml"
    rows = {e.engine: e for e in check(str(path), states=10).engines}
    assert {name: (row.loaded, row.agrees) for name, row in rows.items()} == {
        "mujoco": (True, True), "pybullet": (True, False), "drake": (True, True), "dart": (True, False)}
    legs = "front_left_leg, aux_1, front_right_leg, aux_2, back_leg, aux_3, right_back_leg, aux_4"
    assert rows["pybullet"].diagnosis == (
        "link torso: mass 0.327 kg, inertia 0.00818 kg·m² — pybullet gives it 65.4 kg and 0 kg·m²",
        f"links {legs}: mass 0.0392 kg, inertia principal moments (0.000118, 0.000568, 0.000568) kg·m² — "
        f"pybullet gives them 7.83 kg and 0 kg·m²",
        "links body4, body7, body10, body13: mass 0.0676 kg, inertia principal moments (0.000209, 0.00267, "
        "0.00267) kg·m² — pybullet gives them 13.5 kg and 0 kg·m²")
    assert [line.split(" — ")[1] for line in rows["dart"].diagnosis] == [
        "dart holds 1 kg·m² (the file: 0.00818 kg·m²)",
        "dart holds 1 kg·m² (the file: principal moments (0.000118, 0.000568, 0.000568) kg·m²)",
        "dart holds 1 kg·m² (the file: principal moments (0.000209, 0.00267, 0.00267) kg·m²)"]


def test_a_mass_scale_an_engine_does_not_apply_is_one_diagnosis_line():
    """gymnasium's half_cheetah.xml says <compiler settotalmass="14">: MuJoCo scales every mass and inertia to
    that total; Drake 1.51's parser ignores it (and warns), so every link is 1.51× the file's: one line says so."""
    import gymnasium

    path = Path(gymnasium.__file__).parent / "envs" / "mujoco" / "assets" / "half_cheetah.xml"
    (drake,) = check(str(path), engines=("drake",), states=10).engines
    assert drake.loaded and not drake.agrees
    assert drake.diagnosis == ("links torso, bthigh, bshin, bfoot, fthigh, fshin, ffoot: 14 kg in all — drake scales "
                               "every mass and inertia of them by 1.51 (one factor: a total mass or a density its "
                               "parser does not apply, such as <compiler settotalmass>)",)


def test_an_engine_whose_mass_matrix_is_singular_is_compared_and_diagnosed_and_its_json_is_strict(capsys):
    """gymnasium's humanoid.xml in PyBullet: loadMJCF drops the inertias, so its floating-base M is singular
    (no q̈). The row is compared, not failed: its forward difference is inf in the table, null in the JSON (which
    has no Infinity), and the diagnosis names every link whose inertia it dropped."""
    import json

    import gymnasium
    from cli_support import run_cli

    path = Path(gymnasium.__file__).parent / "envs" / "mujoco" / "assets" / "humanoid.xml"
    code, out, err = run_cli(capsys, "model", "check", path, "--engine", "pybullet", "--states", "10",
                             "--format", "json")

    def no_constant(name):
        raise ValueError(f"not JSON: {name}")

    (row,) = json.loads(out, parse_constant=no_constant)["engines"]
    assert code == 1 and row["loaded"] and not row["agrees"] and row["forward"] is None and row["message"] == ""
    assert row["mass_matrix"] > 1e-3 and len(row["diagnosis"]) == 8
    assert all(line.endswith("— pybullet drops the inertia") for line in row["diagnosis"]), row["diagnosis"]


def test_separate_trees_of_the_world_body_are_left_out_and_the_arm_is_compared():
    """An arm with a separate free puck and a target on two slides (like pybullet_data's striker and
    gymnasium's pusher): separate trees share no joint with the arm, so the check keeps the arm (the tree with
    the most moving joints), says which trees it left out, and compares it in every engine instead of refusing
    it; MuJoCo and Drake agree with the model reference. The actuator naming a target slide and the keyframe
    (whose qpos holds the left-out joints) go with them, or MuJoCo would not compile the text."""
    path = FIXTURES / "separate_trees.xml"
    report = check(str(path), states=10)
    assert report.moving_joints == ("shoulder_pan", "elbow")
    assert all(e.loaded for e in report.engines), [(e.engine, e.message) for e in report.engines]
    assert {e.engine: e.agrees for e in report.engines if e.engine in ("mujoco", "drake")} == \
        {"mujoco": True, "drake": True}
    assert "puck (joint puck_free); target (joints target_x, target_y) left out: each is a separate tree of the " \
        "world body that shares no joint with the model (shoulder), so it cannot change its M, bias or q̈" \
        in report.notes
    source, model = read_description(str(path))
    assert [b.name for b in model.bodies] == ["world", "shoulder", "forearm"]
