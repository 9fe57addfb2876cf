"""ours: constrained dynamics in maximal coordinates (after Baraff & Witkin), a library of its own.

Point masses here; rigid bodies (revolute, prismatic, fixed and ball joints) in :mod:`ours.rigid`.
Build a :class:`System` of masses, gravity and constraints (:class:`Pin`, :class:`Wire`, :class:`Rod`;
in 2-D also :class:`Line` and :class:`Ellipse`), then :func:`simulate` a whole trajectory in one call;
the stepping loop is compiled with numba (cached between runs) for every constraint kind.

    >>> from ours import System, Wire, simulate
    >>> bead = System((1.0,), (0.0, -9.81), (Wire(0, (0.0, 0.0), 1.0),))
    >>> run = simulate(bead, [[1.0, 0.0]], [[0.0, 0.0]], 1e-3, 1000, 10, method="rattle")
"""

from ours.cache import configure_numba

configure_numba()  # before anything imports numba (ours imports it on the first simulate)

from ours.bead import bead_multiplier  # noqa: E402
from ours.constraint import CurveConstraint, DistanceConstraint, Ellipse, Line, Pin, Rod, Wire  # noqa: E402
from ours.errors import InvalidPair, ModelError, OursError  # noqa: E402
from ours.integrator import INTEGRATORS, Integrator, get_integrator  # noqa: E402
from ours.method import DEFAULT_K_S, METHODS, critical_damping, resolve_pair, valid_pairs  # noqa: E402
from ours.simulate import Result, compile_all, multipliers, simulate  # noqa: E402
from ours.system import System  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_K_S", "INTEGRATORS", "METHODS", "CurveConstraint", "DistanceConstraint", "Ellipse", "Line", "Integrator", "InvalidPair",
    "ModelError", "OursError", "Pin", "Result", "Rod", "System", "Wire", "bead_multiplier",
    "compile_all", "critical_damping", "get_integrator", "multipliers", "resolve_pair",
    "simulate", "valid_pairs",
]
