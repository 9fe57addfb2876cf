// A bead on a wire (a particle on a pin: the circle of a planar scene, the sphere of a 3-D one).
//
// Cartesian coordinates, with the constraint force from the acceleration-level
// constraint (Baraff-Witkin for one pin): for d = x - anchor,
//     m x'' = m g + lambda d,   lambda = -m (d.g + |x'|^2) / |d|^2,
// so that d.x'' + |x'|^2 = 0 and |d| stays at the pin's length. The force the
// pin exerts on the bead, lambda d, is written as f0.
// Option `method`: "rk4" (default; fourth order) or "euler" (symplectic Euler; first order, drifts).
#include "xval_protocol.hpp"

using xval::Vec3;

namespace {

struct Bead {
    double mass;
    Vec3 anchor, gravity;
    Vec3 force(Vec3 x, Vec3 v) const {  // N, the pin's force on the bead
        Vec3 d = x - anchor;
        double lambda = -mass * (xval::dot(d, gravity) + xval::dot(v, v)) / xval::dot(d, d);
        return lambda * d;
    }
    Vec3 acceleration(Vec3 x, Vec3 v) const { return gravity + force(x, v) / mass; }
};

void solve(const xval::Problem& problem, xval::Output& out) {
    if (problem.particles.size() != 1 || problem.constraints.size() != 1 || problem.constraints[0].kind != "pin")
        throw xval::Unsupported("expects one particle on one pin; scene '" + problem.scene_name + "' is not that");
    const std::string method = problem.option("method", std::string("rk4"));
    if (method != "rk4" && method != "euler") throw xval::Error("options.method must be \"rk4\" or \"euler\"");
    const Bead bead{problem.particles[0].mass, problem.constraints[0].anchor, problem.gravity};
    const double h = problem.dt;
    std::vector<Vec3> q = problem.positions(), v = problem.velocities(), f{bead.force(q[0], v[0])};
    out.row(0, q, v, &f);
    out.clock.start();
    for (long step = 1; step <= problem.steps; ++step) {
        Vec3 x = q[0], u = v[0];
        if (method == "euler") {
            u += h * bead.acceleration(x, u);
            x += h * u;
        } else {
            Vec3 k1x = u, k1v = bead.acceleration(x, u);
            Vec3 k2x = u + 0.5 * h * k1v, k2v = bead.acceleration(x + 0.5 * h * k1x, k2x);
            Vec3 k3x = u + 0.5 * h * k2v, k3v = bead.acceleration(x + 0.5 * h * k2x, k3x);
            Vec3 k4x = u + h * k3v, k4v = bead.acceleration(x + h * k3x, k4x);
            x += (h / 6) * (k1x + 2 * k2x + 2 * k3x + k4x);
            u += (h / 6) * (k1v + 2 * k2v + 2 * k3v + k4v);
        }
        q[0] = x;
        v[0] = u;
        if (out.wants(step)) {
            f[0] = bead.force(x, u);
            out.row(step, q, v, &f);
        }
    }
    out.clock.stop();
}

}  // namespace

int main() { return xval::run(solve, /*forces=*/true, "bead 1.0", "bead"); }
