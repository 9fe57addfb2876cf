"""The model imports ``xval model check`` compares, each reached through the registry (``Engine.model_import``).

``ENGINES`` (the registry's ``MODEL_CHECK``) are compared against ``REFERENCE``
(Pinocchio, engines/model/pinocchio.py). An engine whose library is not
installed raises :class:`Refused` saying why and how to install it.
"""

from __future__ import annotations

from engines import registry
from engines.adapter import ModelImport
from engines.errors import UserError
from engines.model.loaded import Refused

ENGINES = registry.MODEL_CHECK
REFERENCE = "pinocchio"
#: The pip package that provides the reference.
REFERENCE_PACKAGE = "pin"


def importer(name: str) -> ModelImport:
    """The model import of engine ``name`` (or of the reference); UserError for an unknown name, Refused
    when its library is missing."""
    if name == REFERENCE:
        try:
            from engines.model import pinocchio
        except ImportError as exc:
            raise Refused(f"not installed ({exc}); pip install {REFERENCE_PACKAGE}") from None
        return ModelImport(pinocchio.version, pinocchio.load)
    if name not in ENGINES:
        raise UserError(f"unknown model engine {name!r}; choose from {', '.join((*ENGINES, REFERENCE))}")
    found = registry.status(name)
    if found.engine is None:
        raise Refused(f"not installed ({found.reason})")
    made = found.engine.model_import()
    if made is None:
        raise UserError(f"engine {name!r} declares no model import (Engine.model_import)")
    return made
