"""Why an engine's dynamics differ: its mass properties per link against the file's, in words.

Each engine's links at q = 0 in the world frame (mass, COM, rotational
inertia about the COM) are compared with what the description says. An
engine that fused welded links holds them under the survivor's name: the
file's links are combined the same way before comparing, and when the
group differs, known importer habits (dropping the inertia of massless
links, giving links 1 kg and 1 kg·m²) are tried on its suspicious members
to name them. Only links that move count: the rest cannot change M or b; an
engine's hinge axes, when it says where they are, against the file's.
A difference counts when it can change an entry of M by more than
DIAGNOSED (a tenth of the check's tolerance) of M's scale S_M: an inertia
by ΔI, a mass by Δm·L², a centre of mass by about m·L·Δc (L the reach);
without S_M, the scale is the moving mass times L².
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from compare.model.tolerance import DIAGNOSED
from engines.model.description import ModelDescription
from engines.model.inertia import LinkInertia, combine, description_inertias

#: Relative size (of the model's mass, length and inertia scales) below which a difference is not named.
RELATIVE = DIAGNOSED


@dataclass(frozen=True)
class Finding:
    """links : the file's links concerned. says : what the file gives them. does : what the engine made of
    it, with ``{it}`` standing for the links (it / them)."""

    links: tuple[str, ...]
    says: str
    does: str


@dataclass(frozen=True)
class Scales:
    mass: float
    length: float

    @property
    def inertia(self) -> float:
        return self.mass * self.length ** 2


def scales(model: ModelDescription, file: dict[str, LinkInertia], m_scale: float | None = None) -> Scales:
    """The model's scales; with ``m_scale`` (S_M, the largest |M| entry of the reference) the mass scale is
    S_M / L², so that the inertia scale is S_M itself."""
    moving = model.moving_links
    reach = float(max([np.linalg.norm(file[name].com) for name in moving] + [0.01]))
    if m_scale is not None and m_scale > 0:
        return Scales(m_scale / reach ** 2, reach)
    mass = sum(file[name].mass for name in moving) or 1.0
    return Scales(mass, reach)


def differs(engine: LinkInertia, file: LinkInertia, scale: Scales) -> tuple[bool, bool, bool]:
    """(mass, COM, inertia) differ beyond round-off."""
    mass = abs(engine.mass - file.mass) > RELATIVE * scale.mass
    com = engine.mass > 0 and file.mass > 0 and np.linalg.norm(engine.com - file.com) > RELATIVE * scale.length
    inertia = np.abs(engine.inertia - file.inertia).max() > RELATIVE * scale.inertia
    return bool(mass), bool(com), bool(inertia)


def moments(inertia: np.ndarray) -> str:
    """A rotational inertia in words: one number when isotropic, else its principal moments (kg·m²)."""
    values = np.linalg.eigvalsh(inertia)
    if values[-1] - values[0] <= 1e-9 * max(abs(values[-1]), 1e-300):
        return f"{_number(values[-1])} kg·m²"
    return f"principal moments ({', '.join(_number(v) for v in values)}) kg·m²"


def _number(value: float) -> str:
    return f"{value:.3g}" if abs(value) > 1e-12 else "0"


def file_says(model: ModelDescription, link: str, file: LinkInertia) -> str:
    inertial = model.body(link).inertial
    if not inertial.declared:
        return "no <inertial>"
    if inertial.mass == 0 and np.abs(inertial.inertia_matrix).max() > 0:
        return f"mass 0 with inertia {moments(inertial.inertia_matrix)}"
    a, b, c = np.linalg.eigvalsh(file.inertia)
    against = ", against the triangle inequality (A + B < C)" if a + b < c * (1 - 1e-12) else ""
    return f"mass {_number(file.mass)} kg, inertia {moments(file.inertia)}{against}"


def _suspicious(model: ModelDescription, link: str) -> bool:
    inertial = model.body(link).inertial
    return not inertial.declared or (inertial.mass == 0 and np.abs(inertial.inertia_matrix).max() > 0)


#: Importer habits tried on the suspicious members of a fused group: (what it does, the link as imported).
HABITS = (
    ("drops the inertia", lambda link: replace(link, inertia=np.zeros((3, 3)))),
    ("gives {it} 1 kg and 1 kg·m²", lambda link: replace(link, mass=1.0, inertia=np.eye(3))),
)


def diagnose(model: ModelDescription, engine: dict[str, LinkInertia], m_scale: float | None = None) -> list[Finding]:
    """What the engine holds differently from the file, link by link (or group by group when it fused them).
    m_scale : kg·m², the largest |M| entry of the reference over the sample (see :func:`scales`)."""
    file = description_inertias(model)
    scale = scales(model, file, m_scale)
    moving = set(model.moving_links)
    groups: dict[str, list[str]] = {}
    findings: list[Finding] = []
    for body in model.bodies:
        if body.name in engine:
            groups[body.name] = [body.name]
            continue
        joint = model.joint(body.parent_joint) if body.parent_joint else None
        head = _survivor(model, body.name, engine)
        if head is not None:
            groups[head].append(body.name)
        elif body.name in moving and (joint is not None and joint.moving):
            findings.append(Finding((body.name,), file_says(model, body.name, file[body.name]), "has no body for {it}"))
    scaled = _scaled(model, engine, file, scale)
    if scaled is not None and not findings:
        return [scaled]
    for head, members in groups.items():
        if head not in moving:
            continue
        expected = combine([file[name] for name in members])
        if not any(differs(engine[head], expected, scale)):
            continue
        findings.extend(_explain(model, engine[head], members, file, scale))
    return findings


def _scaled(model: ModelDescription, engine: dict[str, LinkInertia], file: dict[str, LinkInertia],
            scale: Scales) -> Finding | None:
    """One finding when every moving link's mass and inertia are the file's times one factor k ≠ 1 (a total
    mass or a density the engine's parser does not apply: MuJoCo's <compiler settotalmass>), else None."""
    links = [name for name in model.moving_links if name in engine and file[name].mass > 0]
    total = sum(file[name].mass for name in links)
    if len(links) < 2 or len(links) != len(model.moving_links) or total <= 0:
        return None
    k = sum(engine[name].mass for name in links) / total
    if abs(k - 1) <= RELATIVE or any(any(differs(engine[name], replace(file[name], mass=k * file[name].mass,
                                                                           inertia=k * file[name].inertia), scale))
                                     for name in links):
        return None
    return Finding(tuple(links), f"{_number(total)} kg in all",
                   f"scales every mass and inertia of {{it}} by {_number(k)} (one factor: a total mass or a density "
                   f"its parser does not apply, such as <compiler settotalmass>)")


def _survivor(model: ModelDescription, link: str, engine: dict[str, LinkInertia]) -> str | None:
    """The nearest ancestor across fixed joints that the engine keeps (None: fused into the world)."""
    while True:
        parent_joint = model.body(link).parent_joint
        if parent_joint is None:
            return None
        joint = model.joint(parent_joint)
        if joint.moving:
            return None
        link = joint.parent
        if link in engine:
            return link


def _explain(model, held: LinkInertia, members: list[str], file: dict[str, LinkInertia], scale: Scales) -> list[Finding]:
    if len(members) == 1:
        return [Finding((members[0],), file_says(model, members[0], file[members[0]]), _what_changed(held, file[members[0]], scale))]
    suspects = [name for name in members if _suspicious(model, name)]
    for does, habit in HABITS:
        if suspects:
            trial = combine([habit(file[name]) if name in suspects else file[name] for name in members])
            if not any(differs(held, trial, scale)):
                return [Finding((name,), file_says(model, name, file[name]), does) for name in suspects]
    expected = combine([file[name] for name in members])
    return [Finding(tuple(members), f"welded together ({len(members)} links)", _what_changed(held, expected, scale))]


def _what_changed(held: LinkInertia, expected: LinkInertia, scale: Scales) -> str:
    mass, com, inertia = differs(held, expected, scale)
    if mass:
        text = f"gives {{it}} {_number(held.mass)} kg"
        return text + (f" and {moments(held.inertia)}" if inertia else "")
    if inertia and np.abs(held.inertia).max() <= RELATIVE * scale.inertia:
        return "drops the inertia"
    parts = []
    if com:
        parts.append(f"moves the COM by {_number(float(np.linalg.norm(held.com - expected.com)))} m")
    if inertia:
        parts.append(f"holds {moments(held.inertia)} (the file: {moments(expected.inertia)})")
    return ", ".join(parts)


def sentences(per_engine: dict[str, list[Finding]]) -> list[str]:
    """One line per set of links and what the file says: ``links a, b: says — e1 does, e2 does``."""
    merged: dict[tuple[str, str], dict[str, list[str]]] = {}  # (engine, does) -> says -> links
    for engine, findings in per_engine.items():
        for finding in findings:
            merged.setdefault((engine, finding.does), {}).setdefault(finding.says, []).extend(finding.links)
    lines: dict[tuple[tuple[str, ...], str], list[str]] = {}
    for (engine, does), by_says in merged.items():
        for says, links in by_says.items():
            pronoun = "them" if len(links) > 1 else "it"
            lines.setdefault((tuple(links), says), []).append(f"{engine} {does.format(it=pronoun)}")
    return [f"{'links' if len(links) > 1 else 'link'} {', '.join(links)}: {says} — {', '.join(doers)}"
            for (links, says), doers in lines.items()]


#: What each compared quantity is called in a diagnosis line.
QUANTITY_NAMES = {"mass_matrix": "M", "bias": "the bias", "forward": "the forward dynamics"}


def unexplained(model: ModelDescription, quantity: str, row: int) -> str:
    """The line of a disagreement no link's mass properties explain: where its largest difference is.
    row : the velocity entry (v's order: a floating base's six, then the joints', a ball's three) that differs most."""
    entry = model.dof_names[row]
    joints = [j for j in (model.floating, *model.moving_joints) if j is not None]
    joint = next((j for j in joints if entry == j.name), None) or next(j for j in joints if entry.startswith(f"{j.name}."))
    return (f"cause not found: largest difference at joint {joint.name}, link {joint.child} "
            f"(in {QUANTITY_NAMES[quantity]})")


def misplaced_joints(model: ModelDescription, engine: str, origins: dict[str, np.ndarray] | None) -> list[str]:
    """A line per revolute (continuous) joint whose axis the engine put off the file's, at q = 0: farther than
    RELATIVE times the reach from it (any point of the axis will do, so the distance is to the line); a ball
    joint's centre, likewise."""
    from engines.model.kinematics import link_poses

    if not origins:
        return []
    poses, reach = link_poses(model), _reach(model)
    lines = []
    for joint in model.moving_joints:
        if joint.name not in origins:
            continue
        rotation, where = poses[joint.child]
        axis = rotation @ np.asarray(joint.axis, dtype=float)
        offset = np.asarray(origins[joint.name], dtype=float) - where
        # A ball joint has a centre, not an axis: the distance is to that point.
        off = np.linalg.norm(offset) if joint.type == "ball" else np.linalg.norm(np.cross(offset, axis))
        if off > RELATIVE * reach:
            put = ", ".join(f"{x:.3g}" for x in origins[joint.name])
            what = "centre at" if joint.type == "ball" else "axis through"
            lines.append(f"joint {joint.name}: {engine} puts its {what} ({put}) m at q = 0, the file "
                         f"{what.split()[-1]} ({', '.join(f'{x:.3g}' for x in where)}) m")
    return lines


def _reach(model: ModelDescription) -> float:
    """m: the largest distance of a link frame from the root at q = 0 (1 m for a model with none)."""
    from engines.model.kinematics import link_poses

    return max((float(np.linalg.norm(p)) for _, p in link_poses(model).values()), default=0.0) or 1.0
