#!/usr/bin/env python3
"""A deliberately misbehaving protocol program for tests/test_protocol.py (standard library only).

``protocol_program.py MODE``: read the document, then write rows that hold the
scene's initial state at every sample (protocol-valid, physically wrong), broken
in the way MODE says. ``options.pidfile``, when given, receives "pid pgid child".
"""
import json
import math
import os
import subprocess
import sys
import time

mode = sys.argv[1]
doc = json.load(sys.stdin)
scene, dt, steps = doc["scene"], doc["dt"], doc["sample_steps"]
particles = scene["particles"]
header = ["t"] + [f"{k}{i}_{a}" for i in range(len(particles)) for k in "pv" for a in "xyz"]
state = [x for p in particles for x in (*p["position"], *p["velocity"])]
rows = [[s * dt, *state] for s in steps]

if mode == "hang":  # a child in the same process group, then never finish
    child = subprocess.Popen(["sleep", "600"])
    with open(doc["options"]["pidfile"], "w") as f:
        f.write(f"{os.getpid()} {os.getpgid(0)} {child.pid}")
    time.sleep(600)
if mode == "exit3":
    print("t,p0_x", flush=True)
    sys.exit("protocol_program: the solver diverged at step 17")  # -> exit code 1 with that stderr line
if mode == "exit-code":
    sys.stderr.write("warming up\nsomething went wrong: code 3\n")
    sys.exit(3)
if mode == "unsupported":
    sys.stderr.write("protocol_program: no rods, please\n")
    sys.exit(77)
if mode == "segfault":
    os.kill(os.getpid(), 11)
if mode == "missing-column":
    header, rows = header[:-1], [r[:-1] for r in rows]
if mode == "extra-column":
    header, rows = header + ["q0_x"], [r + [0.0] for r in rows]
if mode == "short-row":
    rows[3] = rows[3][:-1]
if mode == "non-number":
    rows[3][1] = "abc"
if mode == "few-rows":
    rows = rows[:5]
if mode == "extra-row":
    rows.append(rows[-1])
if mode == "bad-time":
    rows[4][0] += 0.5 * dt
if mode == "nan":
    rows[4][2] = math.nan
    rows = rows[:6]
if mode == "wrong-start":
    rows[0][1] += 1e-3
if mode == "no-header":
    header = None
if mode == "wall-time-ms":
    print("# wall_time = 5000")
print("# version = protocol_program 1")
if header:
    print(",".join(header))
for row in rows:
    print(",".join(str(x) for x in row))
