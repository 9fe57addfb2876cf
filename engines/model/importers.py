"""The engines that import model files, by name, each imported only when asked for.

``ENGINES`` are compared against ``REFERENCE`` (Pinocchio). An engine whose
library is not installed raises :class:`Refused` saying how to install it.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from engines.errors import UserError
from engines.model.loaded import Refused

ENGINES = ("mujoco", "pybullet", "drake", "dart")
REFERENCE = "pinocchio"
#: Engine name -> the pip package that provides it.
PACKAGES = {"mujoco": "mujoco", "pybullet": "pybullet", "drake": "drake", "dart": "dartpy", "pinocchio": "pin"}


def importer(name: str) -> ModuleType:
    """The module engines/<name>/model.py (Pinocchio's: engines/model/pinocchio.py); UserError for an unknown
    name, Refused when its library is missing."""
    if name not in PACKAGES:
        raise UserError(f"unknown model engine {name!r}; choose from {', '.join((*ENGINES, REFERENCE))}")
    try:
        return importlib.import_module("engines.model.pinocchio" if name == REFERENCE else f"engines.{name}.model")
    except ImportError as exc:
        raise Refused(f"not installed ({exc}); pip install {PACKAGES[name]}") from None
