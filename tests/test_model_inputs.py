"""What `xval model check` refuses (only what the user must fix in the file) and what it accepts with a note;
and that a link and a joint sharing a name check and simulate in every engine. Fixtures: tests/fixtures/models."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from compare.model.parity import check
from compare.model.tolerance import DIAGNOSED
from engines.model.description import PSD_TOLERANCE
from engines.model.importers import ENGINES
from cli_support import run_cli

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "models"


def rows(path, **kw) -> dict[str, bool]:
    return {e.engine: e.agrees for e in check(str(path), states=10, **kw).engines}


def test_a_link_and_a_joint_with_one_name_check_in_every_engine():
    report = check(str(FIXTURES / "same_name.urdf"), states=10)
    assert {e.engine: e.agrees for e in report.engines} == dict.fromkeys(ENGINES, True)
    assert report.moving_joints == ("shoulder", "elbow")


@pytest.mark.parametrize("engine", ["mujoco/hinge-rk4", "pybullet/multibody", "drake/rk2", "dart/rk4",
                                    "ours/baumgarte-rk4", "reference"])
def test_a_link_and_a_joint_with_one_name_simulate_in_every_engine(capsys, tmp_path, engine):
    """The link frames are looked up by name and type: Pinocchio has a body frame and a joint frame "elbow"."""
    csv = tmp_path / "run.csv"
    code, out, err = run_cli(capsys, "simulate", "--model", FIXTURES / "same_name.urdf", "--engine", engine,
                             "--dt", "1e-3", "--param", "q0.shoulder=30", "--duration", "0.2", "--output", csv)
    assert (code, err) == (0, ""), err
    header = csv.read_text().splitlines()[0].split(",")
    assert {"q_elbow", "elbow_x", "elbow_z", "shoulder_x"} <= set(header)
    # The elbow link's frame hangs 0.5 m below the shoulder joint: at q0 = 30° it starts at (−0.25, 0, −0.433) m
    # (a rotation about +y takes −z towards −x).
    first = dict(zip(header, map(float, csv.read_text().splitlines()[1].split(","))))
    np.testing.assert_allclose([first["elbow_x"], first["elbow_z"]],
                               [-0.5 * np.sin(np.radians(30)), -0.5 * np.cos(np.radians(30))], atol=1e-12)


def test_inertias_on_links_welded_to_the_root_are_accepted_with_a_note():
    report = check(str(FIXTURES / "welded_bad_inertia.urdf"), states=10)
    assert [n for n in report.notes if "welded to the root" in n] == [
        "link base: the inertia is not positive semidefinite (principal moments -0.4, 0.1, 0.6 kg·m²): accepted, "
        "the link is welded to the root (it cannot move, so it cannot change the dynamics)",
        "link bracket: the inertia is not positive semidefinite (principal moments -0.01, 0.01, 0.01 kg·m²): "
        "accepted, the link is welded to the root (it cannot move, so it cannot change the dynamics)"]
    verdicts = {e.engine: e for e in report.engines}
    # MuJoCo validates every body's inertia, moving or not: its own refusal, its own message.
    assert verdicts["mujoco"].message.startswith("Error: error 'inertia must have positive eigenvalues'")
    assert all(verdicts[e].agrees for e in ("pybullet", "drake", "dart"))


def test_an_inertia_negative_within_the_tolerance_of_the_model_s_scale_is_accepted():
    """tip's inertia is zero but for ixz = 1.4e-20 kg·m²: principal moments ±1.4e-20, indefinite on its own
    scale, within 1e-7 of the model's largest moment (0.03 kg·m²)."""
    assert PSD_TOLERANCE == DIAGNOSED  # one tolerance: the check's, not the description's own
    report = check(str(FIXTURES / "tiny_product.urdf"), states=10)
    assert ("link tip: smallest principal moment of inertia -1.4e-20 kg·m² is negative within the tolerance "
            "(1e-07 of the model's largest, 0.03 kg·m²): accepted as positive semidefinite") in report.notes
    verdicts = {e.engine: e for e in report.engines}
    assert all(verdicts[e].agrees for e in ("pybullet", "drake", "dart"))


def test_pybullet_s_no_limit_convention_is_no_limit_in_every_engine():
    report = check(str(FIXTURES / "no_limit.urdf"), states=10)
    assert {e.engine: e.agrees for e in report.engines} == dict.fromkeys(ENGINES, True)
    assert ("joint shoulder: <limit lower=\"1\" upper=\"-1\"> (lower above upper) is PyBullet's convention for "
            "no limit: read as unlimited") in report.notes


def test_blank_lines_before_the_xml_declaration_are_removed_with_a_note():
    report = check(str(FIXTURES / "blank_lines.urdf"), states=10)
    assert {e.engine: e.agrees for e in report.engines} == dict.fromkeys(ENGINES, True)
    assert "blank lines before the XML declaration removed (XML allows nothing before it)" in report.notes


REFUSED = {
    "unexpanded.urdf.xacro": r"model .*unexpanded.urdf.xacro: unexpanded xacro \(xacro: elements\); expand it into "
                             r"a URDF first: xacro FILE > model.urdf",
    "substitution.urdf": r"joint j: origin xyz='\$\(optenv ARM_XYZ 0 0 1\)' is an unexpanded xacro substitution; "
                         r"expand the file with xacro first",
    "commas.urdf": r"joint j: origin xyz='0.07, 0, -0.69' is not 3 finite numbers; fix it",
}
SUBSTITUTED = {"substitution.urdf": "$(optenv ARM_XYZ 0 0 1)", "commas.urdf": "0.07, 0, -0.69"}


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_what_the_user_must_fix_is_refused_in_one_line(capsys, tmp_path, name):
    if name in SUBSTITUTED:
        path = tmp_path / name
        path.write_text((FIXTURES / "same_name.urdf").read_text().replace(
            '<joint name="shoulder" type="continuous">', f'<joint name="j" type="continuous"><origin xyz="{SUBSTITUTED[name]}"/>'))
    else:
        path = FIXTURES / name
    code, out, err = run_cli(capsys, "model", "check", path)
    assert (code, out) == (2, "")
    assert len(err.splitlines()) == 1 and re.match(rf"xval: error: {REFUSED[name]}", err), err


def test_an_mjcf_file_mujoco_cannot_compile_is_refused_with_its_message(capsys, tmp_path):
    path = tmp_path / "bad.xml"
    path.write_text('<mujoco><worldbody><body><joint type="hinge" axis="0 0 0"/><geom size="0.1"/></body>'
                    '</worldbody></mujoco>')
    code, out, err = run_cli(capsys, "model", "check", path)
    assert (code, out) == (2, "")
    assert err.startswith(f"xval: error: model {path}: MuJoCo cannot compile it (Error: ") and err.endswith(
        "; fix the file\n"), err


def test_the_json_states_the_forward_bound(capsys):
    code, out, _ = run_cli(capsys, "model", "check", FIXTURES / "same_name.urdf", "--states", "5", "--format", "json")
    report = json.loads(out)
    assert code == 0 and report["tolerance"] == 1e-6
    assert report["forward_tolerance"] >= report["tolerance"]
