"""The shape every engine's model import shares (engines/model/<engine>.py).

Each engine module has ``NAME``, ``version()`` and ``load(source,
description, **options) -> LoadedModel``, raising :class:`Refused` with the
engine's own message when the engine will not take the file. A
:class:`LoadedModel` answers in the description's moving-joint order and SI
units: q, v, tau, accelerations are (nq,) arrays (rad, m, rad/s, m/s, N·m,
N); continuous joints are one angle each.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Iterable

import numpy as np

from engines.model.description import ModelDescription
from engines.model.inertia import LinkInertia

#: Gravity of every model (m/s², along −z), set explicitly in each engine.
GRAVITY = 9.81


class Refused(Exception):
    """The engine would not load the file; the message is the engine's own."""


class LoadedModel(ABC):
    """One engine's import of one model file.

    options : the import options used, name -> value (every one stated, defaults included).
    notes : what the import changed or left out, in words (e.g. joint damping set to 0).
    """

    engine: str = ""

    def __init__(self, description: ModelDescription, options: dict[str, str], notes: Iterable[str] = ()):
        self.description = description
        self.options = dict(options)
        self.notes = tuple(notes)

    @abstractmethod
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) : (nq, nq) kg·m² (kg, kg·m for prismatic rows)."""

    @abstractmethod
    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """b(q, v) = C(q, v) v + g(q) : (nq,), so that M a + b = tau."""

    @abstractmethod
    def forward(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """a(q, v, tau) : (nq,), the engine's own forward dynamics (no damping, limits or contacts)."""

    @abstractmethod
    def link_inertias(self) -> dict[str, LinkInertia]:
        """Link name -> mass properties in the world frame at q = 0, for every link the engine keeps
        (a link it fused into another is missing; the survivor holds the group)."""


    def joint_origins(self) -> dict[str, np.ndarray] | None:
        """Revolute (continuous) joint name -> a point on its axis (3,) m in the world at the neutral
        configuration, as the engine placed it; None (the default) when the engine does not say."""
        return None


def index_map(description: ModelDescription, engine_names: list[str]) -> np.ndarray:
    """For each of the description's moving joints, its index in the engine's list of joint names."""
    where = {name: k for k, name in enumerate(engine_names)}
    missing = [j.name for j in description.moving_joints if j.name not in where]
    if missing:
        raise Refused(f"the engine's model has no joint named {', '.join(missing)}")
    return np.array([where[j.name] for j in description.moving_joints], dtype=int)
