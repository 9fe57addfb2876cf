"""The one import of Drake (pydrake) in xval: its names, each imported on first use, and its version.

pydrake is imported where a plant is built (and by ``preload``, before a run forks its hosts): listing
the engines (`xval engines`) or planning a run needs only to know it is installed, and importing it was
much of what `xval engines` spent. ``library.MultibodyPlant`` imports pydrake.multibody.plant then.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
from typing import Any

if importlib.util.find_spec("pydrake") is None:
    raise ImportError("No module named 'pydrake'")

#: The pydrake names xval uses, by the module that defines them.
_MODULES = {
    "pydrake.autodiffutils": ("AutoDiffXd", "ExtractGradient", "ExtractValue", "InitializeAutoDiff"),
    "pydrake.math": ("RigidTransform", "RollPitchYaw", "RotationMatrix"),
    "pydrake.multibody.plant": ("DiscreteContactApproximation", "MultibodyPlant"),
    "pydrake.multibody.tree": ("BallRpyJoint", "BodyIndex", "FixedOffsetFrame", "RevoluteJoint", "RotationalInertia",
                               "SpatialInertia"),
    "pydrake.multibody.parsing": ("Parser",),
    "pydrake.systems.analysis": ("ResetIntegratorFromFlags", "Simulator", "Simulator_"),
}
_WHERE = {name: module for module, names in _MODULES.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_WHERE[name]), name)


def preload() -> None:
    """Import every pydrake module xval uses, so that processes forked from this one inherit them."""
    for module in _MODULES:
        importlib.import_module(module)


def version() -> str:
    """Drake's version string, from the installed wheel's metadata (pydrake has no __version__ in some
    wheels), so that asking needs no import of pydrake."""
    return importlib.metadata.version("drake")
