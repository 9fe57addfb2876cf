"""A suite's scenes and engine variants as the reader builds them (compare.suite.reader) and every stage
reads them: the records the plans (compare.suite.plans) and the runner take.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from engines.adapter import Engine
from engines.scene.scene import SceneLike


@dataclass(frozen=True)
class SceneSpec:
    """One scene of a suite: readable ``id``, catalog ``name`` (``model`` for a model file), ``parameters`` as
    written, the built scene (a catalog Scene or a ModelScene)."""

    id: str
    name: str
    parameters: Mapping[str, Any]
    scene: SceneLike


@dataclass(frozen=True)
class EngineSpec:
    """One engine variant of a suite.

    id : what the suite wrote, expanded (``mujoco/hinge-rk4``, or
        ``tests.engines:BROKEN/raise``); used to load the engine in a worker.
    label : the readable id shown in tables and results (``id`` unless set).
    engine : the adapter, or None when it cannot be loaded here (``unavailable`` says why).
    variant : key of ``engine.variants``; options : as written in the suite.
    """

    id: str
    label: str
    variant: str | None
    options: Mapping[str, Any]
    engine: Engine | None
    unavailable: str = ""
