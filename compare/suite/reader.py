"""Suites: which scenes, engine variants and time steps to compare, read from TOML.

:func:`load_suite` reads the file (keys: ``dt``, ``scenes``, ``engines``, and the optional tables
``[reference]``, ``[bounds]``, ``[tolerances]``, ``[gate]``, ``[verdict]``, ``[stability]``,
``[gainmap]``; suites/default.toml is a commented example) into a typed :class:`Suite`. Every mistake
is a :class:`UserError` naming the file (and line), the key and the fix; an engine that cannot be
imported here is kept as *unavailable* and its cases are ``skipped`` with the reason.

Details: docs/running.md, "Module notes", ``compare/suite/reader.py``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from engines import registry
from engines.adapter import Engine
from engines.errors import SceneError, UserError
from engines.scene import catalog

from compare.results.consistency import DEFAULT_TOLERANCE
from engines.files import read_user_text
from compare.results.metrics import DEFAULT_DELTA, Bounds
from compare.suite.command import command_engine_spec
from compare.suite.tolerance_axis import read_tolerances
from compare.suite.gate_rules import GateSettings, gate_settings
from compare.suite.specs import EngineSpec, SceneSpec
from compare.suite.plans import GainMapPlan, StabilityPlan, read_gainmap, read_stability, read_verdict

#: Keys a suite file may hold at the top level, with what each must be.
TOP_LEVEL_KEYS = {
    "name": "a string",
    "description": "a string",
    "duration": "a positive number of seconds",
    "sample_interval": "a positive number of seconds",
    "delta": "a positive number",
    "repeats": "a positive integer",
    "timeout": "a positive number of seconds",
    "dt": "a list of time steps or a table {from, to, per_decade}",
    "reference": "a table with rtol and atol",
    "bounds": "a table with energy_drift and constraint_error",
    "tolerances": "a table of metric name = number",
    "gate": "a table of metric = { rtol, atol } and timing_factor, for xval gate",
    "scenes": "an array of tables [[scenes]]",
    "engines": "an array of engine ids or tables [[engines]]",
    "stability": "a table for xval stability (compare/suite/plans.py): scenes, engines, dt_max, dt_min",
    "gainmap": "a table for the gain map (compare/suite/plans.py): scene, engines, x, y, x_values, y_values, dt",
    "verdict": "a table with tolerance (a fraction of L) for the consistency verdict",
    "tolerance": "a list of tolerances or a table {from, to, per_decade} (compare/suite/tolerance_axis.py)",
    "gradients": "a table with wrt, a list of scene parameters (docs/gradients.md)",
}
REQUIRED_KEYS = ("dt", "scenes", "engines")
SCENE_KEYS = ("id", "scene", "parameters", "model", "q0", "v0", "file_dynamics", "lock")
#: Keys of a model scene ([[scenes]] model = "…"), beside id.
MODEL_KEYS = ("model", "q0", "v0", "file_dynamics", "lock")
ENGINE_KEYS = ("id", "options", "label")
SWEEP_KEYS = ("from", "to", "per_decade")
REFERENCE_KEYS = ("rtol", "atol")
BOUND_KEYS = ("energy_drift", "constraint_error")

DEFAULTS = {"sample_interval": 0.01, "delta": DEFAULT_DELTA, "repeats": 1, "timeout": 120.0}


@dataclass(frozen=True)
class Suite:
    """A parsed, validated suite. ``source`` is the file's text (stored with results)."""

    name: str
    description: str
    path: str
    source: str
    scenes: tuple[SceneSpec, ...]
    engines: tuple[EngineSpec, ...]
    dts: tuple[float, ...]
    duration: float | None
    sample_interval: float
    delta: float
    repeats: int
    timeout: float
    rtol: float
    atol: float
    bounds: Bounds
    gate: GateSettings = field(default_factory=GateSettings)
    stability: StabilityPlan | None = None
    gainmap: GainMapPlan | None = None
    verdict_tolerance: float = DEFAULT_TOLERANCE
    #: The tolerance axis (compare/suite/tolerance_axis.py): swept by error-controlled variants instead of dt.
    tolerances: tuple[float, ...] = ()
    #: [gradients] wrt: the scene parameters each case's gradient metrics are taken with respect to.
    gradient_wrt: tuple[str, ...] = ()

    def engine_names(self) -> set[str]:
        """The names of the engines this suite runs (``mujoco``, ``ours``; the reference is always one)."""
        return {"reference"} | {e.engine.name if e.engine is not None else e.id.split("/")[0] for e in self.engines}

    def fingerprint(self) -> str:
        """A hash of everything that decides which cases run and what they compute (not the file's comments)."""
        physics = {
            "scenes": [[s.id, s.scene.content_hash] for s in self.scenes],
            # An outside program is what it runs: its argv and declared version decide its results too.
            "engines": [[e.id, e.label, dict(e.options), *_program_of(e)] for e in self.engines],
            "dts": list(self.dts),
            "sample_interval": self.sample_interval,
            "delta": self.delta,
            "repeats": self.repeats,
            "reference": [self.rtol, self.atol],
            "bounds": [self.bounds.energy_drift, self.bounds.constraint_error],
        }
        if self.tolerances:  # only then, so suites without the axis keep their fingerprints
            physics["tolerances"] = list(self.tolerances)
        if self.gradient_wrt:  # likewise: a suite without [gradients] keeps its fingerprint
            physics["gradient_wrt"] = list(self.gradient_wrt)
        text = json.dumps(physics, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _program_of(engine: EngineSpec) -> list[Any]:
    """[argv, version] of a command engine (docs/protocol.md), [] for any other engine."""
    program = None if engine.engine is None else engine.engine.program()
    return [] if program is None else [list(program[0]), program[1]]


# -- engine ids ------------------------------------------------------------------


def load_engine(engine_id: str) -> tuple[Engine, str | None]:
    """(engine, variant or None) for ``name[/variant]`` or ``package.module:ATTRIBUTE[/variant]``.

    The ``module:attribute`` form loads an Engine object from any importable
    module (test engines, plug-ins). Raises UserError for an unknown engine,
    ``registry.EngineUnavailable`` when an engine cannot load here.
    """
    return registry.load_engine(engine_id)  # the registry is the one place engine ids are resolved


# -- reading -----------------------------------------------------------------------


def load_suite(path: str | Path) -> Suite:
    """Read and validate the suite at ``path``; UserError naming the file, key and fix."""
    path = Path(path)
    text = read_user_text(path, str(path), "pass the path of a suite: a UTF-8 .toml file such as suites/smoke.toml")
    return parse_suite(text, str(path))


@dataclass(frozen=True)
class RunSettings:
    """The parts of a suite that judge results, readable without loading any engine.

    delta : δ (divergence threshold, fraction of L); bounds : the status bounds;
    gate : the gate's tolerances; verdict_tolerance : the consistency tolerance (fraction of L).
    """

    delta: float = DEFAULT_DELTA
    bounds: Bounds = field(default_factory=Bounds)
    gate: GateSettings = field(default_factory=GateSettings)
    verdict_tolerance: float = DEFAULT_TOLERANCE


def load_run_settings(path: str | Path) -> RunSettings:
    """The :class:`RunSettings` of the suite file at ``path`` (a results directory's ``suite.toml``).

    Defaults when the file does not exist (results written by hand); UserError naming the file for a
    damaged one. The scenes and engines are not built, so gating and reports need no engine here.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return RunSettings()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read the stored suite ({exc}); the results directory is damaged") from None
    data = _parse_toml(text, str(path))
    reader = _Reader(str(path), text)
    values = {**DEFAULTS, **data}
    delta = reader.number("delta", values["delta"])
    bounds_table = reader.table("bounds", data.get("bounds", {}), BOUND_KEYS)
    bounds = Bounds(
        reader.number("bounds.energy_drift", bounds_table.get("energy_drift", Bounds.energy_drift)),
        reader.number("bounds.constraint_error", bounds_table.get("constraint_error", Bounds.constraint_error)),
    )
    gate = gate_settings(data.get("gate"), data.get("tolerances"), reader.error)
    return RunSettings(delta, bounds, gate, read_verdict(reader, data.get("verdict")))


_TOML_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)")


def parse_suite(text: str, path: str = "<suite>") -> Suite:
    """Parse suite TOML ``text``; ``path`` is used in error messages and stored in the Suite."""
    return _Reader(path, text).suite(_parse_toml(text, path))


def _parse_toml(text: str, path: str) -> dict[str, Any]:
    """The TOML document; a syntax error is a UserError with the file, line and column."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        where = _TOML_POSITION.search(message)
        if where:
            reason = _TOML_POSITION.sub("", message).strip()
            raise UserError(
                f"{path}:{where.group(1)}: invalid TOML at column {where.group(2)}: {reason}; fix the syntax there"
            ) from None
        raise UserError(f"{path}: invalid TOML: {message}") from None


class _Reader:
    """Validates one parsed suite; every error names ``path``, the key and, where it can, the line."""

    def __init__(self, path: str, text: str) -> None:
        self.path = path
        self.lines = text.splitlines()

    # -- errors ------------------------------------------------------------------

    def error(self, key: str, message: str) -> UserError:
        line = self.line_of(key)
        where = f"{self.path}:{line}" if line else self.path
        return UserError(f"{where}: {key}: {message}")

    def line_of(self, key: str) -> int | None:
        """Best-effort line (1-based) of ``key`` such as ``delta``, ``scenes[1].scene`` or ``bounds.energy_drift``.

        tomllib gives positions only for syntax errors, so this finds the
        n-th ``[[array]]`` header or ``[table]`` and the first ``name =``
        after it. None when the key is written some other way (inline tables).
        """
        parts = re.findall(r"[A-Za-z_]+|\[\d+\]", key)
        headers = [i for i, line in enumerate(self.lines) if re.match(r"\s*\[", line)]

        def region_after(header: int | None) -> range:
            first = 0 if header is None else header + 1
            following = [h for h in headers if h >= first]
            return range(first, following[0] if following else len(self.lines))

        region = region_after(None)
        if len(parts) >= 2 and parts[1].startswith("["):
            arrays = [i for i in headers if re.match(rf"\s*\[\[\s*{parts[0]}\s*\]\]", self.lines[i])]
            index = int(parts[1][1:-1])
            if index < len(arrays):
                if len(parts) == 2:
                    return arrays[index] + 1
                region, parts = region_after(arrays[index]), parts[2:]
        elif len(parts) >= 2:
            tables = [i for i in headers if re.match(rf"\s*\[\s*{parts[0]}\s*\]", self.lines[i])]
            if tables:
                region, parts = region_after(tables[0]), parts[1:]
        for i in region:
            if re.match(rf'\s*"?{re.escape(parts[0])}"?\s*=', self.lines[i]):
                return i + 1
        return None

    # -- typed getters -------------------------------------------------------------

    def number(self, key: str, value: Any, *, integer: bool = False) -> float:
        kind = "a positive integer" if integer else "a positive number"
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and not isinstance(value, int)):
            raise self.error(key, f"must be {kind}, got {_describe(value)}; write e.g. {key.split('.')[-1]} = {'1' if integer else '0.01'}")
        if not math.isfinite(value) or value <= 0:
            raise self.error(key, f"must be {kind}, got {value!r}")
        return int(value) if integer else float(value)

    def string(self, key: str, value: Any) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(key, f"must be a non-empty string, got {_describe(value)}")
        return value

    def gradients(self, value: Any) -> tuple[str, ...]:
        """``[gradients] wrt = ["theta1", "g"]``: parameter names (each scene refuses those it lacks, case by case)."""
        if value is None:
            return ()
        wrt = self.table("gradients", value, ("wrt",)).get("wrt")
        if not isinstance(wrt, list) or not wrt or not all(isinstance(w, str) and w for w in wrt):
            raise self.error("gradients.wrt", f"must be a non-empty list of parameter names, got {_describe(wrt)}")
        return tuple(wrt)

    def table(self, key: str, value: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(key, f"must be a table, got {_describe(value)}")
        for name in value:
            if name not in allowed:
                raise self.error(f"{key}.{name}", f"unknown key; valid keys are: {', '.join(allowed)}")
        return value

    # -- the suite -----------------------------------------------------------------

    def suite(self, data: dict[str, Any]) -> Suite:
        for key in data:
            if key not in TOP_LEVEL_KEYS:
                raise self.error(key, f"unknown key; valid keys are: {', '.join(TOP_LEVEL_KEYS)}")
        for key in REQUIRED_KEYS:
            if key not in data:
                raise UserError(f"{self.path}: {key}: missing; add {key} = ... ({TOP_LEVEL_KEYS[key]})")
        values = {**DEFAULTS, **data}
        duration = None if "duration" not in data else self.number("duration", data["duration"])
        sample_interval = self.number("sample_interval", values["sample_interval"])
        delta = self.number("delta", values["delta"])
        repeats = int(self.number("repeats", values["repeats"], integer=True))
        timeout = self.number("timeout", values["timeout"])
        name = self.string("name", data["name"]) if "name" in data else Path(self.path).stem
        description = self.string("description", data["description"]) if "description" in data else ""
        reference = self.table("reference", data.get("reference", {}), REFERENCE_KEYS)
        rtol = self.number("reference.rtol", reference.get("rtol", 1e-12))
        atol = self.number("reference.atol", reference.get("atol", 1e-12))
        self.reference_tolerances(rtol, atol)
        bounds_table = self.table("bounds", data.get("bounds", {}), BOUND_KEYS)
        bounds = Bounds(
            self.number("bounds.energy_drift", bounds_table.get("energy_drift", Bounds.energy_drift)),
            self.number("bounds.constraint_error", bounds_table.get("constraint_error", Bounds.constraint_error)),
        )
        # [tolerances] and [gate] end up in ``gate``: keys (a metric's earlier name read as today's) and values
        # are checked by gate_settings, which names the line through self.error (as for a results' suite.toml).
        gate = gate_settings(data.get("gate"), data.get("tolerances"), self.error)
        dts = self.dts(data["dt"])
        scenes = self.scenes(data["scenes"], duration)
        longest_dt = max(dts)
        for spec in scenes:
            if longest_dt > spec.scene.duration:
                raise self.error(
                    "dt",
                    f"the time step {longest_dt:g} s is longer than scene {spec.id!r}'s duration "
                    f"{spec.scene.duration:g} s; use smaller time steps or a longer duration",
                )
        engines = self.engines(data["engines"])
        stability = read_stability(self, data.get("stability"), scenes, engines, dts)
        gainmap = read_gainmap(self, data.get("gainmap"), scenes, self.expand)
        verdict_tolerance = read_verdict(self, data.get("verdict"))
        gradient_wrt = self.gradients(data.get("gradients"))
        return Suite(
            name=name,
            description=description,
            path=self.path,
            source="\n".join(self.lines) + "\n",
            scenes=scenes,
            engines=engines,
            dts=dts,
            duration=duration,
            sample_interval=sample_interval,
            delta=delta,
            repeats=repeats,
            timeout=timeout,
            rtol=rtol,
            atol=atol,
            bounds=bounds,
            gate=gate,
            stability=stability,
            gainmap=gainmap,
            verdict_tolerance=verdict_tolerance,
            gradient_wrt=gradient_wrt,
            tolerances=read_tolerances(self, data.get("tolerance")),
        )

    def reference_tolerances(self, rtol: float, atol: float) -> None:
        """The reference engine's own option ranges apply to [reference] (rtol = 1e-300 would be clamped by
        scipy with a warning, and the results would claim a tolerance that was never used)."""
        try:
            engine, _ = registry.load_engine("reference")
        except UserError:
            return
        for key, value in (("rtol", rtol), ("atol", atol)):
            try:
                engine.resolve(None, {key: value})
            except UserError as exc:
                raise self.error(f"reference.{key}", str(exc)) from None

    def sweep(self, key: str, value: Any, noun: str, example_list: str, example_sweep: str) -> list[float]:
        """Positive values from a list or a geometric sweep table {from, to, per_decade}, in the order written.

        The one reader of every sweep a suite holds (dt, tolerance, the gain map's axes); ``noun`` names one
        value in messages ("time step"), the examples show the two forms.
        """
        leaf = key.split(".")[-1]
        if isinstance(value, list):
            if not value:
                raise self.error(key, f"is empty; list at least one {noun}, e.g. {leaf} = {example_list}")
            values = [self.number(f"{key}[{k}]", v) for k, v in enumerate(value)]
        elif isinstance(value, dict):
            table = self.table(key, value, SWEEP_KEYS)
            for part in SWEEP_KEYS:
                if part not in table:
                    raise self.error(key, f"the sweep needs {part}; write {leaf} = {example_sweep}")
            values = geometric_sweep(self.number(f"{key}.from", table["from"]), self.number(f"{key}.to", table["to"]),
                                     int(self.number(f"{key}.per_decade", table["per_decade"], integer=True)))
        else:
            raise self.error(key, f"must be a list of {noun}s or a table {{from, to, per_decade}}, got {_describe(value)}")
        if len(set(values)) != len(values):
            raise self.error(key, f"lists the same {noun} twice; remove the duplicate")
        return values

    def dts(self, value: Any) -> tuple[float, ...]:
        """The suite's time steps (s), largest first."""
        dts = self.sweep("dt", value, "time step", "[1e-2, 1e-3]", "{ from = 1e-1, to = 1e-4, per_decade = 2 }")
        return tuple(sorted(dts, reverse=True))

    def scenes(self, value: Any, duration: float | None) -> tuple[SceneSpec, ...]:
        if not isinstance(value, list) or not value:
            raise self.error("scenes", "must be a non-empty array of tables; add [[scenes]] with scene = \"bead\"")
        specs: list[SceneSpec] = []
        for k, item in enumerate(value):
            key = f"scenes[{k}]"
            entry = self.table(key, item, SCENE_KEYS)
            if "model" in entry:
                spec = self.model_scene(key, entry, duration)
                if any(s.id == spec.id for s in specs):
                    raise self.error(f"{key}.id", f"{spec.id!r} is used twice; give each scene a distinct id")
                specs.append(spec)
                continue
            stray = [k for k in MODEL_KEYS if k in entry]
            if stray:
                raise self.error(f"{key}.{stray[0]}", "belongs to a model scene; add model = \"path/to/file.urdf\" "
                                 "(or pybullet_data:<path>) or remove it")
            if "scene" not in entry:
                raise self.error(key, f"missing scene; add scene = one of {', '.join(catalog.scene_names())}")
            name = self.string(f"{key}.scene", entry["scene"])
            if name not in catalog.CATALOG:
                raise self.error(
                    f"{key}.scene", f"unknown scene {name!r}; choose one of: {', '.join(catalog.scene_names())}"
                )
            scene_id = self.string(f"{key}.id", entry.get("id", name))
            if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", scene_id):
                raise self.error(f"{key}.id", f"{scene_id!r} is not a readable id; use letters, digits, '.', '_' and '-'")
            if any(s.id == scene_id for s in specs):
                raise self.error(f"{key}.id", f"{scene_id!r} is used twice; give each scene a distinct id")
            parameters = self.table(f"{key}.parameters", entry.get("parameters", {}), tuple(entry.get("parameters", {})))
            overrides = dict(parameters)
            if duration is not None:
                overrides.setdefault("duration", duration)
            try:
                scene = catalog.build(name, overrides)
            except SceneError as exc:
                raise self.error(f"{key}.parameters", f"{exc}") from None
            specs.append(SceneSpec(scene_id, name, dict(parameters), scene))
        return tuple(specs)

    def model_scene(self, key: str, entry: dict[str, Any], duration: float | None) -> SceneSpec:
        """A [[scenes]] entry with ``model = "…"`` (a path relative to the suite file, or pybullet_data:<path>),
        ``q0`` (degrees, or metres for prismatic joints) and ``v0`` (rad/s, m/s) by joint name, and
        ``parameters = { g = … }`` (m/s², the one catalog parameter a model takes)."""
        from engines.model.loaded import GRAVITY
        from engines.model.scene import DEFAULT_DURATION, model_scene

        if "scene" in entry:
            raise self.error(f"{key}.model", "a scene is either a catalog scene (scene, parameters) or a model "
                             "(model, q0, v0, file_dynamics), not both; remove one")
        parameters = self.table(f"{key}.parameters", entry.get("parameters", {}), ("g",))
        model = self.string(f"{key}.model", entry["model"])
        scene_id = self.string(f"{key}.id", entry.get("id", Path(model.partition(":")[2] or model).stem))
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", scene_id):
            raise self.error(f"{key}.id", f"{scene_id!r} is not a readable id; use letters, digits, '.', '_' and '-'")
        q0 = self.table(f"{key}.q0", entry.get("q0", {}), tuple(entry.get("q0", {})))
        v0 = self.table(f"{key}.v0", entry.get("v0", {}), tuple(entry.get("v0", {})))
        file_dynamics = self.string(f"{key}.file_dynamics", entry.get("file_dynamics", "neutral"))
        lock = entry.get("lock", [])
        if not isinstance(lock, list) or not all(isinstance(name, str) for name in lock):
            raise self.error(f"{key}.lock", f"must be a list of joint names, got {_describe(lock)}")
        try:
            scene = model_scene(scene_id, model, base=Path(self.path).parent, q0=q0, v0=v0,
                                duration=DEFAULT_DURATION if duration is None else duration,
                                file_dynamics=file_dynamics, g=parameters.get("g", GRAVITY), lock=lock)
        except UserError as exc:
            raise self.error(f"{key}.model", str(exc)) from None
        return SceneSpec(scene_id, "model", {"model": model, "q0": dict(q0), "v0": dict(v0),
                                             "file_dynamics": file_dynamics, **dict(parameters),
                                             **({"lock": list(lock)} if lock else {})}, scene)

    def engines(self, value: Any) -> tuple[EngineSpec, ...]:
        if not isinstance(value, list) or not value:
            raise self.error(
                "engines", 'must be a non-empty array; write engines = ["ours/*"] or add [[engines]] with id = "..."'
            )
        specs: list[EngineSpec] = []
        for k, item in enumerate(value):
            key = f"engines[{k}]"
            if isinstance(item, dict) and "command" in item:  # an outside program: compare/suite/command.py
                engine, options = command_engine_spec(item, key, self.path, self.error)
                specs.append(EngineSpec(engine.spec.engine_id, engine.spec.engine_id, engine.spec.label, options,
                                        engine))
                if sum(s.label == engine.spec.engine_id for s in specs) > 1:
                    raise self.error(f"{key}.label", f"{engine.spec.label!r} is used twice; give each command its "
                                                     f"own label")
                continue
            entry = {"id": item} if isinstance(item, str) else self.table(key, item, ENGINE_KEYS)
            if "id" not in entry:
                raise self.error(key, 'missing id; add id = "engine/variant", e.g. id = "mujoco/hinge-rk4"')
            engine_id = self.string(f"{key}.id", entry["id"])
            options = self.table(f"{key}.options", entry.get("options", {}), tuple(entry.get("options", {})))
            label = self.string(f"{key}.label", entry["label"]) if "label" in entry else None
            for spec in self.expand(key, engine_id, options, label):
                if any(s.label == spec.label for s in specs):
                    raise self.error(
                        f"{key}.id",
                        f"{spec.label!r} is listed twice; remove one, or give variants with different options a label",
                    )
                specs.append(spec)
        return tuple(specs)

    def expand(self, key: str, engine_id: str, options: dict[str, Any], label: str | None) -> list[EngineSpec]:
        """The EngineSpecs for one entry: one per variant for ``name/*``, else one."""
        try:
            engine, variant = load_engine(engine_id)
        except registry.EngineUnavailable as exc:
            return [EngineSpec(engine_id, label or engine_id, None, options, None, str(exc))]
        except UserError as exc:
            raise self.error(f"{key}.id", str(exc)) from None
        base = engine_id.partition("/")[0]
        variants = list(engine.variants) if variant == "*" else [variant or engine.default_variant]
        if label is not None and len(variants) > 1:
            raise self.error(f"{key}.label", f"a label names one variant, but {engine_id!r} has {len(variants)}; drop the label or name a variant")
        specs = []
        for name in variants:
            try:
                engine.resolve(name, options)
            except UserError as exc:
                which = "options" if name in engine.variants else "id"
                raise self.error(f"{key}.{which}", str(exc)) from None
            full = f"{base}/{name}"
            specs.append(EngineSpec(full, label or full, name, options, engine))
        return specs


def geometric_sweep(start: float, stop: float, per_decade: int) -> list[float]:
    """Values from ``start`` to ``stop`` inclusive, ``per_decade`` per factor of 10, equal ratios.

    Rounded to 12 significant digits so 10^(−k/2) prints cleanly.
    """
    decades = abs(math.log10(stop / start))
    n = max(1, round(decades * per_decade))
    return [float(f"{start * (stop / start) ** (k / n):.12g}") for k in range(n + 1)]


def _describe(value: Any) -> str:
    kind = {str: "a string", bool: "a boolean", int: "an integer", float: "a number", list: "an array", dict: "a table"}
    return f"{kind.get(type(value), type(value).__name__)} {value!r}"
