"""Dynamics parity: each engine's M(q), b(q, v) and a(q, v, tau) against Pinocchio's at sampled states.

States: a floating base anywhere within 1 m of the origin in any orientation (engines/model/floating.py);
a ball joint in any orientation (a uniform unit quaternion, its pitch kept 5° from ±90°: PITCH_MARGIN); q uniform within each joint's limits (the inner 90 %: PyBullet's limit constraints stay idle) or ±π for a
joint without them (±1 m for a prismatic one); v uniform in ±1 rad/s (m/s); tau = M_ref a* + b_ref with
a* uniform in ±1 rad/s² (m/s²), so every joint's reference acceleration is
of order one. Per quantity the relative difference is the largest
|engine − reference| over entries and states divided by the largest
|reference| over entries and states (for the bias, at least the largest
|tau|). An engine agrees when M and the bias are ≤ TOLERANCE and the forward
dynamics ≤ TOLERANCE times the amplification M's conditioning allows
(compare/model/tolerance.py derives it). Reading the file, the reference and
each engine run in a child process of their own (compare/model/isolation.py):
an engine that crashes, aborts or hangs is its own row, the others report.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from compare.model import isolation
from compare.model.diagnosis import Finding, diagnose, misplaced_joints, sentences, unexplained
from compare.model.tolerance import TOLERANCE, amplification
from engines.adapter import ModelImport
from engines.model import source as sources
from engines.model.description import ModelDescription, ModelError
from engines.model.importers import ENGINES, REFERENCE, importer
from engines.model.loaded import LoadedModel, Refused

QUANTITIES = ("mass_matrix", "bias", "forward")


class NothingToCompare(ModelError):
    """The file holds no moving joint and no floating base: no M, bias or acceleration to compare (not an error
    the user must fix; ``xval model survey`` counts it apart)."""


class CheckCrashed(Exception):
    """Reading the file or the model reference crashed or hung: nothing can be compared. ``part``: which one."""

    def __init__(self, part: str, failure: str) -> None:
        super().__init__(f"{part} {failure}")
        self.part, self.failure = part, failure


@dataclass(frozen=True)
class States:
    """q (N, nconfig), v and tau (N, nv) in the description's order (rad, m, quaternions; rad/s, m/s; N·m, N)."""

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray


@dataclass(frozen=True)
class EngineParity:
    """One engine's verdict. The three differences are None when it did not load or failed.

    failure : "" or how its child process ended without an answer ("crashed (SIGSEGV)", "timed out after 60 s").
    """

    engine: str
    version: str
    loaded: bool
    agrees: bool
    mass_matrix: float | None = None
    bias: float | None = None
    forward: float | None = None
    message: str = ""
    options: dict[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    diagnosis: tuple[str, ...] = ()
    failure: str = ""


@dataclass(frozen=True)
class ParityReport:
    model: str
    name: str
    moving_joints: tuple[str, ...]
    #: Pinocchio's answers, what every engine is compared with: the model reference (not the DOP853
    #: ``reference`` engine of the catalog's scenes).
    model_reference: EngineParity
    states: int
    seed: int
    engines: tuple[EngineParity, ...]
    notes: tuple[str, ...]
    diagnosis: tuple[str, ...]
    #: TOLERANCE times the amplification of M's conditioning: the forward dynamics' bound (inf: not judged).
    forward_tolerance: float = TOLERANCE

    @property
    def exit_code(self) -> int:
        return 0 if all(e.agrees for e in self.engines) else 1

    def to_dict(self) -> dict:
        return {"model": self.model, "name": self.name, "moving_joints": list(self.moving_joints),
                "reference": {"name": self.model_reference.engine, "version": self.model_reference.version,
                              "options": self.model_reference.options,
                              "diagnosis": list(self.model_reference.diagnosis)},
                "states": self.states, "seed": self.seed, "tolerance": TOLERANCE,
                "forward_tolerance": self.forward_tolerance if math.isfinite(self.forward_tolerance) else None,
                "engines": [_json_row(e) for e in self.engines], "notes": list(self.notes),
                "diagnosis": list(self.diagnosis)}


def _json_row(row: EngineParity) -> dict:
    """An engine's row for JSON: a difference that is not finite (an engine's M singular, its q̈ NaN) is null
    (JSON has no Infinity or NaN)."""
    found = asdict(row)
    for quantity in ("mass_matrix", "bias", "forward"):
        if found[quantity] is not None and not math.isfinite(found[quantity]):
            found[quantity] = None
    return found


def sample_states(model: ModelDescription, reference: LoadedModel, count: int, seed: int) -> States:
    rng = np.random.default_rng(seed)
    scalar = [j for j in model.moving_joints if j.type != "ball"]
    lower, upper = np.empty(len(scalar)), np.empty(len(scalar))
    for k, joint in enumerate(scalar):
        lo, hi = joint.limits.lower, joint.limits.upper
        if lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi) and hi > lo:
            middle, half = (lo + hi) / 2, 0.45 * (hi - lo)
            lower[k], upper[k] = middle - half, middle + half
        else:
            reach = math.pi if joint.type != "prismatic" else 1.0
            lower[k], upper[k] = -reach, reach
    drawn = rng.uniform(lower, upper, (count, len(scalar)))
    if model.floating is not None:  # the base anywhere within 1 m, in any orientation
        quaternions = _unit_quaternions(rng, count)
        base = np.concatenate([rng.uniform(-1.0, 1.0, (count, 3)), quaternions], axis=1)
    q = np.empty((count, model.nconfig))
    if model.floating is not None:
        q[:, :7] = base
    columns = iter(drawn.T)
    for joint in model.moving_joints:  # a ball joint in any orientation (drawn after the rest: the draws of a
        where = model.slots[joint.name][0]  # model without one are what they always were)
        q[:, where] = _ball_quaternions(rng, count) if joint.type == "ball" else next(columns)[:, None]
    v = rng.uniform(-1.0, 1.0, (count, model.nv))
    target = rng.uniform(-1.0, 1.0, (count, model.nv))
    tau = np.array([reference.mass_matrix(qk) @ ak + reference.bias(qk, vk) for qk, vk, ak in zip(q, v, target)])
    return States(q, v, tau)


#: rad: a ball joint's sampled orientation keeps its pitch (URDF's roll-pitch-yaw of the child frame in the joint
#: frame) this far from ±90°, where Drake's BallRpyJoint is singular (it raises "has reached a singularity").
PITCH_MARGIN = math.radians(5.0)


def _ball_quaternions(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 4) uniform unit quaternions, each redrawn while its pitch is within PITCH_MARGIN of ±90°."""
    out = _unit_quaternions(rng, count)
    while True:
        x, y, z, w = out.T
        near = np.abs(2 * (w * y - x * z)) > math.cos(PITCH_MARGIN)  # |sin(pitch)| = |−R[2, 0]|
        if not near.any():
            return out
        out[near] = _unit_quaternions(rng, int(near.sum()))


def _unit_quaternions(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 4) quaternions uniform over the rotations (normalised Gaussian 4-vectors)."""
    quaternions = rng.normal(size=(count, 4))
    return quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True)


def _require_invertible(model: ModelDescription, reference: LoadedModel, label: str) -> None:
    """ModelError naming the joints that move nothing with mass or inertia (M singular: no forward dynamics)."""
    m = reference.mass_matrix(model.neutral())
    scale = max(float(np.abs(m).max()), 1e-300)
    idle = [name for name, d in zip(model.dof_names, np.diag(m)) if d <= 1e-12 * scale]
    if idle:
        raise ModelError(f"model {label}: joint {', '.join(idle)} moves no mass or inertia (M is singular); "
                         f"give the links it moves an <inertial>")


def evaluate(loaded: LoadedModel, states: States) -> dict[str, list[np.ndarray]]:
    """Each quantity at every state."""
    return {
        "mass_matrix": [loaded.mass_matrix(q) for q in states.q],
        "bias": [loaded.bias(q, v) for q, v in zip(states.q, states.v)],
        "forward": [loaded.forward(q, v, t) for q, v, t in zip(states.q, states.v, states.tau)],
    }


def relative_difference(values: list[np.ndarray], reference: list[np.ndarray], floor: float = 0.0) -> float:
    """Largest |value − reference| over entries and states over the largest |reference| (at least ``floor``);
    inf for a non-finite value."""
    scale = max(float(np.max([np.abs(r).max(initial=0.0) for r in reference])), floor)
    worst = float(np.max([np.abs(np.asarray(v) - r).max(initial=0.0) for v, r in zip(values, reference)]))
    if not math.isfinite(worst):  # np.max propagates NaN, where Python's max would skip it
        return math.inf
    return worst / scale if scale > 0 else worst


#: What ``--base`` takes: a URDF's root welded to the world (URDF's default) or joined by a floating joint.
BASES = ("fixed", "floating")


def read_description(label: str, base: str = "fixed") -> tuple[sources.ModelSource, ModelDescription]:
    """The source and its description (mimic joints as independent coordinates, said in the notes); ``base``
    applies to a URDF (an MJCF says its own: a free joint)."""
    from engines.model.scene import describe

    _check_base(base)
    source = sources.resolve(label)
    return source, describe(source, base)


def _check_base(base: str) -> None:
    if base not in BASES:
        raise ModelError(f"--base: must be one of {', '.join(BASES)}, got {base!r}")


def check(label: str, engines: tuple[str, ...] = ENGINES, states: int = 100, seed: int = 0,
          balance_inertia: bool = False, timeout: float = isolation.DEFAULT_TIMEOUT,
          base: str = "fixed") -> ParityReport:
    """The parity report of model ``label``; UserError (ModelError) for bad input, before any engine runs;
    CheckCrashed when reading the file or the model reference crashed or hung. ``timeout`` : s per child process.
    ``base`` : a URDF's root "fixed" to the world or "floating"."""
    for name in engines:
        if name not in ENGINES:
            raise ModelError(f"--engine: unknown engine {name!r}; choose from {', '.join(ENGINES)}")
    if states < 1:
        raise ModelError(f"--states: must be at least 1, got {states}")
    _check_base(base)
    source = sources.resolve(label)
    source = replace(source, path=Path(source.path).absolute())  # the children work in folders of their own
    model, notes = _answer("reading the file", isolation.run(_describe, source, base, timeout=timeout))
    if model.nq == 0 and model.floating is None:
        raise NothingToCompare(f"model {label}: no moving joint (revolute, continuous or prismatic); nothing to compare")
    model_reference = _answer(f"the model reference ({REFERENCE})",
                              isolation.run(_model_reference, source, model, label, states, seed, timeout=timeout))
    results, findings = [], {}
    for name in engines:
        outcome = isolation.run(_one, name, source, model, model_reference.sample, model_reference.expected,
                                balance_inertia, model_reference.forward_tolerance, timeout=timeout,
                                prepare=functools.partial(importer, name))
        result, findings[name] = _engine_answer(name, outcome)
        results.append(result)
    reference_entry = EngineParity(REFERENCE, model_reference.version, True, True, 0.0, 0.0, 0.0,
                                   options=model_reference.options, notes=model_reference.notes,
                                   diagnosis=tuple(sentences({REFERENCE: model_reference.findings})))
    lines = sentences(findings)
    for result in results:  # every disagreement has a line: the cause, or where the largest difference is
        if result.loaded and not result.agrees and not result.failure and not findings[result.engine]:
            lines += list(result.diagnosis)
    return ParityReport(label, model.name, tuple(j.name for j in model.moving_joints), reference_entry, states,
                        seed, tuple(results), notes, tuple(lines), model_reference.forward_tolerance)


def _describe(source: sources.ModelSource, base: str) -> tuple[ModelDescription, tuple[str, ...]]:
    """The description and the notes on what the engines are given (in a child: MJCF is read by MuJoCo)."""
    from engines.model.scene import describe

    isolation.report("stage", "reading the file")
    model = describe(source, base)
    balls = (f"ball joint{'s' if len(model.balls) > 1 else ''} {', '.join(j.name for j in model.balls)}: sampled in "
             f"any orientation, the pitch kept {math.degrees(PITCH_MARGIN):g}° from ±90° (Drake's BallRpyJoint is "
             f"singular there)",) if model.balls else ()
    return model, (*model.notes, *source.engine_text(drop_mimic=model.mimic_independent)[1], *balls)


@dataclass(frozen=True)
class ModelReferencePart:
    """What the model reference's child sends back: its sample and values, its own import against the file."""

    version: str
    options: dict[str, str]
    notes: tuple[str, ...]
    findings: list[Finding]
    sample: States
    expected: dict[str, list[np.ndarray]]
    forward_tolerance: float


def _model_reference(source, model: ModelDescription, label: str, count: int, seed: int) -> ModelReferencePart:
    module = importer(REFERENCE)
    try:
        reference = module.load(source, model)
    except Refused as exc:
        raise ModelError(f"model {label}: the model reference (pinocchio) cannot load it: {exc}") from None
    _require_invertible(model, reference, label)
    sample = sample_states(model, reference, count, seed)
    expected = evaluate(reference, sample)
    bias_scale = _bias_scale(expected, sample)
    forward = TOLERANCE * amplification(expected["mass_matrix"], expected["forward"], bias_scale)
    return ModelReferencePart(module.version(), reference.options, reference.notes,
                         diagnose(model, reference.link_inertias(), _m_scale(expected)), sample, expected, forward)


def _answer(part: str, outcome: isolation.Outcome):
    """The child's value; what it raised, raised here (a ModelError is the user's); CheckCrashed when it died."""
    if outcome.failure:
        raise CheckCrashed(part, f"{outcome.failure} ({_printed_tail(outcome)})" if outcome.printed else outcome.failure)
    if outcome.error is not None:
        raise outcome.error
    return outcome.value


def _printed_tail(outcome: isolation.Outcome) -> str:
    return "it printed: " + " / ".join(outcome.printed[-3:])


def _bias_scale(expected: dict[str, list[np.ndarray]], sample: States) -> float:
    bias = max(float(np.abs(b).max(initial=0.0)) for b in expected["bias"])
    return max(bias, float(np.abs(sample.tau).max()))


def _m_scale(expected: dict[str, list[np.ndarray]]) -> float:
    return max(float(np.abs(m).max(initial=0.0)) for m in expected["mass_matrix"])


def _engine_answer(name: str, outcome: isolation.Outcome) -> tuple[EngineParity, list[Finding]]:
    """One engine's row from its child's outcome: its answer, or the crash, abort or hang, with what it printed."""
    printed = tuple(f"{name} printed: {line}" for line in outcome.printed)
    version = outcome.reported.get("version", "unknown")
    if outcome.failure:
        stage = outcome.stage or "starting"
        return EngineParity(name, version, stage == "evaluating", False, message=f"{outcome.failure} while {stage}",
                            notes=printed, failure=outcome.failure), []
    if outcome.error is not None:  # _one catches what the engine raises: this is xval's own failure
        error = outcome.error
        return EngineParity(name, version, False, False, message=f"failed: {type(error).__name__}: {error}",
                            notes=printed), []
    result, findings = outcome.value
    return replace(result, notes=(*result.notes, *printed)), findings


def _one(name, source, model, sample, expected, balance_inertia,
         forward_tolerance: float = TOLERANCE) -> tuple[EngineParity, list[Finding]]:
    """One engine's verdict and its per-link findings (none when it did not load or failed)."""
    isolation.report("stage", "loading")
    try:
        module = importer(name)
        version = module.version()
        isolation.report("version", version)
        options = _options_for(module, balance_inertia)
        loaded = module.load(source, model, **options)
    except Refused as exc:
        return EngineParity(name, _version_of(name), False, False, message=str(exc),
                            options=_stated_options(name, balance_inertia)), []
    except Exception as exc:  # an importer that crashes fails alone; the others are still compared
        return EngineParity(name, _version_of(name), False, False, message=f"failed: {type(exc).__name__}: {exc}"), []
    isolation.report("stage", "evaluating")
    try:
        got = evaluate(loaded, sample)
        # The bias is measured against the forces of the sample, the applied torques included: a model whose
        # bias is zero to round-off (wheels about vertical axes) is not judged by its round-off.
        floors = {"bias": _bias_scale(expected, sample)}
        differences = {q: relative_difference(got[q], expected[q], floors.get(q, 0.0)) for q in QUANTITIES}
        findings = diagnose(model, loaded.link_inertias(), _m_scale(expected))
    except Exception as exc:  # an engine that raises on a state fails alone; the others are still compared
        return EngineParity(name, version, True, False, message=f"failed: {type(exc).__name__}: {exc}",
                            options=loaded.options, notes=loaded.notes), []
    bounds = {"mass_matrix": TOLERANCE, "bias": TOLERANCE, "forward": forward_tolerance}
    agrees = all(differences[q] <= bounds[q] for q in QUANTITIES)
    lines = sentences({name: findings}) + misplaced_joints(model, name, loaded.joint_origins())
    if not agrees and not lines:
        worst = max(QUANTITIES, key=lambda q: differences[q] / bounds[q])
        lines = [f"{name}: {unexplained(model, worst, _largest_at(got[worst], expected[worst]))}"]
    return EngineParity(name, version, True, agrees, differences["mass_matrix"], differences["bias"],
                        differences["forward"], options=loaded.options, notes=loaded.notes,
                        diagnosis=tuple(lines)), findings


def _largest_at(values: list[np.ndarray], reference: list[np.ndarray]) -> int:
    """The row (a moving joint's index) of the largest |value − reference| over states and entries."""
    gaps = np.abs(np.asarray(values, dtype=float) - np.asarray(reference, dtype=float))
    gaps[~np.isfinite(gaps)] = np.inf
    index = np.unravel_index(int(np.argmax(gaps)), gaps.shape)
    return int(index[1])


def _options_for(module: ModelImport, balance_inertia: bool) -> dict[str, bool]:
    """The options of ``xval model check`` that this engine's import declares it takes (MuJoCo's balance_inertia)."""
    return {k: v for k, v in {"balance_inertia": balance_inertia}.items() if k in module.options}


def _stated_options(name: str, balance_inertia: bool) -> dict[str, str]:
    """The import options an engine that refused the file was given (MuJoCo's compiler settings)."""
    try:
        module = importer(name)
    except Refused:
        return {}
    return module.stated(**_options_for(module, balance_inertia))


def _version_of(name: str) -> str:
    try:
        return importer(name).version()
    except Refused:
        return "not installed"
