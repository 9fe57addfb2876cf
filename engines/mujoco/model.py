"""MuJoCo's import of a model file: URDF through its compiler, MJCF natively.

Import options (a URDF gets a ``<mujoco><compiler …/></mujoco>`` element):
fusestatic = true (MuJoCo's URDF default: links welded by fixed joints are
fused into one body), inertiafromgeom = auto (its default: only links with
no ``<inertial>`` would take mass from geometry, and none is left),
balanceinertia = false (an inertia violating A + B ≥ C is refused, as
MuJoCo does; ``balance_inertia=True`` turns it on), discardvisual = true.
An MJCF file is compiled as written. Joint damping, friction loss and
armature are set to 0 after compiling (then ``mj_setConst``), the medium
(density, viscosity, wind) too, and the constraint solver is disabled (no
joint limits or contacts), so forward dynamics are the tree's.
"""

from __future__ import annotations


import numpy as np

from engines.model.description import ModelDescription
from engines.model.floating import Mapping, linear_world_angular_body
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource
from engines.model.stepping import common_settings, kept_damping, Stepper
from engines.mujoco.library import mujoco
from engines.model.scene import ModelScene

NAME = "mujoco"


def version() -> str:
    return mujoco.__version__


def compiler_options(balance_inertia: bool = False, fusestatic: bool = True) -> dict[str, str]:
    return {"fusestatic": "true" if fusestatic else "false", "inertiafromgeom": "auto",
            "balanceinertia": "true" if balance_inertia else "false", "discardvisual": "true"}


def load(source: ModelSource, description: ModelDescription, balance_inertia: bool = False,
         fusestatic: bool = True) -> "MujocoModel":
    """``fusestatic=False`` keeps welded links as bodies of their own (not MuJoCo's URDF default)."""
    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    options = compiler_options(balance_inertia, fusestatic) if source.format == "urdf" else {"mjcf": "compiled as written"}
    if source.format == "urdf":
        text = _with_compiler(text, options)
    try:
        if source.format == "urdf" and description.floating is not None:
            # MuJoCo welds a URDF's root: a free joint added to it in the spec, before compiling.
            spec = mujoco.MjSpec.from_string(text)
            spec.worldbody.first_body().add_freejoint(name=description.floating.name)
            model = spec.compile()
            options = {**options, "floating_base": "a free joint added to the root body (MjSpec.add_freejoint)"}
        else:
            model = mujoco.MjModel.from_xml_string(text)
    except ValueError as exc:
        raise Refused(" ".join(str(exc).split())) from None
    return MujocoModel(model, description, options, notes)


def _with_compiler(text: str, options: dict[str, str]) -> str:
    import xml.etree.ElementTree as ET

    robot = ET.fromstring(text)
    for old in robot.findall("mujoco"):
        robot.remove(old)
    extension = ET.SubElement(robot, "mujoco")
    ET.SubElement(extension, "compiler", options)
    return ET.tostring(robot, encoding="unicode")


class MujocoModel(LoadedModel):
    engine = NAME

    def __init__(self, model, description: ModelDescription, options: dict[str, str], notes=()):
        model.dof_damping[:] = 0.0
        model.dof_frictionloss[:] = 0.0
        model.dof_armature[:] = 0.0
        model.jnt_stiffness[:] = 0.0
        model.opt.gravity[:] = (0.0, 0.0, -GRAVITY)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        fluid = bool(model.opt.density or model.opt.viscosity or np.any(model.opt.wind))
        model.opt.density, model.opt.viscosity, model.opt.wind[:] = 0.0, 0.0, 0.0  # no medium: the tree's dynamics
        super().__init__(description, options, (*notes, "joint damping, friction loss, armature and stiffness "
                                                "set to 0; constraints (limits, contacts) disabled",
                                                *(("the medium's density, viscosity and wind set to 0 (the file's "
                                                   "fluid forces left out)",) if fluid else ())))
        self.model, self.data = model, mujoco.MjData(model)
        # The compiler folds armature into the constant mass of "simple" bodies (dof_M0, a body whose only joints
        # are slides: pusher.xml's object): recompute the constants, or those dofs keep their armature.
        mujoco.mj_setConst(model, self.data)
        kinds = mujoco.mjtJoint
        free = [k for k in range(model.njnt) if model.jnt_type[k] == int(kinds.mjJNT_FREE)]
        joints = [k for k in range(model.njnt) if model.jnt_type[k] != int(kinds.mjJNT_FREE)]
        if len(free) != (description.floating is not None):
            raise Refused(f"only one free joint, for a floating base, is compared; mujoco has {len(free)} free joints")
        chosen = [joints[k] for k in index_map(description, [model.joint(k).name for k in joints])]
        ball = int(kinds.mjJNT_BALL)
        for joint, k in zip(description.moving_joints, chosen):
            if (joint.type == "ball") != (model.jnt_type[k] == ball):
                raise Refused(f"mujoco's joint {joint.name} is {'a ball' if model.jnt_type[k] == ball else 'not a ball'}; "
                              f"the file's is {joint.type}")
        #: MuJoCo's qpos index of each of xval's joint configuration entries: a ball's quaternion x y z w read from
        #: MuJoCo's w x y z; its qvel index of each joint velocity entry (a ball's: the child's angular velocity
        #: in the child's frame, as xval's, measured by tests/test_ball_joint.py).
        self.qpos = np.array([i for k in chosen for i in ([model.jnt_qposadr[k] + n for n in (1, 2, 3, 0)]
                                                          if model.jnt_type[k] == ball else [model.jnt_qposadr[k]])],
                             dtype=int)
        self.dof = np.array([model.jnt_dofadr[k] + n for k in chosen for n in range(3 if model.jnt_type[k] == ball else 1)],
                            dtype=int)
        #: The free joint's first qpos and qvel entries (position, quaternion w x y z; linear, angular).
        self.base_q = int(model.jnt_qposadr[free[0]]) if free else -1
        base = np.arange(model.jnt_dofadr[free[0]], model.jnt_dofadr[free[0]] + 6) if free else np.zeros(0, int)
        #: MuJoCo's velocity index of each of xval's (the base's six first).
        self.selected = np.concatenate([base, self.dof]).astype(int)

    def _mapping(self, q, v=None) -> Mapping | None:
        return Mapping(linear_world_angular_body, np.asarray(q, dtype=float), v, self.description.nv) \
            if self.base_q >= 0 else None

    def _set(self, q, v=None, tau=None) -> Mapping | None:
        d, q = self.data, np.asarray(q, dtype=float)
        mapping = self._mapping(q, None if v is None else np.asarray(v, dtype=float))
        d.qpos[:] = self.model.qpos0  # a ball joint's unit quaternion where xval's q does not reach
        d.qvel[:] = 0.0
        d.qfrc_applied[:] = 0.0
        if mapping is not None:
            d.qpos[self.base_q:self.base_q + 7] = *q[:3], q[6], *q[3:6]
            q = q[7:]
        d.qpos[self.qpos] = q
        if v is not None:
            d.qvel[self.selected] = v if mapping is None else mapping.velocity(v)
        if tau is not None:
            d.qfrc_applied[self.selected] = tau if mapping is None else mapping.force(tau)
        return mapping

    def _full_mass(self) -> np.ndarray:
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)
        return full[np.ix_(self.selected, self.selected)]

    def mass_matrix(self, q):
        mapping = self._set(q)
        mujoco.mj_forward(self.model, self.data)
        return self._full_mass() if mapping is None else mapping.mass_matrix(self._full_mass())

    def bias(self, q, v):
        mapping = self._set(q, v)
        mujoco.mj_forward(self.model, self.data)
        bias = self.data.qfrc_bias[self.selected].copy()
        return bias if mapping is None else mapping.bias(self._full_mass(), bias)

    def forward(self, q, v, tau):
        mapping = self._set(q, v, tau)
        mujoco.mj_forward(self.model, self.data)
        acceleration = self.data.qacc[self.selected].copy()
        return acceleration if mapping is None else mapping.acceleration(acceleration)

    def link_inertias(self):
        self._set(self.description.neutral())
        mujoco.mj_kinematics(self.model, self.data)
        found = {}
        for k in range(1, self.model.nbody):  # body 0 is the world
            # ximat: the inertial frame's axes in the world; body_inertia: principal moments in it.
            found[self.model.body(k).name or f"body{k}"] = world_inertia(  # unnamed: as engines.mujoco.description names it
                self.model.body_mass[k], np.zeros(3), np.diag(self.model.body_inertia[k]),
                self.data.ximat[k].reshape(3, 3), self.data.xipos[k])
        return found


class MujocoStepper(Stepper):
    """MuJoCo: the compiled file (engines.mujoco.model), ``mj_step`` with the variant's integrator."""

    def __init__(self, scene: ModelScene, dt: float, integrator: str) -> None:
        self.mujoco = mujoco
        loaded = load(scene.source, scene.description)
        self.model, self.data = loaded.model, loaded.data
        self.model.opt.timestep = dt
        self.model.opt.gravity[:] = scene.gravity
        self.model.opt.integrator = int(getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}"))
        self.qpos, self.dof, self.loaded = loaded.qpos, loaded.dof, loaded
        self.model.dof_damping[self.dof] = kept_damping(scene)
        loaded._set(scene.initial_q, scene.initial_v)  # a floating base mapped from xval's convention
        mujoco.mj_forward(self.model, self.data)
        self.settings = {**common_settings(scene, loaded), "integrator": integrator,
                         "disableflags": int(self.model.opt.disableflags)}

    def advance(self, steps: int) -> None:
        self.mujoco.mj_step(self.model, self.data, nstep=steps)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        q, v = self.data.qpos[self.qpos].copy(), self.data.qvel[self.dof].copy()
        start = self.loaded.base_q
        if start < 0:
            return q, v
        # The free joint's (p, w x y z) and (R v, ω) as xval's (p, x y z w) and (v, ω).
        pose = self.data.qpos[start:start + 7]
        config = np.concatenate([pose[:3], pose[4:7], pose[3:4], q])
        rates = self.data.qvel[self.loaded.selected]
        return config, np.linalg.solve(Mapping(linear_world_angular_body, config, nv=len(rates)).T, rates)
