#!/usr/bin/env python3
"""An error-controlled bead for tests/test_tolerance_axis.py (standard library only, protocol 1).

Integrates the bead's angle θ'' = −(g/r) sin θ with RK4 at a step set by ``options.tolerance``
(h = min(dt, tolerance^(1/4)): RK4's error scales as h⁴, so it follows the tolerance), dt being
the largest step, and writes the samples xval asked for.
"""
import json
import math
import sys

doc = json.load(sys.stdin)
scene, dt, steps = doc["scene"], doc["dt"], doc["sample_steps"]
(x, _, z), (vx, _, vz) = scene["particles"][0]["position"], scene["particles"][0]["velocity"]
g, r = -scene["gravity"][2], math.hypot(x, z)
theta = math.atan2(x, -z)
omega = (vx * math.cos(theta) + vz * math.sin(theta)) / r
h_max = min(dt, doc["options"]["tolerance"] ** 0.25)


def rhs(th, om):
    return om, -(g / r) * math.sin(th)


print("t,p0_x,p0_y,p0_z,v0_x,v0_y,v0_z")
t = 0.0
for step in steps:
    target = step * dt
    while target - t > 1e-15:
        h = min(h_max, target - t)
        k1 = rhs(theta, omega)
        k2 = rhs(theta + h / 2 * k1[0], omega + h / 2 * k1[1])
        k3 = rhs(theta + h / 2 * k2[0], omega + h / 2 * k2[1])
        k4 = rhs(theta + h * k3[0], omega + h * k3[1])
        theta += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        omega += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        t += h
    t = target
    s, c = math.sin(theta), math.cos(theta)
    print(f"{target!r},{r * s!r},0.0,{-r * c!r},{r * c * omega!r},0.0,{r * s * omega!r}")
