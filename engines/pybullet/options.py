"""PyBullet's option tables: its defaults, the options and variants the adapter offers, what it overrides."""

from __future__ import annotations

from engines.adapter import Option
from engines.pybullet.library import pb

# -- PyBullet's own defaults (documented values; the library does not report them) ----------

#: btContactSolverInfo::m_erp2, the error reduction of non-contact constraints.
PYBULLET_ERP = 0.2
#: setPhysicsEngineParameter's numSolverIterations (a fresh client reports it; a test checks
#: this value against one, so importing the adapter connects no client).
PYBULLET_ITERATIONS = 50
#: btMultiBody::m_maxCoordinateVelocity, rad/s: PyBullet clamps multibody joint speeds to it.
#: Not raised: changeDynamics(maxJointVelocity=...) set the base free in 3.2.7 (the pendulum fell).
PYBULLET_MAX_JOINT_VELOCITY = 100.0

SOLVERS = {
    "si": pb.CONSTRAINT_SOLVER_LCP_SI,
    "pgs": pb.CONSTRAINT_SOLVER_LCP_PGS,
    "dantzig": pb.CONSTRAINT_SOLVER_LCP_DANTZIG,
}

#: Overrides a user can switch off (option ``keep_defaults``) to see what PyBullet's default costs:
#: damping (0.04 linear and angular per body), motors (a velocity motor on each joint), sleeping.
KEEPABLE = ("damping", "motors", "sleeping")

#: Point-mass inertia as a fraction of m·L², per formulation (the variants set it; docs/engines.md, "Adapter notes").
MULTIBODY_INERTIA_RATIO = 1e-9
P2P_INERTIA_RATIO = 1e-4

#: The adapter's options, variants (presets of them), one line per variant, and the defaults it overrides.
OPTIONS: dict[str, Option] = {
    "formulation": Option(
        "formulation",
        "multibody",
        "multibody: one multibody per Pin, revolute/spherical joints; p2p: separate bodies joined by JOINT_POINT2POINT",
        "str",
        ("multibody", "p2p"),
    ),
    "solver": Option(
        "solver",
        "si",
        "constraint solver: si (sequential impulse, PyBullet's default), pgs (MLCP projected Gauss-Seidel), "
        "dantzig (MLCP Dantzig, a direct solver)",
        "str",
        tuple(SOLVERS),
    ),
    "erp": Option(
        "erp",
        PYBULLET_ERP,
        f"fraction of a constraint's position error corrected per step (PyBullet's default {PYBULLET_ERP}); in [0, 1]",
    ),
    "iterations": Option(
        "iterations",
        PYBULLET_ITERATIONS,
        f"solver iterations per step (PyBullet's default {PYBULLET_ITERATIONS}); at least 1",
        "int",
        high=10_000,
    ),
    "keep_defaults": Option(
        "keep_defaults",
        "",
        "PyBullet defaults to leave in place, comma-separated, for measuring what they cost: "
        f"{', '.join(KEEPABLE)} (none by default)",
        "str",
    ),
    "inertia_ratio": Option(
        "inertia_ratio",
        MULTIBODY_INERTIA_RATIO,
        "each point mass's central inertia as a fraction of m·L² (L: the scene's characteristic length); "
        f"positive; {MULTIBODY_INERTIA_RATIO:g} for multibody, {P2P_INERTIA_RATIO:g} in the p2p variants "
        "(the sequential-impulse solver needs it)",
    ),
}
VARIANTS: dict[str, dict] = {
    "multibody": {"formulation": "multibody", "inertia_ratio": MULTIBODY_INERTIA_RATIO},
    "p2p": {"formulation": "p2p", "inertia_ratio": P2P_INERTIA_RATIO},
    "p2p-dantzig": {"formulation": "p2p", "solver": "dantzig", "inertia_ratio": P2P_INERTIA_RATIO},
    "p2p-dantzig-erp0.8": {
        "formulation": "p2p", "solver": "dantzig", "erp": 0.8, "inertia_ratio": P2P_INERTIA_RATIO,
    },
    "p2p-iter500": {"formulation": "p2p", "iterations": 500, "inertia_ratio": P2P_INERTIA_RATIO},
}
VARIANT_DOCS = {
    "multibody": "one multibody per Pin: revolute joints (spherical in 3-D), motors off, no damping",
    "p2p": "separate bodies joined by JOINT_POINT2POINT, PyBullet's default solver (sequential impulse, 50 iterations, ERP 0.2)",
    "p2p-dantzig": "p2p with the MLCP Dantzig (direct) solver, ERP 0.2",
    "p2p-dantzig-erp0.8": "p2p with the Dantzig solver and ERP 0.8 (stiffer drift correction)",
    "p2p-iter500": "p2p with the default sequential-impulse solver at 500 iterations",
}
OVERRIDES = {
    "gravity": "scene gravity (PyBullet's default: 0)",
    "fixedTimeStep": "dt (PyBullet's default: 1/240 s)",
    "numSubSteps": 0,
    "linearDamping": "0 (PyBullet's default: 0.04)",
    "angularDamping": "0 (PyBullet's default: 0.04)",
    "jointDamping": 0.0,
    "joint velocity motors": "disabled: zero maximum force (PyBullet's default holds each revolute joint at rest)",
    "sleeping": "disabled (PyBullet's default: bodies sleep after 2 s below 0.8 m/s and 1 rad/s)",
    "collision shapes": "none (no contacts possible)",
}
