"""Reference models of the mechanisms: a slider-pendulum, a four-bar linkage, a bead on an ellipse.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/reference/mechanisms.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engines.errors import Unsupported
from engines.scene.scene import Ellipse, Line, Pin, Rod, Scene


def _xz(vector) -> np.ndarray:
    v = np.asarray(vector, dtype=float)
    return v[..., [0, 2]]


def _embed(xz: np.ndarray) -> np.ndarray:
    """(..., 2) (x, z) → (..., 3) with y = 0."""
    out = np.zeros(xz.shape[:-1] + (3,))
    out[..., 0], out[..., 2] = xz[..., 0], xz[..., 1]
    return out


def empty_samples(scene: Scene, n_samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed positions, velocities (n_samples, P, 3) and constraint forces (n_samples, C, 3)."""
    positions = np.zeros((n_samples, len(scene.particles), 3))
    return positions, np.zeros_like(positions), np.zeros((n_samples, len(scene.constraints), 3))


# -- slider-pendulum ------------------------------------------------------------------


@dataclass(frozen=True)
class SliderPendulum:
    """Slider ``slider`` (mass M) on a line through ``point`` along ``unit``; bob ``bob`` (mass m) on a rod of ``length``.

    point, unit, gravity : (2,) in (x, z). State [s, θ, ṡ, θ̇] in m, rad, m/s, rad/s.
    """

    slider: int
    bob: int
    line_index: int
    rod_index: int
    rod_first_is_bob: bool
    point: np.ndarray
    unit: np.ndarray
    length: float
    slider_mass: float
    bob_mass: float
    gravity: np.ndarray

    def initial_state(self, scene: Scene) -> np.ndarray:
        q, v = _xz(scene.initial_positions), _xz(scene.initial_velocities)
        s = float((q[self.slider] - self.point) @ self.unit)
        sd = float(v[self.slider] @ self.unit)
        d = q[self.bob] - q[self.slider]
        dv = v[self.bob] - v[self.slider]
        theta = math.atan2(d[0], -d[1])
        theta_dot = float(d[0] * dv[1] - d[1] * dv[0]) / self.length**2
        return np.array([s, theta, sd, theta_dot])

    def accelerations(self, theta: float, theta_dot: float) -> tuple[float, float]:
        """(s̈ m/s², θ̈ rad/s²) from the 2×2 mass matrix (Cramer's rule; it is positive definite)."""
        M, m, l = self.slider_mass, self.bob_mass, self.length
        ux, uz = self.unit
        gx, gz = self.gravity
        c, s = math.cos(theta), math.sin(theta)
        ue = ux * c + uz * s
        un = ux * s - uz * c
        m11, m12, m22 = M + m, m * l * ue, m * l * l
        r1 = (M + m) * (gx * ux + gz * uz) + m * l * theta_dot * theta_dot * un
        r2 = m * l * (gx * c + gz * s)
        det = m11 * m22 - m12 * m12
        return (r1 * m22 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        s_ddot, theta_ddot = self.accelerations(y[1], y[3])
        return np.array([y[2], y[3], s_ddot, theta_ddot])

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s, theta, sd, td = states.T
        acc = np.array([self.accelerations(a, b) for a, b in zip(theta, td)]).reshape(-1, 2)
        sdd, tdd = acc[:, 0], acc[:, 1]
        l, u = self.length, self.unit
        e = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        n = np.stack([np.sin(theta), -np.cos(theta)], axis=-1)
        q_s = self.point + s[:, None] * u
        q_p = q_s + l * n
        v_s = sd[:, None] * u
        v_p = v_s + l * td[:, None] * e
        a_s = sdd[:, None] * u
        a_p = a_s + l * tdd[:, None] * e - l * (td**2)[:, None] * n
        on_bob = self.bob_mass * (a_p - self.gravity)  # the rod's force on the bob
        on_line = self.slider_mass * (a_s - self.gravity) + on_bob  # the rail's force on the slider
        positions, velocities, forces = empty_samples(scene, len(states))
        positions[:, self.slider], positions[:, self.bob] = _embed(q_s), _embed(q_p)
        velocities[:, self.slider], velocities[:, self.bob] = _embed(v_s), _embed(v_p)
        forces[:, self.line_index] = _embed(on_line)
        forces[:, self.rod_index] = _embed(on_bob if self.rod_first_is_bob else -on_bob)
        return positions, velocities, forces


def slider_pendulum(scene: Scene) -> SliderPendulum | None:
    """The slider-pendulum reading of ``scene``, or None when it is not one (a Line and a Rod on two particles)."""
    kinds = sorted(type(c).__name__ for c in scene.constraints)
    if len(scene.particles) != 2 or kinds != ["Line", "Rod"]:
        return None
    line_index = next(k for k, c in enumerate(scene.constraints) if isinstance(c, Line))
    rod_index = 1 - line_index
    line, rod = scene.constraints[line_index], scene.constraints[rod_index]
    if {rod.a, rod.b} != {0, 1}:
        return None
    bob = 1 - line.particle
    unit = _xz(line.unit)
    return SliderPendulum(
        slider=line.particle,
        bob=bob,
        line_index=line_index,
        rod_index=rod_index,
        rod_first_is_bob=rod.a == bob,
        point=_xz(line.point),
        unit=unit / np.linalg.norm(unit),
        length=rod.length,
        slider_mass=scene.particles[line.particle].mass,
        bob_mass=scene.particles[bob].mass,
        gravity=_xz(scene.gravity),
    )


# -- four-bar linkage -------------------------------------------------------------------


def is_grashof_crank(a: float, b: float, c: float, d: float) -> bool:
    """True when a crank of length a turns fully: a is the shortest link and a + max(b, c, d) < the other two."""
    others = sorted((b, c, d))
    return a < others[0] and a + others[2] < others[0] + others[1]


def _cross(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    return u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]


@dataclass(frozen=True)
class Linkage:
    """A four-bar's geometry: tip ``first`` (mass m0) pinned by constraint ``first_pin`` at a from
    ``first_pivot``, tip ``second`` (mass m1) pinned by ``second_pin`` at c from ``second_pivot``, the
    coupler (constraint ``rod_index``, b long) between the tips. Vectors are (x, z) m; gravity m/s².
    """

    first: int
    second: int
    first_pin: int
    second_pin: int
    rod_index: int
    rod_first_is_first: bool
    first_pivot: np.ndarray
    second_pivot: np.ndarray
    a: float
    b: float
    c: float
    m0: float
    m1: float
    gravity: np.ndarray

    @classmethod
    def read(cls, scene: Scene, first_pin: int, second_pin: int, rod_index: int, **extra):
        """The linkage of ``scene`` with these constraints, and the fields of a subclass (``extra``)."""
        first, second, rod = (scene.constraints[k] for k in (first_pin, second_pin, rod_index))
        return cls(
            first=first.particle, second=second.particle, first_pin=first_pin, second_pin=second_pin,
            rod_index=rod_index, rod_first_is_first=rod.a == first.particle,
            first_pivot=_xz(first.anchor), second_pivot=_xz(second.anchor),
            a=first.length, b=rod.length, c=second.length,
            m0=scene.particles[first.particle].mass, m1=scene.particles[second.particle].mass,
            gravity=_xz(scene.gravity), **extra,
        )


@dataclass(frozen=True)
class FourBar(Linkage):
    """A Grashof crank's linkage in its crank angle: ``first`` is the crank tip, ``second`` the rocker
    tip; ``branch`` ±1 the side of the line from the crank tip to the rocker pivot the rocker tip lies
    on (+1 left). State [φ, φ̇] rad, rad/s.
    """

    branch: float

    def _rates(self, phi: float) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Crank and rocker tips (2,) m, k = dψ/dφ and h (ψ̈ = k φ̈ + h φ̇²) at crank angle φ."""
        x0, z0, x1, z1, k, h = self._scalar_rates(phi)
        return np.array([x0, z0]), np.array([x1, z1]), k, h

    def _scalar_rates(self, phi: float) -> tuple[float, float, float, float, float, float]:
        """(x0, z0, x1, z1, k, h): the closure and the rates in scalars (the right-hand side is called
        ~10⁴ times per solve, and numpy's per-call cost on 2-vectors is ~10× the arithmetic here)."""
        a, b, c = self.a, self.b, self.c
        ax, az = self.first_pivot
        bx, bz = self.second_pivot
        s, co = math.sin(phi), math.cos(phi)
        x0, z0 = ax + a * s, az - a * co
        dx, dz = bx - x0, bz - z0
        delta = math.hypot(dx, dz)
        ux, uz = dx / delta, dz / delta
        along = (b * b - c * c + delta * delta) / (2.0 * delta)
        across = self.branch * math.sqrt(max(b * b - along * along, 0.0))
        x1, z1 = x0 + along * ux - across * uz, z0 + along * uz + across * ux
        upx, upz = s, -co  # u_φ = (p0 − A) / a
        epx, epz = co, s  # e_φ
        uqx, uqz = (x1 - bx) / c, (z1 - bz) / c  # u_ψ
        eqx, eqz = -uqz, uqx  # e_ψ
        rx, rz = x1 - x0, z1 - z0
        denominator = c * (rx * eqx + rz * eqz)
        k = a * (rx * epx + rz * epz) / denominator
        relx, relz = c * k * eqx - a * epx, c * k * eqz - a * epz
        h = (c * k * k * (rx * uqx + rz * uqz) - a * (rx * upx + rz * upz) - (relx * relx + relz * relz)) / denominator
        return x0, z0, x1, z1, k, h

    def angular_acceleration(self, phi: float, phi_dot: float) -> float:
        """φ̈ (rad/s²) by d'Alembert's principle along the crank coordinate."""
        x0, z0, x1, z1, k, h = self._scalar_rates(phi)
        a, c, m0, m1 = self.a, self.c, self.m0, self.m1
        gx, gz = self.gravity
        g_phi = gx * math.cos(phi) + gz * math.sin(phi)  # g·e_φ
        g_psi = (-gx * (z1 - self.second_pivot[1]) + gz * (x1 - self.second_pivot[0])) / c  # g·e_ψ
        force = m0 * a * g_phi + m1 * c * k * g_psi - m1 * c * c * k * h * phi_dot * phi_dot
        return force / (m0 * a * a + m1 * c * c * k * k)

    def initial_state(self, scene: Scene) -> np.ndarray:
        q, v = _xz(scene.initial_positions), _xz(scene.initial_velocities)
        d = q[self.first] - self.first_pivot
        phi = math.atan2(d[0], -d[1])
        phi_dot = float(d[0] * v[self.first][1] - d[1] * v[self.first][0]) / self.a**2
        return np.array([phi, phi_dot])

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], self.angular_acceleration(y[0], y[1])])

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        positions, velocities, forces = empty_samples(scene, len(states))
        g = self.gravity
        for i, (phi, phi_dot) in enumerate(states):
            p0, p1, k, h = self._rates(phi)
            phi_ddot = self.angular_acceleration(phi, phi_dot)
            u_phi = (p0 - self.first_pivot) / self.a
            u_psi = (p1 - self.second_pivot) / self.c
            e_phi, e_psi = np.array([-u_phi[1], u_phi[0]]), np.array([-u_psi[1], u_psi[0]])
            psi_dot, psi_ddot = k * phi_dot, k * phi_ddot + h * phi_dot**2
            v0, v1 = self.a * phi_dot * e_phi, self.c * psi_dot * e_psi
            a0 = self.a * (phi_ddot * e_phi - phi_dot**2 * u_phi)
            a1 = self.c * (psi_ddot * e_psi - psi_dot**2 * u_psi)
            w = (p0 - p1) / self.b  # the rod pulls the crank tip along −w, the rocker tip along +w
            system = np.zeros((4, 3))
            system[:2, 0], system[2:, 1] = u_phi, u_psi
            system[:2, 2], system[2:, 2] = w, -w
            rhs = np.concatenate([self.m0 * (a0 - g), self.m1 * (a1 - g)])
            lam = np.linalg.lstsq(system, rhs, rcond=None)[0]
            positions[i, self.first], positions[i, self.second] = _embed(p0), _embed(p1)
            velocities[i, self.first], velocities[i, self.second] = _embed(v0), _embed(v1)
            forces[i, self.first_pin] = _embed(lam[0] * u_phi)
            forces[i, self.second_pin] = _embed(lam[1] * u_psi)
            forces[i, self.rod_index] = _embed(lam[2] * w if self.rod_first_is_first else -lam[2] * w)
        return positions, velocities, forces


@dataclass(frozen=True)
class LoopFourBar(Linkage):
    """The four-bar in maximal coordinates, for any linkage that closes, Grashof or not: state
    [p0, p1, v0, v1] (x, z) m and m/s of the tips ``first`` and ``second`` (masses m0, m1), pinned at a
    from ``first_pivot`` and c from ``second_pivot``, a coupler b between them.

    Accelerations from Newton's law with the three distance constraints' forces (Lagrange multipliers):
    J M⁻¹ Jᵀ λ = −J̇v − J M⁻¹ f − 2ω Ċ − ω² C, with C the constraints in the form ½(‖·‖² − l²). The last
    two terms vanish on the constraint manifold, where the exact motion lies, so they change no exact
    solution; they make the manifold attract, so the integrator's drift off it stays at its tolerance.
    J has full rank except where all three links are collinear (a change point), so the rockers' dead
    points, where the crank angle is singular, are ordinary points here.
    """

    #: 1/s: the stabilization's rate ω (four_bar sets the linkage's pendulum frequency).
    omega: float

    def initial_state(self, scene: Scene) -> np.ndarray:
        q, v = _xz(scene.initial_positions), _xz(scene.initial_velocities)
        return np.concatenate([q[self.first], q[self.second], v[self.first], v[self.second]])

    def _forces(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(accelerations (4,) m/s², λ (3,), the constraint gradients r0 = p0 − A, w = p1 − p0, r1 = p1 − B)."""
        p0, p1, v0, v1 = y[0:2], y[2:4], y[4:6], y[6:8]
        r0, w, r1 = p0 - self.first_pivot, p1 - p0, p1 - self.second_pivot
        jac = np.zeros((3, 4))
        jac[0, 0:2], jac[1, 0:2], jac[1, 2:4], jac[2, 2:4] = r0, -w, w, r1
        inverse_mass = np.array([1 / self.m0, 1 / self.m0, 1 / self.m1, 1 / self.m1])
        g = np.concatenate([self.gravity, self.gravity])  # f / m
        dw = v1 - v0
        constraint = 0.5 * np.array([r0 @ r0 - self.a**2, w @ w - self.b**2, r1 @ r1 - self.c**2])
        rate = jac @ y[4:8]
        target = -np.array([v0 @ v0, dw @ dw, v1 @ v1]) - jac @ g - 2 * self.omega * rate - self.omega**2 * constraint
        lam = np.linalg.solve((jac * inverse_mass) @ jac.T, target)
        return g + inverse_mass * (jac.T @ lam), lam, r0, w, r1

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[4:8], self._forces(y)[0]])

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        positions, velocities, forces = empty_samples(scene, len(states))
        for i, y in enumerate(states):
            _, lam, r0, w, r1 = self._forces(np.asarray(y, dtype=float))
            positions[i, self.first], positions[i, self.second] = _embed(y[0:2]), _embed(y[2:4])
            velocities[i, self.first], velocities[i, self.second] = _embed(y[4:6]), _embed(y[6:8])
            # Each constraint's force on its (first) particle: λ times its gradient there.
            forces[i, self.first_pin] = _embed(lam[0] * r0)
            forces[i, self.second_pin] = _embed(lam[2] * r1)
            forces[i, self.rod_index] = _embed(-lam[1] * w if self.rod_first_is_first else lam[1] * w)
        return positions, velocities, forces


def four_bar(scene: Scene) -> FourBar | LoopFourBar | None:
    """The four-bar reading of ``scene`` (two Pins on different particles and a Rod between them), or None.

    A Grashof crank's linkage is integrated in its crank angle (FourBar, one coordinate); any other
    (a triple-rocker, a double-rocker) in maximal coordinates (LoopFourBar).
    """
    if len(scene.particles) != 2 or len(scene.constraints) != 3:
        return None
    pins = [k for k, c in enumerate(scene.constraints) if isinstance(c, Pin)]
    rods = [k for k, c in enumerate(scene.constraints) if isinstance(c, Rod)]
    if len(pins) != 2 or len(rods) != 1:
        return None
    first, second = (scene.constraints[k] for k in pins)
    rod = scene.constraints[rods[0]]
    if first.particle == second.particle or {rod.a, rod.b} != {first.particle, second.particle}:
        return None
    ground = float(np.linalg.norm(_xz(first.anchor) - _xz(second.anchor)))
    for crank_pin, rocker_pin in ((pins[0], pins[1]), (pins[1], pins[0])):
        crank, rocker = scene.constraints[crank_pin], scene.constraints[rocker_pin]
        if not is_grashof_crank(crank.length, rod.length, rocker.length, ground):
            continue
        q = _xz(scene.initial_positions)
        p0, p1 = q[crank.particle], q[rocker.particle]
        side = float(_cross(_xz(rocker.anchor) - p0, p1 - p0))
        return FourBar.read(scene, crank_pin, rocker_pin, rods[0], branch=1.0 if side >= 0.0 else -1.0)
    # No Grashof crank: the crank angle meets a dead point, so the loop is integrated in maximal coordinates.
    length = first.length + rod.length + second.length
    g = float(np.linalg.norm(scene.gravity))
    # The stabilization's rate: the pendulum frequency √(g/L) of the linkage (1/s without gravity).
    return LoopFourBar.read(scene, pins[0], pins[1], rods[0], omega=math.sqrt(g / length) if g > 0 else 1.0)


# -- bead on an ellipse ---------------------------------------------------------------------


@dataclass(frozen=True)
class EllipseBead:
    """A bead of ``mass`` on the ellipse about ``centre`` (x, z) with semi-axes ``semi`` (a along x, b along z).

    State [u, u̇]: the wire parameter, position c + (a sin u, −b cos u) (u = θ on a circle).
    """

    centre: np.ndarray
    semi: np.ndarray
    mass: float
    gravity: np.ndarray

    def initial_state(self, scene: Scene) -> np.ndarray:
        d = _xz(scene.initial_positions[0]) - self.centre
        v = _xz(scene.initial_velocities[0])
        a, b = self.semi
        u = math.atan2(d[0] / a, -d[1] / b)
        t = np.array([a * math.cos(u), b * math.sin(u)])
        return np.array([u, float(v @ t) / float(t @ t)])

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        u, u_dot = y
        a, b = self.semi
        s, c = math.sin(u), math.cos(u)
        tx, tz = a * c, b * s
        # t·(p − c) = (a² − b²) sin u cos u; zero on a circle.
        u_ddot = (tx * self.gravity[0] + tz * self.gravity[1] + u_dot * u_dot * (a * a - b * b) * s * c) / (
            tx * tx + tz * tz
        )
        return np.array([u_dot, u_ddot])

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u, u_dot = states.T
        u_ddot = np.array([self.rhs(0.0, y)[1] for y in states])
        a, b = self.semi
        s, c = np.sin(u), np.cos(u)
        offset = np.stack([a * s, -b * c], axis=-1)
        t = np.stack([a * c, b * s], axis=-1)
        q = self.centre + offset
        v = u_dot[:, None] * t
        acc = u_ddot[:, None] * t - (u_dot**2)[:, None] * offset
        forces = self.mass * (acc - self.gravity)
        return _embed(q)[:, None], _embed(v)[:, None], _embed(forces)[:, None]


def ellipse_bead(scene: Scene) -> EllipseBead | None:
    """The ellipse-bead reading of ``scene`` (one particle, one Ellipse), or None."""
    if len(scene.particles) != 1 or len(scene.constraints) != 1 or not isinstance(scene.constraints[0], Ellipse):
        return None
    wire = scene.constraints[0]
    return EllipseBead(_xz(wire.centre), np.array([wire.semi_x, wire.semi_z]), scene.particles[0].mass,
                       _xz(scene.gravity))


# -- dispatch ---------------------------------------------------------------------------------


Mechanism = SliderPendulum | FourBar | LoopFourBar | EllipseBead


def mechanism_model(scene: Scene) -> Mechanism | None:
    """The reduced model of a planar mechanism scene, None when ``scene`` is a tree of Pins and Rods
    (the chain / spherical forms take it), Unsupported when it uses a mechanism kind in a way none fits."""
    if scene.is_planar:
        for reader in (slider_pendulum, four_bar, ellipse_bead):
            model = reader(scene)
            if model is not None:
                return model
    uses_new_kind = any(isinstance(c, (Line, Ellipse)) for c in scene.constraints)
    if uses_new_kind:
        raise Unsupported(
            f"the reference expresses a line only as a planar slider carrying one pendulum, and an ellipse "
            f"only as a planar bead on it; {scene.name!r} is neither"
        )
    return None
