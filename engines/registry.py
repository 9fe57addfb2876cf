"""Which engines exist, and the one place an engine id is turned into an adapter.

Four kinds of engine, all loaded lazily so one that cannot load is "unavailable" (with the
reason): built-in (``BUILTIN``: name → module defining ``ENGINE``), plugin (entry point group
``xval.engines``), by path (``package.module:ATTRIBUTE[/variant]``) and command
(``command/<label>``, an outside program speaking the process protocol).

Details: docs/engines.md, "Adapter notes", ``engines/registry.py``.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
from dataclasses import dataclass
from collections.abc import Callable
from typing import Any

from engines.adapter import Engine, api_version_problem, parse_engine_id
from engines.errors import UserError

#: Built-in adapters: engine name -> module defining ``ENGINE``. Each engine lives in a folder of its own,
#: engines/<engine>/ (its adapter, its model import, the one import of its library); adding one is that
#: folder and a line here (docs/plugins.md).
BUILTIN: dict[str, str] = {
    "reference": "engines.reference.reference",
    "ours": "engines.ours.adapter",
    "mujoco": "engines.mujoco.adapter",
    "pybullet": "engines.pybullet.adapter",
    "pymunk": "engines.pymunk.adapter",
    "drake": "engines.drake.adapter",
    "mjx": "engines.mjx.adapter",
    "dart": "engines.dart.adapter",
}

#: Built-ins whose library is an optional extra: the pip line that installs it, shown when it is missing.
INSTALL: dict[str, str] = {
    "drake": "pip install 'xval[drake]'",
    "mjx": "pip install 'xval[mjx]'",
    "dart": "pip install 'xval[dart]'",
}

#: Optional built-ins' distributions, whose installed version can be read without importing them
#: (pydrake's import is slow; a run that does not use Drake need not pay for it).
DISTRIBUTION: dict[str, str] = {
    "drake": "drake",
    "mjx": "mujoco-mjx",
    "dart": "dartpy",
}

#: Built-ins whose import of model files ``xval model check`` compares with Pinocchio's (``Engine.model_import``).
MODEL_CHECK: tuple[str, ...] = ("mujoco", "pybullet", "drake", "dart")

#: The entry-point group installed packages register engines under.
ENTRY_POINT_GROUP = "xval.engines"


class EngineUnavailable(UserError):
    """The engine is known but its library (or adapter) cannot be loaded here; the message says why."""


@dataclass(frozen=True)
class EngineStatus:
    """What ``xval engines`` shows for one engine.

    origin : where it comes from: ``engines.mujoco.adapter`` (built-in),
        ``plugin my-solver 0.1.0: my_solver.adapter:ENGINE`` (entry point),
        or ``module:ATTRIBUTE`` (by path).
    kind : ``"built-in"``, ``"plugin"`` or ``"path"``.
    engine : the adapter, or None when unavailable (``reason`` says why).
    """

    name: str
    origin: str
    engine: Engine | None
    reason: str = ""
    kind: str = "built-in"


# -- discovery -------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def entry_points() -> dict[str, importlib.metadata.EntryPoint]:
    """Installed ``xval.engines`` entry points by name.

    Read once per process (scanning every installed distribution costs ~5 ms,
    and a worker resolves an engine id per case); ``entry_points.cache_clear()``
    rereads them after installing a plugin in a running process.
    """
    found: dict[str, importlib.metadata.EntryPoint] = {}
    for point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(point.name, point)  # the first installed distribution wins, like importlib's own lookup
    return found


def _origin(point: importlib.metadata.EntryPoint) -> str:
    dist = getattr(point, "dist", None)
    where = f"{dist.metadata['Name']} {dist.version}" if dist is not None else "unknown distribution"
    return f"plugin from {where}: {point.value}"


def engine_names() -> list[str]:
    """Built-in names, then installed plugins' names (sorted)."""
    return list(BUILTIN) + sorted(set(entry_points()) - set(BUILTIN))


# -- loading ---------------------------------------------------------------------


#: Modules of engines/ before it was split into folders by job, by where they are now: a plugin written
#: against them fails to import, and its error says where to import from.
MOVED = {
    **{f"engines.{n}": f"engines.scene.{n}" for n in ("limits", "catalog", "trajectory", "pendulum", "tree")},
    "engines.reference_mechanisms": "engines.reference.mechanisms",
    "engines.closed_form": "engines.reference.closed_form",
    "engines.adapters": "engines.<engine>.adapter (each engine's home)",
    **{f"engines.adapters.{n}": f"engines.{n}.adapter"
       for n in ("mujoco", "pybullet", "pymunk", "drake", "dart", "mjx", "ours")},
    **{f"engines.model.{n}": f"engines.{n}.model" for n in ("mujoco", "pybullet", "drake", "dart", "ours")},
    **{f"engines.{n}": f"engines.external.{n}" for n in ("protocol", "command", "plugin")},
}
#: Old modules that are packages now, by where their contents went.
BECAME_PACKAGES = {"engines": "engines.scene.catalog, engines.external.plugin, …",
                   "engines.scene": "engines.scene.scene", "engines.reference": "engines.reference.reference",
                   **{f"engines.{n}": f"engines.{n}.adapter"
                      for n in ("mujoco", "pybullet", "pymunk", "drake", "dart", "mjx", "ours")}}


def _failure(exc: BaseException) -> str:
    message = f"{type(exc).__name__}: {exc}".splitlines()[0]
    name = exc.name if isinstance(exc, ImportError) else None
    if isinstance(exc, ModuleNotFoundError) and name in MOVED:
        return f"{message}; {name} is {MOVED[name]} now: import it from there"
    if isinstance(exc, ImportError) and not isinstance(exc, ModuleNotFoundError) and name in BECAME_PACKAGES:
        return (f"{message}; {name} is a package of modules now ({BECAME_PACKAGES[name]}): import from the module, "
                f"or take what a plugin needs from engines.external.plugin (docs/plugins.md)")
    return message


def _adopt(obj: Any, who: str) -> Engine:
    """An Engine from what a plugin exported (an instance or a subclass), its api_version checked.

    Raises EngineUnavailable naming ``who`` and the fix.
    """
    if isinstance(obj, type) and issubclass(obj, Engine):
        try:
            obj = obj()
        except Exception as exc:  # a plugin's constructor is its code: contain it
            raise EngineUnavailable(f"{who}: creating {obj.__name__}() raised {_failure(exc)}") from None
    if not isinstance(obj, Engine):
        raise EngineUnavailable(
            f"{who} is a {type(obj).__name__}, not an engines.adapter.Engine; point it at an instance "
            f"(or subclass) of Engine, e.g. ENGINE = MySolverEngine()"
        )
    problem = api_version_problem(obj, who)
    if problem:
        raise EngineUnavailable(problem)
    return obj


def _load_builtin(name: str) -> EngineStatus:
    module_name = BUILTIN[name]
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        hint = f"; install it with: {INSTALL[name]}" if name in INSTALL else ""
        return EngineStatus(name, module_name, None, f"cannot import: {exc}{hint}")
    return EngineStatus(name, module_name, module.ENGINE)


def _load_plugin(name: str, point: importlib.metadata.EntryPoint) -> EngineStatus:
    origin = _origin(point)
    who = f"plugin {name!r} ({point.value})"
    try:
        exported = point.load()
    except BaseException as exc:  # noqa: BLE001 - a plugin's import runs its code; only it should pay
        if isinstance(exc, KeyboardInterrupt):
            raise
        return EngineStatus(name, origin, None, f"{who}: cannot load: {_failure(exc)}", "plugin")
    try:
        engine = _adopt(exported, who)
    except EngineUnavailable as exc:
        return EngineStatus(name, origin, None, str(exc), "plugin")
    if engine.name != name:
        # Results record engine.name; a mismatch would file cases under a name `xval engines` does not show.
        return EngineStatus(name, origin, None, f"{who}: its Engine.name is {engine.name!r}, but the entry point is "
                            f"named {name!r}; make them the same", "plugin")
    return EngineStatus(name, origin, engine, kind="plugin")


def status(name: str) -> EngineStatus:
    """How engine ``name`` (built-in or plugin) loads here; UserError listing the valid names for an unknown one."""
    if name in BUILTIN:
        return _load_builtin(name)
    points = entry_points()
    if name in points:
        return _load_plugin(name, points[name])
    # (An adapter that is not installed can also be named by path, package.module:ATTRIBUTE; docs/plugins.md.)
    raise UserError(f"unknown engine {name!r}; choose one of: {', '.join(engine_names())}")


def statuses() -> list[EngineStatus]:
    """Every built-in and installed plugin, loaded; a plugin shadowed by a built-in's name is unavailable."""
    out = [status(name) for name in BUILTIN]
    for name, point in sorted(entry_points().items()):
        if name in BUILTIN:
            out.append(EngineStatus(name, _origin(point), None,
                                    f"the name {name!r} is a built-in engine's; rename the entry point", "plugin"))
        else:
            out.append(_load_plugin(name, point))
    return out


def get_engine(name: str) -> Engine:
    """The adapter for ``name``; UserError for an unknown engine, EngineUnavailable when it cannot load."""
    found = status(name)
    if found.engine is None:
        raise EngineUnavailable(f"engine {name!r} is unavailable: {found.reason}")
    return found.engine


def describer(file_format: str) -> Callable[[Any], Any]:
    """The reader of ``file_format`` files (``"mjcf"``) whose meaning an engine's compiler defines
    (``ModelImport.describes``): ``describe(source)`` -> a ModelDescription. EngineUnavailable when no
    model-check engine that reads it can load here."""
    reasons = []
    for name in MODEL_CHECK:
        try:
            found = get_engine(name).model_import()
        except EngineUnavailable as exc:
            reasons.append(str(exc))
            continue
        if file_format in found.describes and found.describe is not None:
            return found.describe
    raise EngineUnavailable(f"no engine that defines {file_format.upper()} files can load here"
                            + (f" ({'; '.join(reasons)})" if reasons else ""))


def load_path(target: str) -> Engine:
    """The Engine at ``package.module:ATTRIBUTE``.

    UserError when the id is malformed or the attribute does not exist (a
    typo in the suite); EngineUnavailable when the module fails to import or
    the object is not a usable Engine (the plugin is broken: its cases are
    skipped with this reason and the rest of the suite runs).
    """
    module_name, _, attribute = target.partition(":")
    if not module_name or not attribute:
        raise UserError(f"engine {target!r}: write a path as package.module:ATTRIBUTE, e.g. my_solver.adapter:ENGINE")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and module_name.startswith(exc.name):
            raise UserError(f"engine {target!r}: no module named {module_name!r}; install the package that "
                            f"provides it, or put its directory on PYTHONPATH") from None
        raise EngineUnavailable(f"engine {target!r} is unavailable: importing {module_name} failed: "
                                f"{_failure(exc)}") from None
    except BaseException as exc:  # noqa: BLE001 - the module's own code raised while importing
        if isinstance(exc, KeyboardInterrupt):
            raise
        raise EngineUnavailable(f"engine {target!r} is unavailable: importing {module_name} failed: "
                                f"{_failure(exc)}") from None
    exported = getattr(module, attribute, None)
    if not (isinstance(exported, Engine) or (isinstance(exported, type) and issubclass(exported, Engine))):
        # A path to the wrong object is a typo in the suite, not a broken plugin: say so at once.
        raise UserError(f"engine {target!r}: {module_name}.{attribute} is not an Engine object; "
                        f"point module:attribute at an engines.adapter.Engine instance")
    return _adopt(exported, f"engine {target!r}")


def load_engine(engine_id: str) -> tuple[Engine, str | None]:
    """(engine, variant or None) for ``name[/variant]`` or ``package.module:ATTRIBUTE[/variant]``.

    The single place engine ids are resolved (suites, workers, the CLI).
    Raises UserError for an unknown engine, EngineUnavailable for one that
    cannot load here.
    """
    if ":" in engine_id:
        target, _, given = engine_id.partition("/")
        return load_path(target), (given or None)
    name, variant = parse_engine_id(engine_id)
    if name == "command" and name not in BUILTIN:  # an outside program (engines.external.command), registered by label
        from engines.external.command import registered

        if not variant:
            raise UserError("engine 'command' needs a label: command/<label>, declared in the suite as "
                            "[[engines]] command = [...], label = \"...\"")
        return registered(variant), variant
    return get_engine(name), variant


def resolve(engine_id: str) -> tuple[Engine, str]:
    """``"mujoco/hinge-rk4"`` -> (the MuJoCo adapter, ``"hinge-rk4"``), the variant checked; any id form."""
    engine, variant = load_engine(engine_id)
    variant = variant or engine.default_variant
    if variant not in engine.variants:
        raise UserError(
            f"unknown variant {engine_id!r}; {engine.name} has: {', '.join(engine.variant_ids())}"
        )
    return engine, variant
