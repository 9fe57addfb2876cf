// A planar double pendulum (scene `double-pendulum`: a pin on particle 0, a rod between 0 and 1),
// in the two absolute rod angles (from the downward vertical toward +x), classical RK4: fourth order.
//
// The constraint forces come from the accelerations: the rod's force on the outer particle is
// m2 a2 - m2 g, the pin's force on the inner one is m1 a1 - m1 g minus the rod's force on it.
// Each is written as the force on the constraint's first particle (Pin: `particle`, Rod: `a`).
#include <array>

#include "xval_protocol.hpp"

using xval::Vec3;

namespace {

using State = std::array<double, 4>;  // theta1, theta2 (rad), omega1, omega2 (rad/s)

struct DoublePendulum {
    double m1, m2, l1, l2, g;
    Vec3 anchor;

    // theta1'', theta2'' (rad/s^2)
    std::array<double, 2> angular_accelerations(const State& s) const {
        double t1 = s[0], t2 = s[1], w1 = s[2], w2 = s[3], d = t1 - t2;
        double den = 2 * m1 + m2 - m2 * std::cos(2 * d);
        double a1 = (-g * (2 * m1 + m2) * std::sin(t1) - m2 * g * std::sin(t1 - 2 * t2) -
                     2 * std::sin(d) * m2 * (w2 * w2 * l2 + w1 * w1 * l1 * std::cos(d))) / (l1 * den);
        double a2 = (2 * std::sin(d) * (w1 * w1 * l1 * (m1 + m2) + g * (m1 + m2) * std::cos(t1) +
                                        w2 * w2 * l2 * m2 * std::cos(d))) / (l2 * den);
        return {a1, a2};
    }
    State derivative(const State& s) const {
        auto a = angular_accelerations(s);
        return {s[2], s[3], a[0], a[1]};
    }
    static Vec3 arm(double t) { return {std::sin(t), 0, -std::cos(t)}; }      // unit vector of a rod
    static Vec3 turn(double t) { return {std::cos(t), 0, std::sin(t)}; }      // d arm / d theta
    void state(const State& s, std::vector<Vec3>& q, std::vector<Vec3>& v, std::size_t inner, std::size_t outer) const {
        q[inner] = anchor + l1 * arm(s[0]);
        q[outer] = q[inner] + l2 * arm(s[1]);
        v[inner] = l1 * s[2] * turn(s[0]);
        v[outer] = v[inner] + l2 * s[3] * turn(s[1]);
    }
    // Forces (N) on the inner particle by the pin, and on the outer particle by the rod.
    std::pair<Vec3, Vec3> forces(const State& s) const {
        auto a = angular_accelerations(s);
        Vec3 acc1 = l1 * (a[0] * turn(s[0]) - s[2] * s[2] * arm(s[0]));
        Vec3 acc2 = acc1 + l2 * (a[1] * turn(s[1]) - s[3] * s[3] * arm(s[1]));
        Vec3 gravity{0, 0, -g};
        Vec3 rod_on_outer = m2 * (acc2 - gravity);
        Vec3 pin_on_inner = m1 * (acc1 - gravity) + rod_on_outer;  // minus the rod's force on the inner one
        return {pin_on_inner, rod_on_outer};
    }
};

void solve(const xval::Problem& p, xval::Output& out) {
    const std::string expected = "expects two particles, a pin on one and a rod between them, gravity along -z; "
                                 "scene '" + p.scene_name + "' is not that";
    if (p.particles.size() != 2 || p.constraints.size() != 2) throw xval::Unsupported(expected);
    int pin = p.constraints[0].kind == "pin" ? 0 : 1, rod = 1 - pin;
    const xval::Constraint &P = p.constraints[pin], &R = p.constraints[rod];
    if (P.kind != "pin" || R.kind != "rod" || p.gravity.x != 0 || p.gravity.y != 0) throw xval::Unsupported(expected);
    std::size_t inner = static_cast<std::size_t>(P.particle), outer = 1 - inner;
    const DoublePendulum model{p.particles[inner].mass, p.particles[outer].mass, P.length, R.length, -p.gravity.z,
                               P.anchor};
    std::vector<Vec3> q = p.positions(), v = p.velocities(), f(2);
    Vec3 d1 = q[inner] - P.anchor, d2 = q[outer] - q[inner];
    State s{std::atan2(d1.x, -d1.z), std::atan2(d2.x, -d2.z), 0, 0};
    s[2] = xval::dot(v[inner], DoublePendulum::turn(s[0])) / P.length;
    s[3] = xval::dot(v[outer] - v[inner], DoublePendulum::turn(s[1])) / R.length;
    // Rod's force on its first particle: on the outer one if it is `a`, else the reaction on the inner one.
    auto record = [&](long step) {
        auto [pin_force, rod_on_outer] = model.forces(s);
        f[pin] = pin_force;
        f[rod] = static_cast<std::size_t>(R.a) == outer ? rod_on_outer : -rod_on_outer;
        out.row(step, q, v, &f);
    };
    record(0);  // the initial state, written as given
    const double h = p.dt;
    out.clock.start();
    for (long step = 1; step <= p.steps; ++step) {
        State k1 = model.derivative(s), t;
        for (int i = 0; i < 4; ++i) t[i] = s[i] + 0.5 * h * k1[i];
        State k2 = model.derivative(t);
        for (int i = 0; i < 4; ++i) t[i] = s[i] + 0.5 * h * k2[i];
        State k3 = model.derivative(t);
        for (int i = 0; i < 4; ++i) t[i] = s[i] + h * k3[i];
        State k4 = model.derivative(t);
        for (int i = 0; i < 4; ++i) s[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
        if (out.wants(step)) {
            model.state(s, q, v, inner, outer);
            record(step);
        }
    }
    out.clock.stop();
}

}  // namespace

int main() { return xval::run(solve, /*forces=*/true, "double_pendulum 1.0", "double_pendulum"); }
