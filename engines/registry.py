"""Which engines exist, imported lazily so a missing engine library is "unavailable", never a crash."""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from engines.adapter import Engine, parse_engine_id
from engines.errors import UserError

#: Built-in adapters: engine name -> module defining ``ENGINE``.
BUILTIN: dict[str, str] = {
    "reference": "engines.reference",
    "ours": "engines.ours",
    "mujoco": "engines.mujoco",
    "pybullet": "engines.pybullet",
    "pymunk": "engines.pymunk",
}


class EngineUnavailable(UserError):
    """The engine is known but its library (or adapter) cannot be imported here."""


@dataclass(frozen=True)
class EngineStatus:
    """What ``xval engines`` shows for one engine."""

    name: str
    origin: str
    engine: Engine | None
    reason: str = ""


def _load(name: str) -> EngineStatus:
    module_name = BUILTIN[name]
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        return EngineStatus(name, module_name, None, f"cannot import: {exc}")
    return EngineStatus(name, module_name, module.ENGINE)


def engine_names() -> list[str]:
    return list(BUILTIN)


def status(name: str) -> EngineStatus:
    if name not in BUILTIN:
        raise UserError(f"unknown engine {name!r}; choose one of: {', '.join(BUILTIN)}")
    return _load(name)


def get_engine(name: str) -> Engine:
    """The adapter for ``name``; UserError for an unknown engine, EngineUnavailable when it cannot load."""
    found = status(name)
    if found.engine is None:
        raise EngineUnavailable(f"engine {name!r} is unavailable: {found.reason}")
    return found.engine


def resolve(engine_id: str) -> tuple[Engine, str]:
    """``"mujoco/hinge-rk4"`` -> (the MuJoCo adapter, ``"hinge-rk4"``), the variant checked."""
    name, variant = parse_engine_id(engine_id)
    engine = get_engine(name)
    variant = variant or engine.default_variant
    if variant not in engine.variants:
        raise UserError(
            f"unknown variant {engine_id!r}; {name} has: {', '.join(engine.variant_ids())}"
        )
    return engine, variant
