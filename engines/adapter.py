"""The protocol every engine adapter follows, and the shared machinery behind it. An adapter fills in:

- ``name``, ``capabilities`` (``{"3d", "constraint-forces"}``), ``options`` (typed :class:`Option`
  records), ``variants`` (named presets, the first the default), ``overrides`` (engine defaults changed);
- ``version()``; ``_check(scene, settings)`` (refusals), ``_check_options(settings)`` (option values);
- ``_run(scene, schedule, settings) -> RawRun``: build, step, record the samples, time the stepping alone.

and may override the hooks the harness calls, each declared here with its default: ``_check_model`` /
``_run_model`` (model files), ``model_import()`` (what ``xval model check`` compares), ``preload(scenes)``
(load once before case hosts fork), ``needs_warm_up``, ``tolerance_options`` /
``tolerance_capable(settings)`` (a suite's tolerance axis), ``program()`` (an outside program's argv and
version), ``spectral_radius`` / ``largest_stable_dt`` (the engine's own stability theory). Nothing else
is looked up on an engine.
Details: docs/engines.md, "Adapter notes", ``engines/adapter.py``.
"""

from __future__ import annotations

import functools
import math
import re
import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, Callable, ClassVar, Iterable, Mapping, Sequence

import numpy as np

from engines.errors import Unsupported, UserError
from engines.scene.scene import Ellipse, Scene, SceneLike, ModelSceneLike
from engines.scene.trajectory import RunInfo, Status, Trajectory

#: Default interval between stored samples, s.
DEFAULT_SAMPLE_INTERVAL = 0.01

#: The engine protocol's version. Bump it when a change would make an adapter
#: written for the old protocol give wrong results (a field changing meaning,
#: a unit, what ``_run`` returns), and list the change in docs/plugins.md.
API_VERSION = 1
#: Protocol versions this xval runs adapters for.
SUPPORTED_API_VERSIONS = (1,)

#: The first sample must match the scene's initial state to this fraction of
#: the scene's length L (positions) or speed scale max(|v0|, √(gL)) (velocities).
#: Every built-in engine matches it to 1e-12; a millimetre/metre, y-up/z-up or
#: particle-order mistake is off by far more than 1e-6.
INITIAL_STATE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Option:
    """One engine option: type, default, meaning and (optionally) allowed values.

    kind : "float", "int", "str", "bool" or "floats" (comma-separated numbers).
    """

    name: str
    default: Any
    doc: str
    kind: str = "float"
    choices: tuple[Any, ...] | None = None
    #: Allowed range of a "float" or "int" option (None: unbounded on that side); ``low_open``: low excluded.
    low: float | None = None
    high: float | None = None
    low_open: bool = False

    def parse(self, raw: Any, engine: str) -> Any:
        """Convert a CLI string (or a value from a suite file); UserError names the option and the fix."""
        where = f"{engine}: option {self.name}"
        try:
            if self.kind == "float":
                value: Any = float(raw)
                if not math.isfinite(value):
                    raise ValueError
            elif self.kind == "int":
                value = int(raw)
            elif self.kind == "bool":
                if isinstance(raw, bool):
                    value = raw
                elif str(raw).lower() in ("1", "true", "yes", "on"):
                    value = True
                elif str(raw).lower() in ("0", "false", "no", "off"):
                    value = False
                else:
                    raise ValueError
            elif self.kind == "floats":
                items = raw.split(",") if isinstance(raw, str) else list(raw)
                value = tuple(float(x) for x in items)
                if not all(math.isfinite(x) for x in value):
                    raise ValueError
            else:
                value = str(raw)
        except (TypeError, ValueError):
            raise UserError(f"{where} must be {_KIND_WORDS[self.kind]}, got {raw!r}") from None
        if self.choices is not None and value not in self.choices:
            raise UserError(f"{where} must be one of {', '.join(map(str, self.choices))}; got {raw!r}")
        if self.kind in ("float", "int") and value is not None and not self._in_range(value):
            raise UserError(f"{where} = {value!r} is outside the allowed range {self.range_text()}")
        return value

    def _in_range(self, value: float) -> bool:
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        return self.high is None or value <= self.high

    def range_text(self) -> str:
        """``(0, 1]``, ``[1, 10000]``, ``>= 0``: the allowed range as written in messages and help."""
        if self.low is not None and self.high is not None:
            return f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}]"
        if self.low is not None:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        return f"<= {self.high:g}" if self.high is not None else "(any)"


_KIND_WORDS = {
    "float": "a finite number",
    "int": "an integer",
    "bool": "true or false",
    "floats": "comma-separated numbers",
    "str": "a string",
}


@dataclass(frozen=True)
class Schedule:
    """When to step and when to sample.

    dt : s; n_steps : steps to take (round(duration / dt));
    stride : steps between samples (round(sample_interval / dt), at least 1).
    Samples are taken at step 0, every ``stride`` steps, and at the last step.
    """

    dt: float
    n_steps: int
    stride: int

    @classmethod
    def make(cls, duration: float, dt: float, sample_interval: float | None = None) -> "Schedule":
        check_time_step(dt, duration)
        interval = DEFAULT_SAMPLE_INTERVAL if sample_interval is None else float(sample_interval)
        if not math.isfinite(interval) or interval <= 0:
            raise UserError(f"sample interval must be positive, got {sample_interval!r}")
        n_steps = max(1, round(duration / dt))
        stride = max(1, round(interval / dt))
        return cls(float(dt), n_steps, stride)

    @property
    def sample_steps(self) -> np.ndarray:
        """(n_samples,) step indices at which the state is recorded (0 is the initial state)."""
        steps = np.arange(0, self.n_steps + 1, self.stride)
        if steps[-1] != self.n_steps:
            steps = np.append(steps, self.n_steps)
        return steps

    @property
    def times(self) -> np.ndarray:
        """(n_samples,) s."""
        return self.sample_steps * self.dt


@functools.lru_cache(maxsize=256)
@dataclass(frozen=True)
class ModelImport:
    """An engine's import of a model file, as ``xval model check`` uses it (engines/<engine>/model.py).

    load : ``load(source, description, **options)`` -> the loaded model (engines.model.loaded.LoadedModel).
    options : the keyword options ``load`` takes that ``xval model check`` may pass (MuJoCo's
        ``balance_inertia``); the others are not given them.
    stated : ``stated(**options)`` -> the import settings a file was given, shown when the engine refused it.
    describes : the file formats whose meaning this engine's compiler defines (MuJoCo's: "mjcf"), and
        ``describe(source)`` -> such a file's engine-neutral ModelDescription (engines.model.description),
        reached through ``engines.registry.describer``.
    """

    version: Callable[[], str]
    load: Callable[..., Any]
    options: frozenset[str] = frozenset()
    stated: Callable[..., dict[str, str]] = lambda **_: {}
    describes: frozenset[str] = frozenset()
    describe: Callable[[Any], Any] | None = None


def refuse_ellipse(scene: Scene, why: str) -> None:
    """Raise Unsupported for the first Ellipse of ``scene``: ``why`` (the engine's reason), then its index."""
    for k, c in enumerate(scene.constraints):
        if isinstance(c, Ellipse):
            raise Unsupported(f"{why}; constraints[{k}] is an 'ellipse'")


def refuse_constraint_kinds(scene: Scene, kinds: Iterable[type], engine: str) -> None:
    """Raise Unsupported naming the first constraint of ``scene`` not of one of ``kinds``."""
    kinds = tuple(kinds)
    for k, c in enumerate(scene.constraints):
        if not isinstance(c, kinds):
            names = ", ".join(getattr(t, "kind", t.__name__) for t in kinds)
            raise Unsupported(f"{engine} models only {names} constraints; constraints[{k}] is a {c.kind!r}")


def scheduled_times(duration: float, dt: float, sample_interval: float) -> np.ndarray:
    """(N,) s: ``Schedule.make(duration, dt, sample_interval).times``, read-only and built once: every
    engine of a scene and dt is sampled there, and the reference's kept samples are keyed by these
    times' bytes (the case host that keeps them and the runner that looks them up must agree)."""
    times = Schedule.make(duration, dt, sample_interval).times
    times.flags.writeable = False
    return times


def check_time_step(dt: Any, duration: float) -> None:
    """Raise UserError for a dt that is not positive and finite or exceeds the duration."""
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise UserError(f"dt must be a number of seconds, got {dt!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise UserError(f"dt must be positive, got {dt!r}; pass a time step in seconds such as 1e-3")
    if value > duration:
        raise UserError(
            f"dt ({value:g} s) is larger than the duration ({duration:g} s); use a smaller dt or a longer duration"
        )


@dataclass
class RawRun:
    """What ``_run`` returns: the samples it recorded (possibly fewer than scheduled).

    positions, velocities : (n_recorded, n_particles, 3) m, m/s.
    forces : (n_recorded, n_constraints, 3) N on each constraint's first particle, or None.
    steps : steps taken; wall_time : s of the stepping loop alone.
    cpu_time : s of this thread's CPU time in the stepping loop alone, when the adapter measures it
        (``time.thread_time()`` differences); None: estimated by :func:`loop_cpu_time`.
    message : a note for RunInfo (e.g. why stepping stopped early).
    settings : extra settings to record (e.g. the inertia given to point masses).
    """

    positions: np.ndarray
    velocities: np.ndarray
    forces: np.ndarray | None
    steps: int
    wall_time: float
    message: str = ""
    settings: dict[str, Any] = field(default_factory=dict)
    cpu_time: float | None = None
    #: (n_recorded, 2·nq) q then v of a model scene's joints (engines.model.stepping), else None.
    joint_states: np.ndarray | None = None
    #: (n_recorded,) m: the largest violation of the engine's own constraints at each sample, for an
    #: engine whose constraints the positions cannot show (Trajectory.constraint_violation), else None.
    constraint_violation: np.ndarray | None = None


def loop_cpu_time(raw: RawRun, cpu: float) -> float:
    """s of CPU time of the run: the adapter's own measure of its stepping loop (engines.recorder), else ``cpu``.

    cpu : s of this thread's CPU time of the whole ``_run`` call (model building
    included), for an adapter that does not measure its loop. Time the
    thread spent waiting for a core (another process loading the machine) is
    not in it, which is why the timing gate compares it rather than wall time
    (compare/gate/gate.py). Splitting it by the loop's share of wall time was
    tried and rejected: under load, preemption falls unevenly on building and
    stepping, and the share was off by up to 2x.
    """
    return float(raw.cpu_time) if raw.cpu_time is not None else cpu


class Engine:
    """Base class of every adapter; see the module docstring for the protocol."""

    #: The protocol version the adapter was written for; see :data:`API_VERSION`.
    api_version: ClassVar[int] = API_VERSION
    name: ClassVar[str] = ""
    capabilities: ClassVar[frozenset[str]] = frozenset()
    options: ClassVar[Mapping[str, Option]] = {}
    variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    variant_docs: ClassVar[Mapping[str, str]] = {}
    overrides: ClassVar[Mapping[str, Any]] = {}

    # -- to implement ------------------------------------------------------------

    def version(self) -> str:
        raise NotImplementedError

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        """Raise Unsupported for a scene this configuration cannot express (capabilities are checked already)."""

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        raise NotImplementedError

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        """Raise UserError for an option value the engine cannot take; run before ``_check`` and
        ``_check_model`` alike, so a bad value is refused whatever the scene."""

    # -- model files (only for an engine with the "model" capability) ------------------------------

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        """Raise Unsupported for a model scene (engines.model.scene.ModelScene) these settings cannot load."""

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        """The RawRun of a model scene: the engine's home imports the file (engines/<engine>/model.py), builds
        its stepper from ``settings`` and hands it to ``engines.model.stepping.run_model``, the one loop."""
        raise NotImplementedError(f"{self.name} declares the 'model' capability but does not run model scenes")

    def model_import(self) -> "ModelImport | None":
        """This engine's import of model files as ``xval model check`` compares it with Pinocchio's, or None
        (the default: the engine is not compared)."""
        return None

    # -- optional: what the harness asks every engine, each with its default ----------------------

    #: The options a suite's tolerance sets, for an engine with the "tolerance" capability
    #: (compare/suite/tolerance_axis.py): Drake's ``("accuracy",)``, the reference's ``("rtol", "atol")``.
    tolerance_options: ClassVar[tuple[str, ...]] = ()
    #: Whether a case host runs each variant for two steps before its first case (so one-off costs, a
    #: library's start-up or compiled kernels, stay out of that case's stepping time): a program started
    #: afresh for every run has none.
    needs_warm_up: ClassVar[bool] = True

    def tolerance_capable(self, settings: Mapping[str, Any]) -> bool:
        """Whether these resolved settings are error-controlled (a tolerance, not dt, sets the error), so a
        suite's tolerance axis sweeps them; default False (a fixed-step variant)."""
        return False

    def preload(self, scenes: Sequence[SceneLike]) -> None:
        """Load once, in the process that will fork the case hosts, what runs of ``scenes`` will need
        (compiled kernels, a solver library), so the hosts inherit it; default: nothing. An error here
        is ignored by the runner (the cases report their own)."""

    def program(self) -> tuple[list[str], str] | None:
        """(argv, version) of the outside program this engine runs (a command engine, docs/protocol.md),
        which a suite's fingerprint includes; None (the default) for an engine in this process."""
        return None

    # -- optional: what only the engine knows ---------------------------------------

    def spectral_radius(self, variant: str | None, options: Mapping[str, Any] | None, dt: float) -> float | None:
        """ρ of the engine's own linearized step at ``dt`` (s) for this variant and options, or None.

        An engine with a linear stability theory of its own (ours' Baumgarte
        feedback) returns the spectral radius of one step: ≤ 1 stable, > 1 the
        error grows by ρ per step. The gain map draws ρ = 1 over any two numeric
        options; None (the default) means "no theory", and nothing is drawn.
        """
        return None

    def largest_stable_dt(self, variant: str | None, options: Mapping[str, Any] | None) -> float | None:
        """s: the largest time step the engine's own theory calls stable for these settings, or None (no theory)."""
        return None

    def jacobian(self, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                 wrt: list[str]) -> tuple[Any, ...] | None:
        """The engine's own derivatives of a run's outputs at its last step, or None (the default).

        J : (m, k) d outputs / d parameters, outputs the CSV's state columns (p{i}_x..z v{i}_x..z, m and
        m/s; a model's q_<joint> v_<joint>), parameters ``wrt`` per SI unit (per radian for an angle), for ``scene`` run
        for its duration at ``dt`` with this variant and options; method : "analytic", "autodiff" or
        "finite-difference" (its own, such as MuJoCo's chained one-step differences). It may answer
        (J, method, times, J over time) instead: times (n,) s, J at each (n, m, k), for the error over time.
        None means the engine has no derivatives of its own for this case, and the harness takes
        central differences of whole rollouts (engines/gradients.py), which every engine supports.
        """
        return None

    # -- provided ----------------------------------------------------------------

    @property
    def default_variant(self) -> str:
        return next(iter(self.variants))

    def variant_ids(self) -> list[str]:
        return [f"{self.name}/{v}" for v in self.variants]

    def resolve(self, variant: str | None = None, options: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Settings for ``variant`` (a key of ``variants``) with ``options`` on top, each parsed and checked."""
        variant = variant or self.default_variant
        if variant not in self.variants:
            raise UserError(
                f"unknown variant {self.name}/{variant}; choose one of: {', '.join(self.variant_ids())}"
            )
        settings = {name: option.default for name, option in self.options.items()}
        settings.update(self.variants[variant])
        for key, raw in (options or {}).items():
            if key not in self.options:
                valid = ", ".join(self.options) or "none"
                raise UserError(f"{self.name}: unknown option {key!r}; its options are: {valid}")
            settings[key] = self.options[key].parse(raw, self.name)
        return settings

    def check(self, scene: SceneLike, variant: str | None = None, options: Mapping[str, Any] | None = None) -> None:
        """Raise Unsupported with the reason when this engine (variant) cannot express ``scene``."""
        missing = scene.requires - self.capabilities
        if missing:
            raise Unsupported(self._lacking(scene, missing))
        settings = self.resolve(variant, options)
        self._check_options(settings)
        if scene.is_model:  # here and in simulate, never in an adapter's _check/_run (ours' warm-up aside)
            self._check_model(scene, settings)
        else:
            self._check(scene, settings)

    def _lacking(self, scene: SceneLike, missing: frozenset[str]) -> str:
        """Why this engine cannot express ``scene``, which needs the capabilities ``missing``."""
        if "model" in missing:
            return (f"{self.name} does not load model files (URDF, MJCF): it runs the catalog's scenes only, and "
                    f"{scene.name!r} is a model")
        if "3d" in missing:
            return f"{self.name} is 2-D and cannot express the 3-D scene {scene.name!r}"
        return f"{self.name} lacks {', '.join(sorted(missing))} needed by {scene.name!r}"

    def simulate(
        self,
        scene: SceneLike,
        dt: float,
        *,
        variant: str | None = None,
        options: Mapping[str, Any] | None = None,
        sample_interval: float | None = None,
    ) -> Trajectory:
        """Simulate ``scene`` for its duration with step ``dt`` (s).

        Returns a Trajectory sampled at ``Schedule.times`` with status ``ok``,
        ``unstable`` (samples up to the first non-finite one) or ``failed``
        (the engine raised; the message says what). Bad input (dt, variant,
        options) and unsupported scenes raise UserError / Unsupported.
        """
        variant = variant or self.default_variant
        schedule = Schedule.make(scene.duration, dt, sample_interval)
        settings = self.resolve(variant, options)
        self.check(scene, variant, options)
        info = RunInfo(
            engine=self.name,
            variant=f"{self.name}/{variant}",
            engine_version=self.version(),
            dt=float(dt),
            settings={**settings, **{f"override.{k}": v for k, v in self.overrides.items()}},
        )
        n_particles, n_constraints = len(scene.particles), len(scene.constraints)
        # Warnings of numerical libraries (numpy's overflow, scipy's, an engine's) become the case's message,
        # not lines on the terminal that no record keeps.
        with warnings.catch_warnings(record=True) as heard:
            warnings.simplefilter("always")
            try:
                started, cpu_started = time.perf_counter(), time.thread_time()
                raw = (self._run_model if scene.is_model else self._run)(scene, schedule, settings)
                elapsed, cpu = time.perf_counter() - started, time.thread_time() - cpu_started
                raw = check_raw_run(self.name, raw, scene, schedule, elapsed)
                info = replace(info, cpu_time=loop_cpu_time(raw, cpu))
            # An engine that raises, or returns nonsense, is a result, not a crash; so is one that calls
            # sys.exit (pydrake raises a failed C++ assertion as SystemExit).
            except (Exception, SystemExit) as exc:
                empty = np.empty((0, n_particles, 3))
                cause = blow_up_cause(exc)
                status, message = (Status.UNSTABLE, cause) if cause else (Status.FAILED, first_line(exc))
                message = join_messages(message, warning_note(heard))
                return Trajectory(np.empty(0), empty, empty.copy(), replace(info, status=status, message=message))
        trajectory = _finish(schedule, raw, info, n_constraints)
        note = warning_note(heard)
        if note:
            trajectory = replace(trajectory, info=replace(trajectory.info,
                                                          message=join_messages(trajectory.info.message, note)))
        return trajectory


#: What an engine says when its own finiteness check trips (Drake's DRAKE_THROW_UNLESS(AllFinite(q_v)),
#: a NaN/inf named in a message, numpy's FloatingPointError): the state blew up, the engine did not fail.
_BLOW_UP = re.compile(r"AllFinite|isfinite|non-?finite|not finite|\b(?:NaN|nan|inf|Inf|infinity)\b")


def blow_up_cause(exc: BaseException) -> str | None:
    """One line naming the cause when ``exc`` is an engine's reaction to a non-finite state, else None."""
    if isinstance(exc, (FloatingPointError, OverflowError)) or _BLOW_UP.search(str(exc)):
        line = first_line(exc)
        found = re.search(r"condition '([^']*)' failed", line)  # Drake's assertion: the condition is the cause
        if found:
            line = f"{type(exc).__name__}: condition '{found.group(1)}' failed"
        return f"non-finite state (the engine's own check: {line[:200]})"
    return None


def first_line(exc: BaseException) -> str:
    """``Type: first line of the message`` of an exception."""
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def warning_note(heard: list[warnings.WarningMessage]) -> str:
    """``warnings: overflow encountered in multiply (RuntimeWarning, 3×)``: each distinct warning once, in order."""
    counts: dict[tuple[str, str], int] = {}
    for w in heard:
        key = (str(w.message).splitlines()[0] if str(w.message) else "", w.category.__name__)
        counts[key] = counts.get(key, 0) + 1
    if not counts:
        return ""
    parts = [f"{text} ({category}{f', {n}×' if n > 1 else ''})" for (text, category), n in counts.items()]
    return "warnings: " + "; ".join(parts)


def join_messages(*parts: str) -> str:
    """The non-empty parts joined with ``; ``."""
    return "; ".join(p for p in parts if p)


class RawRunError(ValueError):
    """What an adapter's ``_run`` returned breaks the protocol; the message names the adapter, field and fix."""


def api_version_problem(engine: "Engine", who: str) -> str | None:
    """Why xval cannot run ``engine`` (declared ``api_version`` not spoken here), or None when it can.

    who : how to name the adapter in the message (``plugin 'my-solver' (my_solver.adapter:ENGINE)``).
    """
    declared = engine.api_version
    if declared in SUPPORTED_API_VERSIONS:
        return None
    speaks = ", ".join(map(str, SUPPORTED_API_VERSIONS))
    if isinstance(declared, int) and not isinstance(declared, bool) and declared > max(SUPPORTED_API_VERSIONS):
        return (f"{who} declares api_version = {declared}, newer than this xval speaks ({speaks}); "
                f"upgrade xval, or install a version of the plugin written for api_version {API_VERSION}")
    return (f"{who} declares api_version = {declared!r}, but this xval speaks api_version {speaks}; "
            f"update the adapter to the protocol in docs/plugins.md (see its 'Protocol versions' list), "
            f"then set api_version = {API_VERSION}")


def _as_samples(name: str, field_name: str, value: Any, n_particles_or_constraints: int, what: str,
                n_max: int) -> np.ndarray:
    """``value`` as a float64 (n, k, 3) array with 1 <= n <= n_max, or RawRunError naming the field."""
    expected = f"(n <= {n_max}, {n_particles_or_constraints}, 3): samples x {what} x (x, y, z)"
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise RawRunError(
            f"{name}: RawRun.{field_name} is not a numeric array ({type(value).__name__}); expected shape {expected}"
        ) from None
    if array.ndim != 3 or array.shape[1:] != (n_particles_or_constraints, 3) or not 1 <= array.shape[0] <= n_max:
        raise RawRunError(
            f"{name}: RawRun.{field_name} has shape {array.shape}, expected {expected}; record one row per "
            f"scheduled sample (schedule.sample_steps), in the scene frame (engines.external.plugin.Recorder builds it)"
        )
    return array


def check_raw_run(name: str, raw: Any, scene: Scene, schedule: Schedule, elapsed: float) -> RawRun:
    """Check what ``_run`` returned, once for every adapter; RawRunError says what is wrong and how to fix it.

    - ``raw`` is a RawRun; positions and velocities are (n, P, 3) with
      1 <= n <= len(schedule.times); forces are (n, C, 3) or None; joint_states
      (n, 2·nq) and constraint_violation (n,) or None;
    - units and frame: the first sample is the scene's initial state (m, m/s,
      scene frame, particles in scene order) to :data:`INITIAL_STATE_TOLERANCE`;
    - steps is an integer >= 0; wall_time is seconds, finite,
      >= 0 and no longer than ``elapsed`` (s, the whole ``_run`` call).

    Non-finite values are not errors here: ``_finish`` turns them into ``unstable``.
    Returns ``raw`` with float64 arrays.
    """
    if not isinstance(raw, RawRun):
        raise RawRunError(f"{name}: _run returned {type(raw).__name__}, expected engines.adapter.RawRun "
                          f"(engines.external.plugin.Recorder builds one)")
    n_max, n_p, n_c = len(schedule.times), len(scene.particles), len(scene.constraints)
    positions = _as_samples(name, "positions", raw.positions, n_p, "particles", n_max)
    velocities = _as_samples(name, "velocities", raw.velocities, n_p, "particles", n_max)
    if velocities.shape != positions.shape:
        raise RawRunError(f"{name}: RawRun.velocities has shape {velocities.shape} but positions {positions.shape}; "
                          f"record both at the same samples")
    forces = None
    if raw.forces is not None:
        forces = _as_samples(name, "forces", raw.forces, n_c, "constraints", n_max)
        if len(forces) != len(positions):
            raise RawRunError(f"{name}: RawRun.forces has {len(forces)} samples but positions {len(positions)}; "
                              f"record both at the same samples, or return forces=None")
    _check_initial_state(name, scene, positions[0], velocities[0])
    joint_states = raw.joint_states
    if joint_states is not None:
        joint_states = np.asarray(joint_states, dtype=np.float64)
        if joint_states.ndim != 2 or len(joint_states) != len(positions):
            raise RawRunError(f"{name}: RawRun.joint_states has shape {joint_states.shape}, expected "
                              f"({len(positions)}, 2·nq): q then v at each recorded sample")
    violation = raw.constraint_violation
    if violation is not None:
        violation = np.asarray(violation, dtype=np.float64)
        if violation.shape != (len(positions),):
            raise RawRunError(f"{name}: RawRun.constraint_violation has shape {violation.shape}, expected "
                              f"({len(positions)},): the largest constraint violation (m) at each recorded "
                              f"sample, or None")
    # No upper bound: an adaptive solver (the reference's DOP853) takes its own number of steps.
    if isinstance(raw.steps, bool) or not isinstance(raw.steps, (int, np.integer)) or raw.steps < 0:
        raise RawRunError(f"{name}: RawRun.steps = {raw.steps!r}, expected the integer number of steps taken (>= 0)")
    wall = raw.wall_time
    if isinstance(wall, bool) or not isinstance(wall, (int, float, np.floating)) or not math.isfinite(wall) or wall < 0:
        raise RawRunError(f"{name}: RawRun.wall_time = {wall!r}, expected seconds (a finite number >= 0)")
    # A stepping loop cannot take longer than the call around it; allow clock granularity.
    if wall > 1.05 * elapsed + 1e-3:
        raise RawRunError(
            f"{name}: RawRun.wall_time = {wall:.6g} s but _run took only {elapsed:.6g} s; give the stepping "
            f"loop's wall time in seconds (time.perf_counter() differences), not ms or ns"
        )
    return replace(raw, positions=positions, velocities=velocities, forces=forces, steps=int(raw.steps),
                   wall_time=float(wall), joint_states=joint_states, constraint_violation=violation)


def _check_initial_state(name: str, scene: Scene, q0: np.ndarray, v0: np.ndarray) -> None:
    """RawRunError when sample 0 (q0, v0: (P, 3) m, m/s) is not the scene's initial state."""
    if not (np.isfinite(q0).all() and np.isfinite(v0).all()):
        return  # unstable from the start: _finish reports it
    length = scene.characteristic_length
    speed = max(float(np.abs(scene.initial_velocities).max()),
                math.sqrt(float(np.linalg.norm(scene.gravity)) * length), 1e-3)
    dq = float(np.abs(q0 - scene.initial_positions).max())
    dv = float(np.abs(v0 - scene.initial_velocities).max())
    if dq > INITIAL_STATE_TOLERANCE * length:
        raise RawRunError(
            f"{name}: the first sample's positions are {dq:.3g} m off the scene's initial positions; sample 0 "
            f"must be the initial state in the scene frame (metres, z up, particles in scene order)"
        )
    if dv > INITIAL_STATE_TOLERANCE * speed:
        raise RawRunError(
            f"{name}: the first sample's velocities are {dv:.3g} m/s off the scene's initial velocities; sample 0 "
            f"must be the initial state in the scene frame (m/s, z up, particles in scene order)"
        )


def _finish(schedule: Schedule, raw: RawRun, info: RunInfo, n_constraints: int) -> Trajectory:
    """Build the Trajectory; truncate at the first non-finite sample (state, or reported constraint
    violation) and mark it unstable."""
    n = len(raw.positions)
    t = schedule.times[:n]
    finite = np.isfinite(raw.positions).all(axis=(1, 2)) & np.isfinite(raw.velocities).all(axis=(1, 2))
    if raw.constraint_violation is not None:
        # A joint gap that overflowed is a state gone non-finite, though the joint coordinates read finite.
        finite &= np.isfinite(raw.constraint_violation)
    status, message = Status.OK, raw.message
    if not finite.all():
        first_bad = int(np.argmin(finite))
        status = Status.UNSTABLE
        message = f"non-finite state at t = {t[first_bad]:.6g} s" + (f"; {raw.message}" if raw.message else "")
        n = first_bad
    elif n < len(schedule.times):
        # The adapter stopped stepping early (it saw the state run away).
        status = Status.UNSTABLE
        message = raw.message or f"stepping stopped at t = {t[-1] if n else 0:.6g} s"
    # Shapes were checked by check_raw_run; forces that go non-finite alone do not make a run unstable.
    forces = None if raw.forces is None else raw.forces[:n]
    info = replace(
        info,
        steps=int(raw.steps),
        wall_time=float(raw.wall_time),
        status=status,
        message=message,
        settings={**info.settings, **raw.settings},
    )
    joint_states = None if raw.joint_states is None else raw.joint_states[:n]
    violation = None if raw.constraint_violation is None else raw.constraint_violation[:n]
    return Trajectory(t[:n], raw.positions[:n], raw.velocities[:n], info, forces, joint_states, violation)


def parse_engine_id(engine_id: str) -> tuple[str, str | None]:
    """``"mujoco/hinge-rk4"`` -> ``("mujoco", "hinge-rk4")``; ``"reference"`` -> ``("reference", None)``."""
    name, _, variant = engine_id.partition("/")
    return name, (variant or None)
