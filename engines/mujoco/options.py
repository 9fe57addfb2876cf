"""MuJoCo's option tables: its defaults, the options and variants the adapter offers, what it overrides."""

from __future__ import annotations

import numpy as np

from engines.adapter import Option
from engines.mujoco.library import mujoco

#: MuJoCo's own default solref (timeconst s, dampratio) and solimp (dmin, dmax, width m, midpoint, power).
_ref, _imp = np.zeros(mujoco.mjNREF), np.zeros(mujoco.mjNIMP)
mujoco.mj_defaultSolRefImp(_ref, _imp)
MUJOCO_SOLREF: tuple[float, ...] = tuple(float(x) for x in _ref)
MUJOCO_SOLIMP: tuple[float, ...] = tuple(float(x) for x in _imp)

#: Point-mass inertia as a fraction of m·L², per formulation (the variants set it; docs/engines.md, "Adapter notes").
HINGE_INERTIA_RATIO = 1e-12
CONNECT_INERTIA_RATIO = 1e-9
#: kg·m²: the least inertia MuJoCo compiles ("mass and inertia of moving bodies must be larger than
#: mjMINVAL"); a ratio that would give less is raised to it (a scene smaller than ~3 cm at 1 kg).
MIN_INERTIA = mujoco.mjMINVAL * (1 + 1e-6)

#: Stiff equality setting: time constant 2·dt (the smallest refsafe allows), critical damping,
#: impedance 0.9999 whatever the violation (R = 1e-4 of the constraint's inverse mass).
STIFF = {"timeconst_steps": 2.0, "solref": (0.02, 1.0), "solimp": (0.9999, 0.9999, 0.001, 0.5, 2.0)}
#: The connect variants' point-mass inertia: a ball joint turns the arm with it.
CONNECT = {"inertia_ratio": CONNECT_INERTIA_RATIO}

INTEGRATORS = {
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}

#: The adapter's options, variants (presets of them), one line per variant, and the defaults it overrides.
OPTIONS: dict[str, Option] = {
    "formulation": Option(
        "formulation", "hinge", "hinge: nested bodies with joints; connect: free bodies and connect equalities",
        kind="str", choices=("hinge", "connect"),
    ),
    "integrator": Option(
        "integrator", "Euler", "MuJoCo integrator (Euler is MuJoCo's default, semi-implicit)",
        kind="str", choices=tuple(INTEGRATORS),
    ),
    "solref": Option(
        "solref", MUJOCO_SOLREF,
        "connect: timeconst (s), dampratio of the equality constraints (MuJoCo's default 0.02, 1)",
        kind="floats",
    ),
    "solimp": Option(
        "solimp", MUJOCO_SOLIMP,
        "connect: dmin, dmax, width (m), midpoint, power (MuJoCo's default 0.9, 0.95, 0.001, 0.5, 2)",
        kind="floats",
    ),
    "timeconst_steps": Option(
        "timeconst_steps", 0.0,
        "connect: when > 0, solref's time constant is this many time steps (2 is the least refsafe allows)",
    ),
    "refsafe": Option(
        "refsafe", True, "keep MuJoCo's refsafe clamp of solref's time constant to at least 2·dt", kind="bool"
    ),
    "inertia_ratio": Option(
        "inertia_ratio", HINGE_INERTIA_RATIO,
        "rotational inertia of each point-mass body, as a fraction of m·L² (L: the scene's length scale); "
        f"{HINGE_INERTIA_RATIO:g} for hinge, {CONNECT_INERTIA_RATIO:g} in the connect variants",
    ),
}
VARIANTS: dict[str, dict] = {
    "hinge": {"formulation": "hinge"},
    "hinge-rk4": {"formulation": "hinge", "integrator": "RK4"},
    "hinge-implicit": {"formulation": "hinge", "integrator": "implicit"},
    "hinge-implicitfast": {"formulation": "hinge", "integrator": "implicitfast"},
    "connect": {"formulation": "connect", **CONNECT},
    "connect-stiff": {"formulation": "connect", **CONNECT, **STIFF},
    "connect-rk4": {"formulation": "connect", "integrator": "RK4", **CONNECT},
    "connect-rk4-stiff": {"formulation": "connect", "integrator": "RK4", **CONNECT, **STIFF},
    "connect-implicitfast-stiff": {"formulation": "connect", "integrator": "implicitfast", **CONNECT, **STIFF},
}
VARIANT_DOCS = {
    "hinge": "reduced coordinates, MuJoCo's default Euler integrator",
    "hinge-rk4": "reduced coordinates, RK4 (4th order)",
    "hinge-implicit": "reduced coordinates, implicit in velocity",
    "hinge-implicitfast": "reduced coordinates, implicit in velocity without the RNE derivative",
    "connect": "free bodies + connect equalities with MuJoCo's default solref/solimp, Euler",
    "connect-stiff": "connect with solref time constant 2·dt, solimp 0.9999, Euler",
    "connect-rk4": "connect with MuJoCo's default solref/solimp, RK4",
    "connect-rk4-stiff": "connect with the stiff setting, RK4",
    "connect-implicitfast-stiff": "connect with the stiff setting, implicitfast",
}
OVERRIDES = {"flag.contact": "disable (default enable): the scenes have nothing to collide"}
