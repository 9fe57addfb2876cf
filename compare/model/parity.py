"""Dynamics parity: each engine's M(q), b(q, v) and a(q, v, tau) against Pinocchio's at sampled states.

States: q uniform within each joint's limits (the inner 90 %: PyBullet's
limit constraints stay idle) or ±π for a joint without them (±1 m for a
prismatic one); v uniform in ±1 rad/s (m/s); tau = M_ref a* + b_ref with
a* uniform in ±1 rad/s² (m/s²), so every joint's reference acceleration is
of order one. Per quantity the relative difference is the largest
|engine − reference| over entries and states divided by the largest
|reference| over entries and states (for the bias, at least the largest
|tau|). An engine agrees when all three are ≤ TOLERANCE.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from compare.model.diagnosis import Finding, diagnose, sentences
from engines.adapter import ModelImport
from engines.model import source as sources
from engines.model import urdf
from engines.model.description import ModelDescription, ModelError
from engines.model.importers import ENGINES, REFERENCE, importer
from engines.model.loaded import LoadedModel, Refused

#: Largest relative difference that still agrees: far above float64 round-off (measured 1e-15 .. 1e-13,
#: PyBullet's acceleration from one step included), far below any import mistake (the smallest seen, 1e-4).
TOLERANCE = 1e-6
QUANTITIES = ("mass_matrix", "bias", "forward")


@dataclass(frozen=True)
class States:
    """q, v, tau : (N, nq) in the description's joint order (rad, m; rad/s, m/s; N·m, N)."""

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray


@dataclass(frozen=True)
class EngineParity:
    """One engine's verdict. The three differences are None when it did not load or failed."""

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


@dataclass(frozen=True)
class ParityReport:
    model: str
    name: str
    moving_joints: tuple[str, ...]
    reference: EngineParity
    states: int
    seed: int
    engines: tuple[EngineParity, ...]
    notes: tuple[str, ...]
    diagnosis: tuple[str, ...]

    @property
    def exit_code(self) -> int:
        return 0 if all(e.agrees for e in self.engines) else 1

    def to_dict(self) -> dict:
        return {"model": self.model, "name": self.name, "moving_joints": list(self.moving_joints),
                "reference": {"name": self.reference.engine, "version": self.reference.version,
                              "options": self.reference.options, "diagnosis": list(self.reference.diagnosis)},
                "states": self.states, "seed": self.seed, "tolerance": TOLERANCE,
                "engines": [asdict(e) for e in self.engines], "notes": list(self.notes),
                "diagnosis": list(self.diagnosis)}


def sample_states(model: ModelDescription, reference: LoadedModel, count: int, seed: int) -> States:
    rng = np.random.default_rng(seed)
    lower, upper = np.empty(model.nq), np.empty(model.nq)
    for k, joint in enumerate(model.moving_joints):
        lo, hi = joint.limits.lower, joint.limits.upper
        if lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi) and hi > lo:
            middle, half = (lo + hi) / 2, 0.45 * (hi - lo)
            lower[k], upper[k] = middle - half, middle + half
        else:
            reach = math.pi if joint.type != "prismatic" else 1.0
            lower[k], upper[k] = -reach, reach
    q = rng.uniform(lower, upper, (count, model.nq))
    v = rng.uniform(-1.0, 1.0, (count, model.nq))
    target = rng.uniform(-1.0, 1.0, (count, model.nq))
    tau = np.array([reference.mass_matrix(qk) @ ak + reference.bias(qk, vk) for qk, vk, ak in zip(q, v, target)])
    return States(q, v, tau)


def _require_invertible(model: ModelDescription, reference: LoadedModel, label: str) -> None:
    """ModelError naming the joints that move nothing with mass or inertia (M singular: no forward dynamics)."""
    m = reference.mass_matrix(np.zeros(model.nq))
    scale = max(float(np.abs(m).max()), 1e-300)
    idle = [j.name for j, d in zip(model.moving_joints, np.diag(m)) if d <= 1e-12 * scale]
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


def read_description(label: str) -> tuple[sources.ModelSource, ModelDescription]:
    """The source and its description (mimic joints as independent coordinates, said in the notes)."""
    source = sources.resolve(label)
    if source.format == "urdf":
        return source, urdf.read(source, mimic_independent=True)
    from engines.model import mjcf

    return source, mjcf.read(source)


def check(label: str, engines: tuple[str, ...] = ENGINES, states: int = 100, seed: int = 0,
          balance_inertia: bool = False) -> ParityReport:
    """The parity report of model ``label``; UserError (ModelError) for bad input, before any engine runs."""
    for name in engines:
        if name not in ENGINES:
            raise ModelError(f"--engine: unknown engine {name!r}; choose from {', '.join(ENGINES)}")
    if states < 1:
        raise ModelError(f"--states: must be at least 1, got {states}")
    source, model = read_description(label)
    if model.nq == 0:
        raise ModelError(f"model {label}: no moving joint (revolute, continuous or prismatic); nothing to compare")
    try:
        reference = importer(REFERENCE).load(source, model)
    except Refused as exc:
        raise ModelError(f"model {label}: the reference (pinocchio) cannot load it: {exc}") from None
    _require_invertible(model, reference, label)
    sample = sample_states(model, reference, states, seed)
    expected = evaluate(reference, sample)
    results, findings = [], {}
    for name in engines:
        result, findings[name] = _one(name, source, model, sample, expected, balance_inertia)
        results.append(result)
    reference_findings = diagnose(model, reference.link_inertias())
    notes = (*model.notes, *source.engine_text(drop_mimic=model.mimic_independent)[1])
    ref_entry = EngineParity(REFERENCE, importer(REFERENCE).version(), True, True, 0.0, 0.0, 0.0,
                             options=reference.options, notes=reference.notes,
                             diagnosis=tuple(sentences({REFERENCE: reference_findings})))
    return ParityReport(label, model.name, tuple(j.name for j in model.moving_joints), ref_entry, states, seed,
                        tuple(results), notes, tuple(sentences(findings)))


def _one(name, source, model, sample, expected, balance_inertia) -> tuple[EngineParity, list[Finding]]:
    """One engine's verdict and its per-link findings (none when it did not load or failed)."""
    try:
        module = importer(name)
        version = module.version()
        options = _options_for(module, balance_inertia)
        loaded = module.load(source, model, **options)
    except Refused as exc:
        return EngineParity(name, _version_of(name), False, False, message=str(exc),
                            options=_stated_options(name, balance_inertia)), []
    except Exception as exc:  # an importer that crashes fails alone; the others are still compared
        return EngineParity(name, _version_of(name), False, False, message=f"failed: {type(exc).__name__}: {exc}"), []
    try:
        got = evaluate(loaded, sample)
        # The bias is measured against the forces of the sample, the applied torques included: a model whose
        # bias is zero to round-off (wheels about vertical axes) is not judged by its round-off.
        floors = {"bias": float(np.abs(sample.tau).max())}
        differences = {q: relative_difference(got[q], expected[q], floors.get(q, 0.0)) for q in QUANTITIES}
        findings = diagnose(model, loaded.link_inertias())
    except Exception as exc:  # an engine that raises on a state fails alone; the others are still compared
        return EngineParity(name, version, True, False, message=f"failed: {type(exc).__name__}: {exc}",
                            options=loaded.options, notes=loaded.notes), []
    agrees = all(d <= TOLERANCE for d in differences.values())
    return EngineParity(name, version, True, agrees, differences["mass_matrix"], differences["bias"],
                        differences["forward"], options=loaded.options, notes=loaded.notes,
                        diagnosis=tuple(sentences({name: findings}))), findings


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
