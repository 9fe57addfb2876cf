"""MuJoCo adapter: the scenes as a MuJoCo user would build them, in two formulations.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/mujoco/adapter.py``.
"""

from __future__ import annotations

import re
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, ModelImport, RawRun, Schedule, refuse_ellipse
from engines.errors import Unsupported, UserError
from engines.model.stepping import run_model
from engines.mujoco import description, model
from engines.mujoco.library import mj_rollout, mujoco
from engines.mujoco import options as tables
from engines.mujoco.options import MIN_INERTIA, MUJOCO_SOLIMP, MUJOCO_SOLREF
from engines.recorder import Recorder
from engines.scene.scene import Ellipse, Line, Pin, Scene, ModelSceneLike
from engines.scene.tree import Tree, read_tree

#: Steps per rollout call: long enough that the per-call overhead is negligible against the steps,
#: short enough that the state buffer stays a few MB.
CHUNK_STEPS = 20_000

_WARNINGS = {
    int(mujoco.mjtWarning.mjWARN_BADQACC): "bad acceleration (mjWARN_BADQACC)",
    int(mujoco.mjtWarning.mjWARN_BADQVEL): "bad velocity (mjWARN_BADQVEL)",
    int(mujoco.mjtWarning.mjWARN_BADQPOS): "bad position (mjWARN_BADQPOS)",
    int(mujoco.mjtWarning.mjWARN_INERTIA): "bad inertia (mjWARN_INERTIA)",
    int(mujoco.mjtWarning.mjWARN_CNSTRFULL): "constraint buffer full (mjWARN_CNSTRFULL)",
}


# -- structure of a scene ----------------------------------------------------------


def constraint_tree(scene: Scene) -> Tree:
    """The scene's tree of joints (:func:`engines.scene.tree.read_tree`), or Unsupported for what the hinge
    formulation cannot build: an Ellipse, a particle not hung from a Pin or Line, a loop through a Line."""
    refuse_ellipse(scene, _NO_ELLIPSE)
    tree = read_tree(scene)
    if tree.loose:
        raise Unsupported(
            f"mujoco/hinge: particles {tree.loose} are not hung from a Pin; the hinge formulation builds "
            "chains from a fixed anchor (use mujoco/connect for free-floating bodies)"
        )
    for k in tree.closures:
        if isinstance(scene.constraints[k], Line):
            raise Unsupported(
                f"mujoco/hinge: constraint {k} holds an already-jointed particle on a line, a loop MuJoCo "
                "cannot close (it has no point-on-line equality)"
            )
    return tree


_NO_ELLIPSE = (
    "MuJoCo cannot hold a body on an ellipse: its joints move a point on a circle (hinge) or a line "
    "(slide), and no equality constraint holds one on a curve"
)


@dataclass(frozen=True)
class ClosureArm:
    """The arm that closes loop constraint k: a body hinged at ``pivot`` (a child of particle ``host``'s
    body, or of the world when ``host`` is −1), reaching to particle ``far``, joined to it by a connect."""

    constraint: int
    host: int
    far: int
    pivot: np.ndarray


def closure_arm(scene: Scene, k: int) -> ClosureArm:
    """A Pin's arm is hinged at its anchor (on the world); a Rod's at its first particle (on that body)."""
    c = scene.constraints[k]
    if isinstance(c, Pin):
        return ClosureArm(k, -1, c.particle, np.asarray(c.anchor, dtype=float))
    return ClosureArm(k, c.a, c.b, scene.initial_positions[c.a])


def arm_owners(scene: Scene) -> list[int]:
    """For each constraint, the particle whose body carries its arm (connect formulation).

    A Pin's arm belongs to its particle; a Rod's to either end. No body may own
    two arms, so this is a bipartite matching (augmenting paths), preferring a
    Rod's second particle so a chain hung from a Pin matches at once.
    """
    for k, c in enumerate(scene.constraints):
        if isinstance(c, Ellipse):
            raise Unsupported(f"{_NO_ELLIPSE}; constraints[{k}] is an 'ellipse'")
        if isinstance(c, Line):
            raise Unsupported(
                f"mujoco/connect: MuJoCo has no equality constraint that holds a point on a line "
                f"(constraints[{k}] is a 'line'); use mujoco/hinge, whose slide joint does"
            )
    n = len(scene.particles)
    owner_of_particle = [-1] * n
    candidates = [
        [c.particle] if isinstance(c, Pin) else [c.b, c.a] for c in scene.constraints
    ]

    def place(k: int, seen: set[int]) -> bool:
        for i in candidates[k]:
            if i in seen:
                continue
            seen.add(i)
            if owner_of_particle[i] == -1 or place(owner_of_particle[i], seen):
                owner_of_particle[i] = k
                return True
        return False

    for k in range(len(scene.constraints)):
        if not place(k, set()):
            raise Unsupported(
                f"mujoco/connect: constraint {k} cannot get an arm of its own (more constraints than "
                "particles in a connected group: a closed loop), and connect joints are ball joints, "
                "not distance constraints; use mujoco/hinge, which closes a loop with an equality"
            )
    owners = [-1] * len(scene.constraints)
    for i, k in enumerate(owner_of_particle):
        if k >= 0:
            owners[k] = i
    return owners


# -- MJCF ------------------------------------------------------------------------------


def _fmt(values) -> str:
    return " ".join(repr(float(v)) for v in np.atleast_1d(values))


def _header(scene: Scene, dt: float, settings: Mapping[str, Any]) -> list[str]:
    refsafe = "" if settings["refsafe"] else ' refsafe="disable"'
    return [
        f'<mujoco model="xval-{scene.name}">',
        f'  <option timestep="{dt!r}" gravity="{_fmt(scene.gravity)}" integrator="{settings["integrator"]}">',
        f'    <flag contact="disable"{refsafe}/>',
        "  </option>",
        "  <worldbody>",
    ]


def _inertial(mass: float, inertia: float, pos=(0.0, 0.0, 0.0)) -> str:
    return f'<inertial pos="{_fmt(pos)}" mass="{mass!r}" diaginertia="{_fmt([inertia] * 3)}"/>'


def hinge_mjcf(scene: Scene, dt: float, settings: Mapping[str, Any], inertia: np.ndarray) -> str:
    """Nested bodies, one per particle, with a hinge about +y (planar) or a ball joint (3-D), a slide
    joint for a particle on a Line; loop closures as arm bodies joined by connect equalities."""
    tree = constraint_tree(scene)
    q = scene.initial_positions
    joint = '<joint type="hinge" axis="0 1 0"/>' if scene.is_planar else '<joint type="ball"/>'
    children: dict[int, list[int]] = {}
    for i in tree.order:
        children.setdefault(tree.parent[i], []).append(i)
    arms = [closure_arm(scene, k) for k in tree.closures]
    arm_mass = settings["inertia_ratio"] * float(scene.masses.mean())
    arm_inertia = arm_mass * scene.characteristic_length**2

    def arm_body(arm: ClosureArm, origin: np.ndarray, pad: str) -> list[str]:
        return [
            f'{pad}<body name="arm{arm.constraint}" pos="{_fmt(origin)}">',
            f"{pad}  {joint}",
            f"{pad}  {_inertial(arm_mass, arm_inertia)}",
            f"{pad}</body>",
        ]

    def body(i: int, depth: int) -> list[str]:
        pad = "  " * depth
        origin = tree.pivot[i] if tree.parent[i] == -1 else q[tree.parent[i]] - tree.pivot[tree.parent[i]]
        arm = q[i] - tree.pivot[i]
        root = scene.constraints[tree.constraint_of[i]]
        own = f'<joint type="slide" axis="{_fmt(root.unit)}"/>' if isinstance(root, Line) else joint
        lines = [
            f'{pad}<body name="p{i}" pos="{_fmt(origin)}">',
            f"{pad}  {own}",
            f"{pad}  {_inertial(scene.particles[i].mass, inertia[i], arm)}",
            f'{pad}  <site name="s{i}" pos="{_fmt(arm)}"/>',
        ]
        for j in children.get(i, []):
            lines += body(j, depth + 1)
        for a in arms:
            if a.host == i:
                lines += arm_body(a, q[i] - tree.pivot[i], pad + "  ")
        return lines + [f"{pad}</body>"]

    lines = _header(scene, dt, settings)
    for i in children.get(-1, []):
        lines += body(i, 2)
    for a in arms:
        if a.host == -1:
            lines += arm_body(a, a.pivot, "    ")
    lines.append("  </worldbody>")
    if arms:
        solref, solimp = equality_softness(settings, dt)
        soft = f' solref="{_fmt(solref)}" solimp="{_fmt(solimp)}"'
        lines.append("  <equality>")
        for a in arms:
            lines.append(
                f'    <connect name="c{a.constraint}" body1="arm{a.constraint}" body2="p{a.far}" '
                f'anchor="{_fmt(q[a.far] - a.pivot)}"{soft}/>'
            )
        lines.append("  </equality>")
    return "\n".join(lines + ["</mujoco>"])


def connect_mjcf(scene: Scene, dt: float, settings: Mapping[str, Any], inertia: np.ndarray) -> str:
    """Free bodies at the particles, joined by connect equalities at the end of each constraint's arm."""
    q = scene.initial_positions
    lines = _header(scene, dt, settings)
    for i, p in enumerate(scene.particles):
        lines += [
            f'    <body name="p{i}" pos="{_fmt(p.position)}">',
            "      <freejoint/>",
            f"      {_inertial(p.mass, inertia[i])}",
            f'      <site name="s{i}"/>',
            "    </body>",
        ]
    lines += ["  </worldbody>", "  <equality>"]
    solref, solimp = equality_softness(settings, dt)
    soft = ""
    if solref != MUJOCO_SOLREF:
        soft += f' solref="{_fmt(solref)}"'
    if solimp != MUJOCO_SOLIMP:
        soft += f' solimp="{_fmt(solimp)}"'
    for k, (c, owner) in enumerate(zip(scene.constraints, arm_owners(scene))):
        far = np.asarray(c.anchor) if isinstance(c, Pin) else q[c.a if owner == c.b else c.b]
        other = "" if isinstance(c, Pin) else f' body2="p{c.a if owner == c.b else c.b}"'
        lines.append(f'    <connect name="c{k}" body1="p{owner}"{other} anchor="{_fmt(far - q[owner])}"{soft}/>')
    return "\n".join(lines + ["  </equality>", "</mujoco>"])


def equality_softness(settings: Mapping[str, Any], dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(solref, solimp) for the connect equalities; ``timeconst_steps`` > 0 replaces the time constant by that many dt."""
    solref = tuple(settings["solref"])
    if settings["timeconst_steps"] > 0:
        solref = (settings["timeconst_steps"] * dt, solref[1])
    return solref, tuple(settings["solimp"])


# -- the adapter -------------------------------------------------------------------------


#: Per thread: compiled models and an MjData for each, by their MJCF with the timestep left out, the
#: most recently used last (see _model_and_data).
_CACHE = threading.local()
#: Models kept per thread: more than the scenes x variants of a suite's dt sweep, which it cycles through.
_MODELS_KEPT = 32
#: A model whose MjData maps more than this (bytes of arena) is not kept: its address space would
#: count against the case host's memory limit.
_LARGEST_KEPT = 64 * 2**20


def _model_and_data(xml: str, dt: float) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """This thread's model compiled from ``xml``, with timestep ``dt`` s, and an MjData for it, reset.

    Compiling the MJCF and making an MjData (whose binding builds a view of
    every field) were most of what a case cost besides stepping (cProfile of
    the case host over the default suite), and a dt sweep
    runs each MJCF at every dt. The models of one MJCF at two timesteps differ
    only in ``opt.timestep``, and the stiff variants', whose time constant
    follows dt, also in the equalities' ``solref``: the compiler copies both
    into the model and derives nothing from them. So a thread keeps the model
    and MjData of each MJCF it ran (the key leaves both out), sets them for
    the run, and resets the data (``mj_resetData``: what a new MjData starts
    from). The model is the run's alone while it runs (one thread runs one
    case at a time); a run never changes it.
    """
    solrefs: list[str] = []  # the connect equalities' solref numbers, taken out of the key

    def take_solref(match: re.Match) -> str:
        solrefs.append(match.group(2))
        return f'{match.group(1)} solref=""'

    key = _SOLREF.sub(take_solref, without_timestep(xml))
    kept = getattr(_CACHE, "models", None)
    if kept is None:
        kept = _CACHE.models = OrderedDict()
    entry = kept.get(key)
    if entry is None:
        model = mujoco.MjModel.from_xml_string(xml)
        entry = model, mujoco.MjData(model)
        if model.narena <= _LARGEST_KEPT:
            kept[key] = entry
            while len(kept) > _MODELS_KEPT:
                kept.popitem(last=False)
        return entry
    kept.move_to_end(key)
    model, data = entry
    model.opt.timestep = dt
    if solrefs:  # every connect equality has the same solref (equality_softness)
        model.eq_solref[:] = [float(x) for x in solrefs[0].split()]
    mujoco.mj_resetData(model, data)
    return model, data


def without_timestep(xml: str) -> str:
    """The MJCF ``xml`` with its option's timestep left out: a key for what does not depend on dt."""
    return _TIMESTEP.sub('timestep=""', xml, count=1)


_TIMESTEP = re.compile(r'timestep="[^"]*"')

#: A connect equality's solref attribute in an MJCF (group 1: the element up to it; group 2: its
#: numbers). Only the equalities': a solref anywhere else stays in _model_and_data's key (a model per
#: value) and never reaches eq_solref.
_SOLREF = re.compile(r'(<connect [^>]*?) solref="([^"]*)"')


class MuJoCoEngine(Engine):
    """MuJoCo: reduced coordinates (hinge / ball joints) and maximal coordinates (connect equalities)."""

    name = "mujoco"
    capabilities = frozenset({"3d", "constraint-forces", "model"})
    # The option tables (engines/mujoco/options.py).
    options, variants, variant_docs, overrides = tables.OPTIONS, tables.VARIANTS, tables.VARIANT_DOCS, tables.OVERRIDES

    def version(self) -> str:
        return mujoco.mj_versionString()

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        return run_model(scene, schedule, model.MujocoStepper(scene, schedule.dt, settings["integrator"]))

    def model_import(self) -> ModelImport:
        return ModelImport(model.version, model.load, frozenset({"balance_inertia"}), model.compiler_options,
                           describes=frozenset({"mjcf"}), describe=description.read)

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        if settings["formulation"] != "hinge":
            raise Unsupported("mujoco: a model file is compiled in joint coordinates; the connect variants "
                              "build particle scenes from free bodies, use mujoco/hinge*")

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        if len(settings["solref"]) != 2 or not all(x > 0 for x in settings["solref"]):
            raise UserError(
                f"mujoco: option solref must be two positive numbers (timeconst s, dampratio), "
                f"got {settings['solref']}"
            )
        if len(settings["solimp"]) not in (3, 5) or not all(0 < x < 1 for x in settings["solimp"][:2]):
            raise UserError(
                "mujoco: option solimp must be 3 or 5 numbers (dmin, dmax, width[, midpoint, power]) "
                f"with dmin and dmax in (0, 1), got {settings['solimp']}"
            )
        if settings["timeconst_steps"] < 0:
            raise UserError(f"mujoco: option timeconst_steps must be ≥ 0, got {settings['timeconst_steps']}")
        if settings["inertia_ratio"] <= 0:
            raise UserError(f"mujoco: option inertia_ratio must be positive, got {settings['inertia_ratio']}")

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        if settings["formulation"] == "hinge":
            constraint_tree(scene)
        else:
            arm_owners(scene)

    # -- building ----------------------------------------------------------------------

    def build(self, scene: Scene, dt: float, settings: Mapping[str, Any]) -> tuple[mujoco.MjModel, str, np.ndarray]:
        """(compiled model, MJCF text, (n,) kg·m² inertia of each particle body); the model is the caller's."""
        xml, inertia = self.mjcf(scene, dt, settings)
        return mujoco.MjModel.from_xml_string(xml), xml, inertia

    def mjcf(self, scene: Scene, dt: float, settings: Mapping[str, Any]) -> tuple[str, np.ndarray]:
        """The MJCF text of ``scene`` at timestep ``dt`` s and the (n,) kg·m² inertia of each particle body."""
        # MuJoCo's floor is absolute (mjMINVAL kg·m²), the ratio is relative: a small scene (the
        # 1 mm bead: m·L² = 1e-6) gets the least inertia MuJoCo compiles instead of a refusal.
        inertia = np.maximum(settings["inertia_ratio"] * scene.masses * scene.characteristic_length**2, MIN_INERTIA)
        settings = {**settings, "solimp": _full_solimp(settings["solimp"])}
        make = hinge_mjcf if settings["formulation"] == "hinge" else connect_mjcf
        return make(scene, dt, settings, inertia), inertia

    # -- running -----------------------------------------------------------------------

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        xml, inertia = self.mjcf(scene, schedule.dt, settings)
        model, data = _model_and_data(xml, schedule.dt)
        hinge = settings["formulation"] == "hinge"
        if hinge:
            data.qvel[:] = hinge_velocities(scene, model)
        else:
            data.qvel[:] = connect_velocities(scene)
        mujoco.mj_forward(model, data)

        state_spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        nstate = mujoco.mj_stateSize(model, state_spec)
        initial = np.empty((1, nstate))
        mujoco.mj_getState(model, data, initial[0], state_spec)
        sample_steps = schedule.sample_steps
        states = np.empty((len(sample_steps), nstate))
        states[0] = initial[0]
        rec = Recorder(scene, schedule)
        recorded, steps_done, message = 1, 0, ""

        heard: list[str] = []
        previous_handler = mujoco.get_mju_user_warning()
        # MuJoCo prints warnings and appends them to MUJOCO_LOG.TXT in the working directory;
        # collect them for RunInfo instead (the handler is process-wide, so restore it after).
        mujoco.set_mju_user_warning(heard.append)
        runner = mj_rollout.Rollout(nthread=0)
        buffer = np.empty((1, min(CHUNK_STEPS, schedule.n_steps), nstate))
        warmstart = np.zeros((1, model.nv))
        models, datas = [model], [data]
        try:
            while steps_done < schedule.n_steps:
                nstep = min(buffer.shape[1], schedule.n_steps - steps_done)
                out = buffer[:, :nstep]  # a leading axis of 1 keeps the slice C-contiguous
                warmstart[0] = data.qacc_warmstart
                with rec.stepping():
                    # skip_checks: the shapes are right by construction, and the checks cost more than short chunks.
                    runner.rollout(
                        models, datas, initial, None, skip_checks=True, nstep=nstep,
                        initial_warmstart=warmstart, state=out,
                    )
                warned = [w for w in _WARNINGS if data.warning[w].number > 0]
                good = nstep
                if warned:
                    # The reset sets the clock back, so the first row whose time is not its step's is the reset.
                    expected = (steps_done + 1 + np.arange(nstep)) * schedule.dt
                    off = np.abs(out[0, :, 0] - expected) > 0.5 * schedule.dt
                    good = int(np.argmax(off)) if off.any() else nstep - 1
                    said = f" ({heard[0].strip()})" if heard else ""
                    message = (
                        f"MuJoCo raised {', '.join(_WARNINGS[w] for w in warned)}{said} in the step from "
                        f"t = {(steps_done + good) * schedule.dt:.6g} s and reset its state; the samples end before it"
                    )
                rows = sample_steps[(sample_steps > steps_done) & (sample_steps <= steps_done + good)]
                states[recorded : recorded + len(rows)] = out[0, rows - steps_done - 1]
                recorded += len(rows)
                steps_done += good
                if warned:
                    break
                initial[0] = out[0, nstep - 1]
        finally:
            runner.close()
            mujoco.set_mju_user_warning(previous_handler)

        positions, velocities, forces = read_samples(scene, model, data, states[:recorded], hinge)
        # The rollout ran in C to the end (or to MuJoCo's reset); the samples pass the recorder's stop rule now.
        for step, q, v, f in zip(rec.steps, positions, velocities, forces):
            if not rec.record(step, q, v, f):
                break
        n = len(rec.q_rows)
        return rec.raw_run(
            positions=positions[:n], velocities=velocities[:n], forces=forces[:n],
            steps=rec.last_step if rec.stopped else steps_done,
            message=message, settings=self._record(model, settings, inertia, schedule.dt),
        )

    def jacobian(self, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                 wrt: list[str]) -> tuple[np.ndarray, str] | None:
        """mjd_transitionFD's one-step Jacobians chained over the run (Euler and implicit hinges); None for RK4,
        which it refuses (engines/mujoco/gradients.py)."""
        from engines.mujoco import gradients  # numpy alone; imported when gradients are asked for

        return gradients.jacobian(self, scene, variant, options, dt, wrt, hinge_velocities)

    def _record(self, model: mujoco.MjModel, settings: Mapping[str, Any], inertia: np.ndarray, dt: float) -> dict:
        """The settings a reader needs to reproduce the run, read back from the compiled model."""
        record: dict[str, Any] = {
            "stepping": f"mujoco.rollout, chunks of up to {CHUNK_STEPS} steps",
            "point_mass_inertia": [float(x) for x in inertia],
            "solver": mujoco.mjtSolver(model.opt.solver).name,
            "solver_iterations": int(model.opt.iterations),
            "solver_tolerance": float(model.opt.tolerance),
            "disableflags": int(model.opt.disableflags),
        }
        if settings["formulation"] == "connect" and model.neq:
            record["effective_solref"] = [float(x) for x in model.eq_solref[0]]
            record["effective_solimp"] = [float(x) for x in model.eq_solimp[0]]
            timeconst = float(model.eq_solref[0][0])
            record["effective_timeconst"] = max(timeconst, 2 * dt) if settings["refsafe"] else timeconst
        return record


def _full_solimp(solimp: tuple[float, ...]) -> tuple[float, ...]:
    """MuJoCo's 3-number solimp form means midpoint and power keep their defaults."""
    return tuple(solimp) + MUJOCO_SOLIMP[len(solimp) :]


def hinge_velocities(scene: Scene, model: mujoco.MjModel) -> np.ndarray:
    """(nv,) joint velocities for the scene's initial particle velocities (the model is built at qpos0 = initial).

    Each link's absolute angular velocity ω solves ω × r = Δv (r the arm, Δv the
    particle's velocity relative to its pivot) with ω ⊥ r: ω = r × Δv / |r|².
    A joint velocity is relative to the parent's; at qpos0 every body frame is
    aligned with the world, so local and world components agree.
    """
    tree = constraint_tree(scene)
    q, v = scene.initial_positions, scene.initial_velocities
    omega = np.zeros((len(q), 3))
    qvel = np.zeros(model.nv)
    for i in tree.order:
        parent = tree.parent[i]
        joint = model.body_jntadr[model.body(f"p{i}").id]
        dof = model.jnt_dofadr[joint]
        root = scene.constraints[tree.constraint_of[i]]
        if isinstance(root, Line):  # a slide joint: the speed along the line; the body does not turn
            qvel[dof] = float(v[i] @ root.unit)
            continue
        r = q[i] - tree.pivot[i]
        dv = v[i] - (v[parent] if parent >= 0 else 0.0)
        omega[i] = np.cross(r, dv) / float(r @ r)
        relative = omega[i] - (omega[parent] if parent >= 0 else 0.0)
        if scene.is_planar:
            qvel[dof] = relative[1]
        else:
            qvel[dof : dof + 3] = relative
    for k in tree.closures:  # each arm turns so that its tip moves with the particle it reaches
        arm = closure_arm(scene, k)
        r = q[arm.far] - arm.pivot
        dv = v[arm.far] - (v[arm.host] if arm.host >= 0 else 0.0)
        relative = np.cross(r, dv) / float(r @ r) - (omega[arm.host] if arm.host >= 0 else 0.0)
        dof = model.jnt_dofadr[model.body_jntadr[model.body(f"arm{k}").id]]
        if scene.is_planar:
            qvel[dof] = relative[1]
        else:
            qvel[dof : dof + 3] = relative
    return qvel


def connect_velocities(scene: Scene) -> np.ndarray:
    """(6·n,) free-joint velocities: each particle's velocity, and the angular velocity its arm must have.

    A free joint's qvel is the body origin's linear velocity (world frame) then
    the angular velocity (body frame, the world's at qpos0). The arm r (owner
    to far end) must turn so that its tip moves with the far end:
    ω × r = Δv, taken ⊥ r (no spin about the arm): ω = r × Δv / |r|². Leaving ω
    at 0 would start the constraint with a velocity violation of |Δv|.
    """
    q, v = scene.initial_positions, scene.initial_velocities
    qvel = np.zeros((len(q), 6))
    qvel[:, :3] = v
    for c, owner in zip(scene.constraints, arm_owners(scene)):
        if isinstance(c, Pin):
            far, far_velocity = np.asarray(c.anchor), np.zeros(3)
        else:
            other = c.a if owner == c.b else c.b
            far, far_velocity = q[other], v[other]
        r = far - q[owner]
        qvel[owner, 3:] = np.cross(r, far_velocity - v[owner]) / float(r @ r)
    return qvel.ravel()


def read_samples(
    scene: Scene, model: mujoco.MjModel, data: mujoco.MjData, states: np.ndarray, hinge: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, P, 3) m, velocities (n, P, 3) m/s and constraint forces (n, C, 3) N at each state.

    Each state is loaded and ``mj_forward``-ed (and, hinge, ``mj_rnePostConstraint``);
    what is read from it is copied out as it stands, and turned into the result
    for all samples at once afterwards, with array arithmetic rather than a
    Python call per particle and sample (most of what reading a run cost):

    - positions: each particle's site, ``site_xpos``;
    - velocities: what ``mj_objectVelocity`` gives for the site in world
      orientation: the body's com-based velocity ``cvel`` (rotation, linear)
      moved from its tree's centre of mass to the site, v = v_c − (p − c) × ω;
    - forces: those MuJoCo applies at that state, as the force on each
      constraint's first particle (:class:`_ForceReader`).
    """
    n, n_p = len(states), len(scene.particles)
    sites = np.array([model.site(f"s{i}").id for i in range(n_p)], dtype=int)
    bodies = model.site_bodyid[sites]
    roots = model.body_rootid[bodies]
    # Views of data's buffers, taken once (they stay put as data changes); each sample copies them
    # whole (a model has a handful of sites and bodies), and the rows wanted are picked out after
    # the loop: the fewest Python calls per sample.
    site_xpos, cvel, subtree_com = data.site_xpos, data.cvel, data.subtree_com
    all_xpos, all_cvel, all_com = (np.empty((n,) + a.shape) for a in (site_xpos, cvel, subtree_com))
    reader = _ForceReader(scene, model, hinge, n, data)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    set_state, forward, rne_post_constraint = mujoco.mj_setState, mujoco.mj_forward, mujoco.mj_rnePostConstraint
    for s, state in enumerate(states):
        set_state(model, data, state, full)
        forward(model, data)
        all_xpos[s] = site_xpos
        all_cvel[s] = cvel
        all_com[s] = subtree_com
        if hinge:
            rne_post_constraint(model, data)
        reader.read(s, data)
    positions, spatial, centres = all_xpos[:, sites], all_cvel[:, bodies], all_com[:, roots]
    velocities = spatial[..., 3:] - np.cross(positions - centres, spatial[..., :3])
    return positions, velocities, reader.forces()


class _ForceReader:
    """Collects, sample by sample, what each constraint's force on its first particle is made of, and
    gives them all as one (n, C, 3) N array (:meth:`forces`).

    hinge: cfrc_int's force part of each particle's body is what the parent
    exerts on the body's subtree through the joint; the body is a massless arm
    ending at its particle, so it is the link's force on that particle. The
    record's first particle is the child (Pin, Line, or a Rod whose a is the
    child: sign +) or the parent (sign −). A loop closure's force is its
    connect's efc force (on the arm, body1): the arm carries it to its host (+),
    the particle it reaches gets the negative.

    connect: a connect's three efc rows are the world-frame force on body1
    (qfrc = Jᵀf, J = ∂(p1 − p2)/∂q); body1 is the arm's owner, so the sign is +
    when the owner is the constraint's first particle (Pin.particle, Rod.a).
    The equality rows' indices in efc are found at the first state, and again
    only when the number of constraint rows changes.
    """

    def __init__(self, scene: Scene, model: mujoco.MjModel, hinge: bool, n: int, data: mujoco.MjData) -> None:
        self.n_c = len(scene.constraints)
        self.hinge = hinge
        self.rows = np.zeros((0, 3), dtype=int)  # (E, 3) efc rows of each equality's force components
        self.nefc = -1
        if hinge:
            tree = constraint_tree(scene)
            n_p = len(scene.particles)
            self.bodies = np.array([model.body(f"p{i}").id for i in range(n_p)], dtype=int)
            self.slots = np.array([tree.constraint_of[i] for i in range(n_p)], dtype=int)
            self.body_signs = np.array([
                1.0 if isinstance(scene.constraints[tree.constraint_of[i]], (Pin, Line))
                or scene.constraints[tree.constraint_of[i]].a == i else -1.0
                for i in range(n_p)
            ])[:, None]
            self.cfrc_int = data.cfrc_int  # a view of data's buffer, copied whole at each sample
            self.all_cfrc_int = np.empty((n,) + self.cfrc_int.shape)
            # Equality e closes constraint tree.closures[e]: a closing Pin's first particle is the one
            # the arm reaches (−), a closing Rod's (a) hosts the arm (+).
            self.eq_slots = np.array(tree.closures, dtype=int)
            self.eq_signs = np.array([-1.0 if isinstance(scene.constraints[k], Pin) else 1.0
                                      for k in tree.closures])[:, None]
        else:
            owners = arm_owners(scene)
            self.eq_slots = np.arange(self.n_c)
            self.eq_signs = np.array([
                1.0 if owners[k] == (c.particle if isinstance(c, Pin) else c.a) else -1.0
                for k, c in enumerate(scene.constraints)
            ])[:, None]
        self.eq_forces = np.empty((n, len(self.eq_slots), 3))

    def read(self, s: int, data: mujoco.MjData) -> None:
        """Keep sample ``s``'s raw forces from ``data`` (after mj_forward, and mj_rnePostConstraint for hinge)."""
        if len(self.eq_slots):
            if data.nefc != self.nefc:
                self.nefc = data.nefc
                equality = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
                self.rows = np.array([np.flatnonzero(equality & (data.efc_id == e))
                                      for e in range(len(self.eq_slots))], dtype=int).reshape(-1, 3)
            self.eq_forces[s] = data.efc_force[self.rows]
        if self.hinge:
            self.all_cfrc_int[s] = self.cfrc_int

    def forces(self) -> np.ndarray:
        """(n, C, 3) N: each constraint's force on its first particle at every sample read."""
        n = len(self.eq_forces)
        out = np.zeros((n, self.n_c, 3))
        if len(self.eq_slots):
            out[:, self.eq_slots] = self.eq_signs * self.eq_forces
        if self.hinge:
            out[:, self.slots] = self.body_signs * self.all_cfrc_int[:n, self.bodies, 3:]
        return out


ENGINE = MuJoCoEngine()
