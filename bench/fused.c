/* Hand-fused yardsticks in C: the same arithmetic, in the same order, as bench/fused.py
 * (and so as ours' compiled loop) for the double pendulum; the RK4 step twice, with the 2×2
 * solve by Cholesky and in closed form. Built by bench/bench_ours.py with
 * gcc -O3 -ffp-contract=off (no fused multiply-adds, so the results match ours to round-off).
 * q, v: the 2×2 positions and velocities (row-major), stepped n_steps times in place. */
#include <math.h>

typedef struct { double w0, w1, fx0, fy0, fx1, fy1, ax, ay, L1sq, L2sq, b00w, b10w, b11w; } System;

static void setup(System *s, const double *masses, const double *gravity, const double *anchor, const double *lengths) {
    s->w0 = 1.0 / masses[0];
    s->w1 = 1.0 / masses[1];
    s->fx0 = masses[0] * gravity[0]; s->fy0 = masses[0] * gravity[1];
    s->fx1 = masses[1] * gravity[0]; s->fy1 = masses[1] * gravity[1];
    s->ax = anchor[0]; s->ay = anchor[1];
    s->L1sq = lengths[0] * lengths[0]; s->L2sq = lengths[1] * lengths[1];
    s->b00w = 0.0 + s->w0; s->b10w = 0.0 + s->w0; s->b11w = (0.0 + s->w0) + s->w1;
}

/* closed: 0 solves J W Jᵀ λ = r by Cholesky (ours' banded solve), 1 in closed form (Cramer's rule, as
 * ours' kernels specialised for at most 3 constraints do). */
static inline void accel(const System *s, const double *x, const double *u, double ks, double kd, double *a,
                         int closed) {
    double d0x = x[0] - s->ax, d0y = x[1] - s->ay, d1x = x[0] - x[2], d1y = x[1] - x[3];
    double v0x = u[0], v0y = u[1], v1x = u[0] - u[2], v1y = u[1] - u[3];
    double jwf0 = d0x * (s->w0 * s->fx0) + d0y * (s->w0 * s->fy0);
    double jwf1 = d1x * (s->w0 * s->fx0 - s->w1 * s->fx1) + d1y * (s->w0 * s->fy0 - s->w1 * s->fy1);
    double c0 = 0.5 * ((d0x * d0x + d0y * d0y) - s->L1sq);
    double c1 = 0.5 * ((d1x * d1x + d1y * d1y) - s->L2sq);
    double cd0 = d0x * v0x + d0y * v0y, cd1 = d1x * v1x + d1y * v1y;
    double r0 = -(v0x * v0x + v0y * v0y) - jwf0 - ks * c0 - kd * cd0;
    double r1 = -(v1x * v1x + v1y * v1y) - jwf1 - ks * c1 - kd * cd1;
    double a00 = s->b00w * (d0x * d0x + d0y * d0y);
    double a10 = s->b10w * (d1x * d0x + d1y * d0y);
    double a11 = s->b11w * (d1x * d1x + d1y * d1y);
    double lam0, lam1;
    if (closed) {
        double det = a00 * a11 - a10 * a10;
        lam0 = (a11 * r0 - a10 * r1) / det;
        lam1 = (a00 * r1 - a10 * r0) / det;
    } else {
        double l00 = sqrt(a00), l10 = a10 / l00, l11 = sqrt(a11 - l10 * l10);
        double z0 = r0 / l00, z1 = (r1 - l10 * z0) / l11;
        lam1 = z1 / l11;
        lam0 = (z0 - l10 * lam1) / l00;
    }
    a[0] = s->w0 * s->fx0 + s->w0 * lam0 * d0x + s->w0 * lam1 * d1x;
    a[1] = s->w0 * s->fy0 + s->w0 * lam0 * d0y + s->w0 * lam1 * d1y;
    a[2] = s->w1 * s->fx1 - s->w1 * lam1 * d1x;
    a[3] = s->w1 * s->fy1 - s->w1 * lam1 * d1y;
}

static inline void rk4(double *q, double *v, const double *masses, const double *gravity, const double *anchor,
                       const double *lengths, double ks, double kd, double h, long n_steps, int closed) {
    System s;
    setup(&s, masses, gravity, anchor, lengths);
    double x[4] = {q[0], q[1], q[2], q[3]}, u[4] = {v[0], v[1], v[2], v[3]};
    double hh = 0.5 * h, b1 = h * (1.0 / 6.0), b2 = h * (1.0 / 3.0);
    for (long n = 0; n < n_steps; n++) {
        double k1[4], k2[4], k3[4], k4[4], q2[4], v2[4], q3[4], v3[4], q4[4], v4[4];
        accel(&s, x, u, ks, kd, k1, closed);
        for (int i = 0; i < 4; i++) { q2[i] = x[i] + hh * u[i]; v2[i] = u[i] + hh * k1[i]; }
        accel(&s, q2, v2, ks, kd, k2, closed);
        for (int i = 0; i < 4; i++) { q3[i] = x[i] + hh * v2[i]; v3[i] = u[i] + hh * k2[i]; }
        accel(&s, q3, v3, ks, kd, k3, closed);
        for (int i = 0; i < 4; i++) { q4[i] = x[i] + h * v3[i]; v4[i] = u[i] + h * k3[i]; }
        accel(&s, q4, v4, ks, kd, k4, closed);
        for (int i = 0; i < 4; i++) {
            x[i] = x[i] + b1 * u[i] + b2 * v2[i] + b2 * v3[i] + b1 * v4[i];
            u[i] = u[i] + b1 * k1[i] + b2 * k2[i] + b2 * k3[i] + b1 * k4[i];
        }
    }
    for (int i = 0; i < 4; i++) { q[i] = x[i]; v[i] = u[i]; }
}

/* Baumgarte + RK4, λ by Cholesky: ours' arithmetic for any system, written out for this one. */
void double_pendulum_rk4(double *q, double *v, const double *masses, const double *gravity, const double *anchor,
                         const double *lengths, double ks, double kd, double h, long n_steps) {
    rk4(q, v, masses, gravity, anchor, lengths, ks, kd, h, n_steps, 0);
}

/* Baumgarte + RK4, λ in closed form: what the machine can do for this system. */
void double_pendulum_rk4_closed(double *q, double *v, const double *masses, const double *gravity,
                                const double *anchor, const double *lengths, double ks, double kd, double h,
                                long n_steps) {
    rk4(q, v, masses, gravity, anchor, lengths, ks, kd, h, n_steps, 1);
}

long double_pendulum_rattle(double *q, double *v, const double *masses, const double *gravity, const double *anchor,
                            const double *lengths, double tolerance, long max_iterations, double h, long n_steps) {
    System s;
    setup(&s, masses, gravity, anchor, lengths);
    double x0 = q[0], y0 = q[1], x1 = q[2], y1 = q[3], u0 = v[0], w0 = v[1], u1 = v[2], w1 = v[3];
    double hh2 = 0.5 * h * h;
    for (long step = 0; step < n_steps; step++) {
        double e0x = x0 - s.ax, e0y = y0 - s.ay, e1x = x0 - x1, e1y = y0 - y1;
        double l00 = sqrt(s.b00w * (e0x * e0x + e0y * e0y));
        double l10 = s.b10w * (e1x * e0x + e1y * e0y) / l00;
        double l11 = sqrt(s.b11w * (e1x * e1x + e1y * e1y) - l10 * l10);
        double n0x = x0 + h * u0 + hh2 * s.w0 * s.fx0, n0y = y0 + h * w0 + hh2 * s.w0 * s.fy0;
        double n1x = x1 + h * u1 + hh2 * s.w1 * s.fx1, n1y = y1 + h * w1 + hh2 * s.w1 * s.fy1;
        double Lam0 = 0.0, Lam1 = 0.0;
        int converged = 0;
        for (long it = 0; it <= max_iterations; it++) {
            double d0x = n0x - s.ax, d0y = n0y - s.ay, d1x = n0x - n1x, d1y = n0y - n1y;
            double c0 = 0.5 * ((d0x * d0x + d0y * d0y) - s.L1sq), c1 = 0.5 * ((d1x * d1x + d1y * d1y) - s.L2sq);
            double worst = fmax(fmax(0.0, fabs(c0) / s.L1sq), fabs(c1) / s.L2sq);
            if (worst <= tolerance) { converged = 1; break; }
            double z0 = -c0 / l00, z1 = (-c1 - l10 * z0) / l11;
            double g1 = z1 / l11, g0 = (z0 - l10 * g1) / l00;
            Lam0 += g0; Lam1 += g1;
            n0x += s.w0 * g0 * e0x + s.w0 * g1 * e1x;
            n0y += s.w0 * g0 * e0y + s.w0 * g1 * e1y;
            n1x -= s.w1 * g1 * e1x;
            n1y -= s.w1 * g1 * e1y;
        }
        if (!converged) return step;
        double ih = 1.0 / h;
        u0 += h * s.w0 * s.fx0 + ih * s.w0 * Lam0 * e0x + ih * s.w0 * Lam1 * e1x;
        w0 += h * s.w0 * s.fy0 + ih * s.w0 * Lam0 * e0y + ih * s.w0 * Lam1 * e1y;
        u1 += h * s.w1 * s.fx1 - ih * s.w1 * Lam1 * e1x;
        w1 += h * s.w1 * s.fy1 - ih * s.w1 * Lam1 * e1y;
        x0 = n0x; y0 = n0y; x1 = n1x; y1 = n1y;
        double d0x = x0 - s.ax, d0y = y0 - s.ay, d1x = x0 - x1, d1y = y0 - y1;
        double m00 = sqrt(s.b00w * (d0x * d0x + d0y * d0y));
        double m10 = s.b10w * (d1x * d0x + d1y * d0y) / m00;
        double m11 = sqrt(s.b11w * (d1x * d1x + d1y * d1y) - m10 * m10);
        double z0 = (d0x * u0 + d0y * w0) / m00;
        double z1 = ((d1x * (u0 - u1) + d1y * (w0 - w1)) - m10 * z0) / m11;
        double mu1 = z1 / m11, mu0 = (z0 - m10 * mu1) / m00;
        u0 -= s.w0 * mu0 * d0x + s.w0 * mu1 * d1x;
        w0 -= s.w0 * mu0 * d0y + s.w0 * mu1 * d1y;
        u1 += s.w1 * mu1 * d1x;
        w1 += s.w1 * mu1 * d1y;
    }
    q[0] = x0; q[1] = y0; q[2] = x1; q[3] = y1; v[0] = u0; v[1] = w0; v[2] = u1; v[3] = w1;
    return n_steps;
}
