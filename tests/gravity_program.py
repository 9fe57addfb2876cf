#!/usr/bin/env python3
"""A planar double pendulum whose only bug is gravity hard-coded to 9.8 m/s² (protocol v1, standard library only).

Classical RK4 in the two absolute rod angles (fourth order, so its error falls fast as dt shrinks) — towards
the motion under g = 9.8, not the scene's 9.81: a quiet model error that xval's consistency rule must catch
(tests/test_consistency.py). ``gravity_program.py [G]`` uses G instead of 9.8 (the scene's own value makes it
a correct solver).
"""
import json
import math
import sys

G = float(sys.argv[1]) if len(sys.argv) > 1 else 9.8  # the bug: the scene's gravity is never read
doc = json.load(sys.stdin)
scene, h = doc["scene"], doc["dt"]
kinds = sorted(c["kind"] for c in scene["constraints"])
if len(scene["particles"]) != 2 or kinds != ["pin", "rod"]:
    print(f"gravity_program: expects a double pendulum, not the scene {scene['name']!r}", file=sys.stderr)
    sys.exit(77)
pin = next(c for c in scene["constraints"] if c["kind"] == "pin")
rod = next(c for c in scene["constraints"] if c["kind"] == "rod")
inner = pin["particle"]
outer = 1 - inner
m1, m2 = scene["particles"][inner]["mass"], scene["particles"][outer]["mass"]
l1, l2, (ax, _, az) = pin["length"], rod["length"], pin["anchor"]
(x1, _, z1), (x2, _, z2) = scene["particles"][inner]["position"], scene["particles"][outer]["position"]
(u1, _, w1), (u2, _, w2) = scene["particles"][inner]["velocity"], scene["particles"][outer]["velocity"]
t1, t2 = math.atan2(x1 - ax, -(z1 - az)), math.atan2(x2 - x1, -(z2 - z1))
s = [t1, t2, (u1 * math.cos(t1) + w1 * math.sin(t1)) / l1,
     ((u2 - u1) * math.cos(t2) + (w2 - w1) * math.sin(t2)) / l2]


def derivative(y):
    a, b, wa, wb = y
    d = a - b
    den = 2 * m1 + m2 - m2 * math.cos(2 * d)
    acc_a = (-G * (2 * m1 + m2) * math.sin(a) - m2 * G * math.sin(a - 2 * b)
             - 2 * math.sin(d) * m2 * (wb * wb * l2 + wa * wa * l1 * math.cos(d))) / (l1 * den)
    acc_b = (2 * math.sin(d) * (wa * wa * l1 * (m1 + m2) + G * (m1 + m2) * math.cos(a)
                                + wb * wb * l2 * m2 * math.cos(d))) / (l2 * den)
    return [wa, wb, acc_a, acc_b]


def row(step, y):
    a, b, wa, wb = y
    p = [0.0] * 12
    p[6 * inner:6 * inner + 6] = [ax + l1 * math.sin(a), 0.0, az - l1 * math.cos(a),
                                  l1 * wa * math.cos(a), 0.0, l1 * wa * math.sin(a)]
    q = p[6 * inner:6 * inner + 6]
    p[6 * outer:6 * outer + 6] = [q[0] + l2 * math.sin(b), 0.0, q[2] - l2 * math.cos(b),
                                  q[3] + l2 * wb * math.cos(b), 0.0, q[5] + l2 * wb * math.sin(b)]
    return ",".join(repr(v) for v in [step * h, *p])


wanted = set(doc["sample_steps"])
rows = [",".join(repr(v) for v in [0.0, *(c for k in (0, 1) for c in (
    *scene["particles"][k]["position"], *scene["particles"][k]["velocity"]))])]
for step in range(1, doc["steps"] + 1):
    k1 = derivative(s)
    k2 = derivative([v + 0.5 * h * k for v, k in zip(s, k1)])
    k3 = derivative([v + 0.5 * h * k for v, k in zip(s, k2)])
    k4 = derivative([v + h * k for v, k in zip(s, k3)])
    s = [v + h / 6 * (a + 2 * b + 2 * c + d) for v, a, b, c, d in zip(s, k1, k2, k3, k4)]
    if step in wanted:
        rows.append(row(step, s))
print(f"# version = gravity_program {G}")
print(",".join(["t"] + [f"{k}{i}_{a}" for i in range(2) for k in "pv" for a in "xyz"]))
print("\n".join(rows))
