"""The model layer: the description refuses what it cannot hold, the URDF reader says what the file says,
and every engine's import answers M, bias and forward dynamics in the description's order (real engines)."""

from __future__ import annotations

import numpy as np
import pytest

from engines.model import source, urdf
from engines.model.description import ModelError
from engines.model.importers import ENGINES, REFERENCE, importer
from engines.model.loaded import Refused


def description_of(tmp_path, text: str, **kw):
    path = tmp_path / "m.urdf"
    path.write_text(text)
    return urdf.read(source.resolve(str(path)), **kw)


def robot(links: str, joints: str = "") -> str:
    return f'<robot name="r">{links}{joints}</robot>'


LINK = '<link name="{n}"><inertial><mass value="{m}"/><inertia ixx="{i}" iyy="{i}" izz="{i}"/></inertial></link>'


def two_links(mass=1.0, inertia=0.1, kind="revolute", extra="") -> str:
    return robot(LINK.format(n="base", m=1, i=0.1) + LINK.format(n="arm", m=mass, i=inertia),
                 f'<joint name="j" type="{kind}"><parent link="base"/><child link="arm"/>'
                 f'<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>{extra}</joint>')


@pytest.mark.parametrize("text, message", [
    (two_links(mass=-1), r"^link arm: mass -1 kg is negative or not finite; give <inertial><mass value=…> a value ≥ 0$"),
    (two_links(inertia=-0.1), r"^link arm: the inertia is not positive semidefinite \(principal moments -0\.1, -0\.1, -0\.1 kg·m²\)"),
    (two_links(kind="planar"), r"^joint j: type 'planar' is not supported; use one of revolute, continuous, prismatic, fixed$"),
    (two_links(kind="floating"), r"^joint j: type 'floating' is not supported; the base is welded to the world; remove the floating joint$"),
    (two_links(extra='<mimic joint="k"/>'), r"^joint j: mimic joints are not supported \(it mimics k\); remove its <mimic> element$"),
    (robot(LINK.format(n="a", m=1, i=1) + LINK.format(n="b", m=1, i=1)),
     r"^the model must have exactly one root link, found a, b; connect the links into one tree$"),
    (robot(LINK.format(n="a", m=1, i=1) + LINK.format(n="b", m=1, i=1) + LINK.format(n="c", m=1, i=1),
           '<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
           '<joint name="cb" type="fixed"><parent link="c"/><child link="b"/></joint>'
           '<joint name="bc" type="fixed"><parent link="b"/><child link="c"/></joint>'),
     r"^link b is the child of joints ab and cb: closed loops are not supported"),
])
def test_the_description_refuses_with_the_link_or_joint_and_the_fix(tmp_path, text, message):
    with pytest.raises(ModelError, match=message):
        description_of(tmp_path, text)


def test_a_mimic_joint_is_an_independent_coordinate_when_asked(tmp_path):
    model = description_of(tmp_path, two_links(extra='<mimic joint="k"/>'), mimic_independent=True)
    assert [j.name for j in model.moving_joints] == ["j"]


def test_the_reader_stores_a_rotated_inertial_frame_in_link_axes(tmp_path):
    # diag(1, 2, 3) in a frame yawed by 90°: in link axes the x and y moments swap.
    text = robot('<link name="a"><inertial><origin xyz="0.1 0.2 0.3" rpy="0 0 1.5707963267948966"/>'
                 '<mass value="2"/><inertia ixx="1" iyy="2" izz="3"/></inertial></link>')
    body = description_of(tmp_path, text).body("a")
    assert body.inertial.com == (0.1, 0.2, 0.3) and body.inertial.rotated
    np.testing.assert_allclose(body.inertial.inertia_matrix, np.diag([2.0, 1.0, 3.0]), atol=1e-15)


def test_a_link_without_inertial_is_massless_and_marked(tmp_path):
    body = description_of(tmp_path, robot('<link name="a"/>')).body("a")
    assert (body.inertial.mass, body.inertial.declared) == (0.0, False)


@pytest.mark.parametrize("model, message", [
    ("missing.urdf", r"^model missing.urdf: no such file \(missing.urdf\); give a path to a .urdf or MJCF .xml file"),
    ("pybullet_data:nothing.urdf", r"^model pybullet_data:nothing.urdf: no such file"),
])
def test_a_missing_file_is_one_line(model, message, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ModelError, match=message):
        source.resolve(model)


def test_malformed_xml_names_the_line(tmp_path):
    (tmp_path / "bad.urdf").write_text('<robot name="r">\n<link name="a">\n</robot>')
    with pytest.raises(ModelError, match=r"^model .*bad.urdf: not well-formed XML \(mismatched tag: line 3, column 2\); fix the file$"):
        source.resolve(str(tmp_path / "bad.urdf"))


KUKA = "pybullet_data:kuka_iiwa/model.urdf"


@pytest.fixture(scope="module")
def kuka():
    src = source.resolve(KUKA)
    model = urdf.read(src)
    return src, model, importer(REFERENCE).load(src, model)


@pytest.mark.parametrize("engine", ENGINES)
def test_every_engine_agrees_with_pinocchio_on_the_kuka_arm(kuka, engine):
    """All five hold the file as written (measured: 1e-15 relative); 1e-12 leaves room for round-off only."""
    src, model, reference = kuka
    loaded = importer(engine).load(src, model)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v, tau = rng.uniform(-1, 1, (3, model.nq))
        for name, args in (("mass_matrix", (q,)), ("bias", (q, v)), ("forward", (q, v, tau))):
            ours, ref = getattr(loaded, name)(*args), getattr(reference, name)(*args)
            assert np.abs(ours - ref).max() <= 1e-12 * np.abs(ref).max(), (engine, name)


def test_mujoco_refuses_an_inertia_against_the_triangle_inequality_unless_asked_to_balance():
    src = source.resolve("pybullet_data:xarm/xarm6_robot.urdf")
    model = urdf.read(src)
    with pytest.raises(Refused, match=r"inertia must satisfy A \+ B >= C; use 'balanceinertia' to fix"):
        importer("mujoco").load(src, model)
    assert importer("mujoco").load(src, model, balance_inertia=True).options["balanceinertia"] == "true"


def test_joints_are_ordered_depth_first_children_in_file_order(tmp_path):
    links = "".join(LINK.format(n=n, m=1, i=0.1) for n in ("root", "a", "b", "a1", "b1"))
    joint = '<joint name="{n}" type="continuous"><parent link="{p}"/><child link="{c}"/><axis xyz="0 0 2"/></joint>'
    # Declared out of order: the description walks the tree from the root.
    joints = "".join(joint.format(n=f"to_{c}", p=p, c=c) for p, c in (("b", "b1"), ("root", "a"), ("a", "a1"), ("root", "b")))
    model = description_of(tmp_path, robot(links, joints))
    assert [j.name for j in model.moving_joints] == ["to_a", "to_a1", "to_b", "to_b1"]
    assert model.joint("to_a").axis == (0.0, 0.0, 1.0)  # normalised
    assert model.joint("to_a").limits.lower is None  # continuous: unbounded


def test_the_mujoco_compiler_options_are_stated():
    src = source.resolve(KUKA)
    assert importer("mujoco").load(src, urdf.read(src)).options == {
        "fusestatic": "true", "inertiafromgeom": "auto", "balanceinertia": "false", "discardvisual": "true"}


MJCF = '<mujoco><worldbody><body name="b">{joints}<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>'


def test_the_mjcf_reader_holds_a_ball_joint(tmp_path):
    """Issue 42 turned this refusal ("type 'ball' is not supported") into a ball joint: a quaternion in q, three
    velocities (tests/test_ball_joint.py checks the dynamics)."""
    from engines.mujoco import description as mjcf

    (tmp_path / "m.xml").write_text(MJCF.format(joints='<joint name="ball" type="ball"/>'))
    model = mjcf.read(source.resolve(str(tmp_path / "m.xml")))
    assert [(j.name, j.type, j.nq, j.nv) for j in model.moving_joints] == [("ball", "ball", 4, 3)]


def test_a_joint_that_moves_nothing_is_refused_before_any_engine_runs(tmp_path):
    from compare.model.parity import check

    text = robot(LINK.format(n="base", m=1, i=0.1) + '<link name="empty"/>',
                 '<joint name="idle" type="continuous"><parent link="base"/><child link="empty"/></joint>')
    (tmp_path / "m.urdf").write_text(text)
    with pytest.raises(ModelError, match=r"joint idle moves no mass or inertia \(M is singular\); give the links it moves an <inertial>$"):
        check(str(tmp_path / "m.urdf"), states=2)


def test_mjcf_is_read_by_the_engine_that_declares_the_format_and_an_unread_format_is_refused():
    """The shared model layer reaches MuJoCo's MJCF reader only through the registry (ModelImport.describes)."""
    from engines.mujoco import description
    from engines.registry import EngineUnavailable, describer

    assert describer("mjcf") is description.read
    with pytest.raises(EngineUnavailable, match="no engine that defines SDF files can load here"):
        describer("sdf")
