#!/usr/bin/env python3
"""A bead on a circular wire (a Pin in the x-z plane), RK4 in its angle: xval protocol v1, standard library only."""
import json, math, sys, time

doc = json.load(sys.stdin)                               # {"protocol": 1, "scene": ..., "dt", "steps", "sample_steps", "options"}
scene, dt = doc["scene"], doc["dt"]
if len(scene["particles"]) != 1 or [c["kind"] for c in scene["constraints"]] != ["pin"]:
    print(f"bead.py: expects one particle on one pin, not the scene {scene['name']!r}", file=sys.stderr)
    sys.exit(77)                                         # 77: "cannot express this scene" -> skipped
(pin,), (bead,) = scene["constraints"], scene["particles"]
ax, _, az = pin["anchor"]
r, (gx, _, gz) = pin["length"], scene["gravity"]
(x, _, z), (vx, _, vz) = bead["position"], bead["velocity"]
theta = math.atan2(x - ax, -(z - az))                    # from the downward vertical toward +x
omega = (vx * math.cos(theta) + vz * math.sin(theta)) / r


def accel(th):
    return (gx * math.cos(th) + gz * math.sin(th)) / r   # tangential gravity / r


def row(step, th, om):
    s, c = math.sin(th), math.cos(th)
    return f"{step * dt!r},{ax + r * s!r},0.0,{az - r * c!r},{r * om * c!r},0.0,{r * om * s!r}"


wanted, rows, wall = set(doc["sample_steps"]), [row(0, theta, omega)], 0.0
start = time.perf_counter()
for step in range(1, doc["steps"] + 1):
    k1, l1 = omega, accel(theta)
    k2, l2 = omega + 0.5 * dt * l1, accel(theta + 0.5 * dt * k1)
    k3, l3 = omega + 0.5 * dt * l2, accel(theta + 0.5 * dt * k2)
    k4, l4 = omega + dt * l3, accel(theta + dt * k3)
    theta += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    omega += dt / 6 * (l1 + 2 * l2 + 2 * l3 + l4)
    if step in wanted:
        rows.append(row(step, theta, omega))
print(f"# wall_time = {time.perf_counter() - start!r}\n# version = bead.py 1.0")
print("t,p0_x,p0_y,p0_z,v0_x,v0_y,v0_z", *rows, sep="\n")
