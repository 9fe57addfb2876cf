"""What the process protocol costs: per-case overhead beyond the program's own time, and CSV speed.

1. Overhead per case (target: at most 50 ms beyond the program's own time).
   The C++ example solvers (examples/cpp, built here with g++) run through the
   ``command/`` engine (``Engine.simulate``: the document, starting the
   program in its own process group, reading and checking its CSV, killing
   the group) and, as the peer in the same run, bare: ``subprocess.run`` with
   the same document on stdin and its stdout collected, which is the
   program's own time (its start-up and stepping and writing included).
   The overhead is the difference of the medians.
2. Reading CSV (target: at least 1e6 numbers/s): ``engines.external.protocol.read_csv``
   plus ``match_columns`` on a 100 000-row double-pendulum table, against
   ``numpy.loadtxt`` on the same text as the peer; and writing it
   (``write_csv``) against ``numpy.savetxt`` with ``%r``.
"""

from __future__ import annotations

import io
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from engines.scene import catalog  # noqa: E402
from engines.external import command, protocol  # noqa: E402
from engines.adapter import Schedule  # noqa: E402

REPEATS = 15


def median_time(function, repeats: int = REPEATS) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def overhead(build: Path) -> None:
    print("overhead per case: command/ engine vs the bare program, interleaved (median of "
          f"{REPEATS}, 3 for the last; target: at most 50 ms beyond the program's own time)")
    print(f"{'program':<16} {'scene':<16} {'dt':>6} {'rows':>6} {'bare ms':>8} {'engine ms':>10} {'overhead ms':>12}")
    for program, scene_name, dt, interval, repeats in (
            ("bead", "bead", 1e-3, None, REPEATS),
            ("double_pendulum", "double-pendulum", 1e-3, None, REPEATS),
            ("double_pendulum", "double-pendulum", 1e-4, 1e-3, REPEATS),
            ("double_pendulum", "double-pendulum", 1e-4, 1e-4, 3)):  # 100 001 rows: reading dominates
        scene = catalog.build(scene_name)  # 10 s
        engine = command.command_engine(f"bench-{program}", [str(build / program)], build,
                                        capabilities=["constraint-forces"])
        schedule = Schedule.make(scene.duration, dt, interval)
        payload = json.dumps(protocol.document(scene, dt, schedule.n_steps, schedule.sample_steps, {})).encode()

        def bare():
            done = subprocess.run([str(build / program)], input=payload, capture_output=True, check=True)  # noqa: B023
            assert done.stdout

        def through_engine():
            trajectory = engine.simulate(scene, dt, sample_interval=interval)  # noqa: B023 (timed in the loop)
            assert trajectory.info.status == "ok", trajectory.info.message

        through_engine(), bare()  # page the program in
        # Interleaved, so both see the same machine load (it is shared).
        pairs = [(median_time(bare, 1), median_time(through_engine, 1)) for _ in range(repeats)]
        t_bare = statistics.median(p[0] for p in pairs)
        t_engine = statistics.median(p[1] for p in pairs)
        print(f"{program:<16} {scene_name:<16} {dt:>6g} {len(schedule.sample_steps):>6} {t_bare * 1e3:>8.1f} "
              f"{t_engine * 1e3:>10.1f} {(t_engine - t_bare) * 1e3:>12.1f}")


def csv_speed() -> None:
    scene = catalog.build("double-pendulum")
    rows = 100_000
    header = protocol.columns(scene, forces=True)
    values = np.random.default_rng(0).standard_normal((rows, len(header)))
    numbers = values.size
    text = protocol.write_csv(header, values)

    def read():
        protocol.match_columns(protocol.read_csv(text), scene)

    def loadtxt():
        np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)

    def write():
        protocol.write_csv(header, values)

    def savetxt():
        np.savetxt(io.StringIO(), values, fmt="%r", delimiter=",", header=",".join(header), comments="")

    assert np.array_equal(protocol.read_csv(text).values, values)
    print(f"\nCSV: {rows} rows x {len(header)} columns = {numbers:.3g} numbers, {len(text) / 1e6:.1f} MB "
          f"(median of 5; target: reading at least 1e6 numbers/s)")
    for name, function, peer_name, peer in (("read_csv+match_columns", read, "numpy.loadtxt", loadtxt),
                                            ("write_csv", write, "numpy.savetxt %r", savetxt)):
        mine, theirs = median_time(function, 5), median_time(peer, 5)
        print(f"{name:<24} {numbers / mine / 1e6:>6.2f} M numbers/s   {peer_name:<17} {numbers / theirs / 1e6:>6.2f} "
              f"M numbers/s   ratio {theirs / mine:.1f}x")


def main() -> None:
    if shutil.which("g++") is None:
        print("g++ is not installed: skipping the overhead part (the CSV part follows)")
    else:
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(["make", "-s", "-C", str(ROOT / "examples" / "cpp"), f"BUILD={tmp}"], check=True)
            overhead(Path(tmp))
    csv_speed()


if __name__ == "__main__":
    main()
