"""Our own reader of a URDF file into a :class:`ModelDescription` (xml.etree; what the file says).

Readings of the URDF specification stated once: a link without
``<inertial>`` has mass 0 and inertia 0; a missing ``<origin>`` is the
identity; a missing ``<axis>`` is (1, 0, 0), and an axis is normalised; a
continuous joint has no position limits whatever ``<limit>`` says; a
``<limit>`` whose lower is above its upper is no limit (PyBullet's own
convention, ``lower=1 upper=-1``; said in a note); the inertia is given about
the centre of mass in the inertial frame, which ``<inertial><origin rpy>``
rotates (the description stores it in link axes); ``type="spherical"``
(PyBullet's extension) is a ball joint, its axis and its cone limits
(``lower``, ``upper``, ``twist``) left out as every limit is. A file that still holds
xacro (``xacro:`` elements) is refused: it must be expanded first.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np

from engines.model.description import Body, Inertial, Joint, Limits, ModelDescription, ModelError
from engines.model.kinematics import rpy_matrix
from engines.model.source import ModelSource, unexpanded_xacro


#: The world body and the joint a floating base adds above a URDF's root link (names no URDF link takes).
WORLD, FLOATING = "__world__", "__floating_base__"


def read(source: ModelSource, mimic_independent: bool = False, floating: bool = False) -> ModelDescription:
    """The description of a URDF source; ModelError naming the link or joint for what it cannot hold.

    floating : the root link joined to the world by a floating joint (``--base floating``); URDF's default,
    and this one's, is the root welded to the world."""
    robot = source.root
    _refuse_xacro(source.label, robot)
    links = robot.findall("link")
    joints, notes = [], []
    for element in robot.findall("joint"):
        joint = _joint(element)
        lo, hi = joint.limits.lower, joint.limits.upper
        if lo is not None and hi is not None and lo > hi:
            notes.append(f"joint {joint.name}: <limit lower=\"{lo:g}\" upper=\"{hi:g}\"> (lower above upper) is "
                         f"PyBullet's convention for no limit: read as unlimited")
            joint = replace(joint, limits=replace(joint.limits, lower=None, upper=None))
        joints.append(joint)
    bodies = {}
    for element in links:
        name = _name(element, "link")
        bodies[name] = (name, _inertial(element, name))
    if not bodies:
        raise ModelError(f"model {source.label}: no <link> elements; a URDF needs at least one link")
    parent_of = {j.child: j for j in joints}
    children: dict[str, list[Joint]] = {}
    for joint in joints:
        children.setdefault(joint.parent, []).append(joint)
    roots = [name for name in bodies if name not in parent_of]
    root = roots[0] if len(roots) == 1 else next(iter(bodies))
    # Depth-first from the root, children in file order; ModelDescription refuses what is not one tree.
    ordered_joints: list[Joint] = []
    ordered_links = [root] if len(roots) == 1 else []
    stack = list(reversed(children.get(root, []))) if len(roots) == 1 else []
    while stack:
        joint = stack.pop()
        if joint.child in ordered_links:
            break  # a loop: the description names it
        ordered_joints.append(joint)
        ordered_links.append(joint.child)
        stack.extend(reversed(children.get(joint.child, [])))
    ordered_links += [n for n in bodies if n not in ordered_links]
    ordered_joints += [j for j in joints if j not in ordered_joints]
    body_records = tuple(Body(n, parent_of[n].name if n in parent_of else None, bodies[n][1]) for n in ordered_links)
    if floating and len(roots) == 1:
        body_records = (Body(WORLD, None), *(replace(b, parent_joint=FLOATING) if b.name == root else b
                                             for b in body_records))
        ordered_joints.insert(0, Joint(FLOATING, "floating", WORLD, root))
        root = WORLD
    return ModelDescription(name=robot.get("name", source.path.stem), source=source.label, format="urdf",
                            root=root, bodies=body_records, joints=tuple(ordered_joints), notes=tuple(notes),
                            mimic_independent=mimic_independent)


#: The namespace of xacro, the ROS macro language whose files must be expanded into URDF before use.
XACRO = "{http://www.ros.org/wiki/xacro}"


def _refuse_xacro(label: str, robot: ET.Element) -> None:
    if any(isinstance(e.tag, str) and e.tag.startswith(XACRO) for e in robot.iter()):
        raise unexpanded_xacro(label)


def _name(element: ET.Element, kind: str) -> str:
    name = element.get("name")
    if not name:
        raise ModelError(f"a <{kind}> has no name attribute; give every {kind} a unique name")
    return name


def _numbers(element: ET.Element | None, attribute: str, default: tuple[float, ...], where: str) -> tuple[float, ...]:
    if element is None or element.get(attribute) is None:
        return default
    text = element.get(attribute, "")
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        values = ()
    if not values and ("$(" in text or "${" in text):
        raise ModelError(f"{where}: {element.tag} {attribute}={text!r} is an unexpanded xacro substitution; "
                         f"expand the file with xacro first")
    if len(values) != len(default) or not all(math.isfinite(v) for v in values):
        raise ModelError(f"{where}: {element.tag} {attribute}={text!r} is not {len(default)} finite numbers; fix it")
    return values


def _number(element: ET.Element | None, attribute: str, default: float | None, where: str) -> float | None:
    if element is None or element.get(attribute) is None:
        return default
    return _numbers(element, attribute, (0.0,), where)[0]


def _inertial(link: ET.Element, name: str) -> Inertial:
    element = link.find("inertial")
    if element is None:
        return Inertial(declared=False)
    where = f"link {name}"
    origin = element.find("origin")
    xyz = _numbers(origin, "xyz", (0.0, 0.0, 0.0), where)
    rpy = _numbers(origin, "rpy", (0.0, 0.0, 0.0), where)
    mass = _number(element.find("mass"), "value", 0.0, where)
    tensor = element.find("inertia")
    ixx, ixy, ixz, iyy, iyz, izz = (_number(tensor, k, 0.0, where) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    local = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    rotation = rpy_matrix(rpy)
    in_link = rotation @ local @ rotation.T
    return Inertial(mass=mass, com=xyz, inertia=tuple(tuple(float(v) for v in row) for row in in_link),
                    declared=True, rotated=any(abs(a) > 0 for a in rpy))


def _joint(element: ET.Element) -> Joint:
    name = _name(element, "joint")
    where = f"joint {name}"
    kind = element.get("type", "")
    if kind == "spherical":  # PyBullet's ball joint
        kind = "ball"
    if kind == "floating":  # the one floating joint is the base's, asked for with --base floating
        raise ModelError(f"{where}: type 'floating' is not supported; the base is welded to the world; "
                         f"remove the floating joint")
    parent, child = element.find("parent"), element.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise ModelError(f"{where}: needs <parent link=…> and <child link=…>; add them")
    origin = element.find("origin")
    axis = np.array(_numbers(element.find("axis"), "xyz", (1.0, 0.0, 0.0), where))
    norm = float(np.linalg.norm(axis))
    if kind in ("revolute", "continuous", "prismatic"):
        if norm == 0:
            raise ModelError(f"{where}: <axis xyz=\"0 0 0\"> has no direction; give the joint's axis")
        axis = axis / norm
    limit, dynamics, mimic = element.find("limit"), element.find("dynamics"), element.find("mimic")
    bounded = kind in ("revolute", "prismatic")
    limits = Limits(
        lower=_number(limit, "lower", 0.0 if limit is not None else None, where) if bounded else None,
        upper=_number(limit, "upper", 0.0 if limit is not None else None, where) if bounded else None,
        effort=_number(limit, "effort", None, where),
        velocity=_number(limit, "velocity", None, where),
    )
    return Joint(
        name=name, type=kind, parent=parent.get("link"), child=child.get("link"),
        axis=tuple(float(a) for a in axis), xyz=_numbers(origin, "xyz", (0.0, 0.0, 0.0), where),
        rpy=_numbers(origin, "rpy", (0.0, 0.0, 0.0), where), limits=limits,
        damping=_number(dynamics, "damping", 0.0, where), friction=_number(dynamics, "friction", 0.0, where),
        mimic=None if mimic is None else mimic.get("joint", "?"),
    )
