"""Engines that misbehave on purpose, for the runner's isolation tests (test-only; not collected by pytest).

Loaded by suites as ``compare_engines:MISBEHAVING/<variant>``. Every variant
but the misbehaving ones returns the reference solution itself, so a case
that behaves has zero position error.

The engine runs in a case host (compare.run.isolation). On a cluster the host
is a child of a Dask worker: ``kill-worker`` SIGKILLs that worker, as an
out-of-memory killer or a lost machine would. A local run drives its hosts
from the xval process itself (compare.run.hosts), so there the host's parent
is xval (or pytest, which called run_suite): ``kill-worker`` then raises
instead of killing the run or the test session. To break a local pool of
workers, run with ``isolate=False`` and ``kill``: the engine then runs in the
pool's worker, and kills it.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.scene.scene import Scene

MODES = ("exact", "raise", "nan", "sleep", "pause", "kill", "exit", "drift", "kill-worker")
#: s the ``pause`` mode waits before it answers like ``exact``.
PAUSE = 6.0  # s: longer than the 4 s timeout of the case queued behind it (tests/test_hosts.py)


class MisbehavingEngine(Engine):
    """exact: the reference; raise: raises in the stepping loop; nan: NaN from halfway;
    sleep: sleeps for an hour; pause: sleeps PAUSE s, then answers like exact;
    kill: SIGKILLs its own process; exit: os._exit(3);
    drift: the reference with the bead pushed 0.5 m off its wire (finite, but past the bounds);
    kill-worker: SIGKILLs the process that forked the case host when that is an executor's worker."""

    name = "misbehaving"
    capabilities = frozenset({"3d", "constraint-forces"})
    options = {"mode": Option("mode", "exact", "how to misbehave", kind="str", choices=MODES)}
    variants = {mode: {"mode": mode} for mode in MODES}

    def version(self) -> str:
        return "test 1"

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        from engines.reference.reference import solve

        mode = settings["mode"]
        if mode == "raise":
            raise RuntimeError("deliberate failure in the stepping loop")
        if mode == "sleep":
            time.sleep(3600)
        if mode == "pause":
            time.sleep(PAUSE)
        if mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if mode == "exit":
            os._exit(3)
        if mode == "kill-worker":
            parent = os.getppid()
            if _runs_a_suite(parent):
                raise RuntimeError(f"kill-worker: the case host's parent (pid {parent}) is no spawned worker "
                                   "and may be running the suite; it kills only a Dask worker")
            os.kill(parent, signal.SIGKILL)
            os._exit(9)  # no answer, and no orphaned case host left behind
        positions, velocities, forces = solve(scene).at(schedule.times)
        if mode == "nan":
            positions[len(positions) // 2 :] = np.nan
        if mode == "drift":
            # From the first step on: sample 0 must stay the initial state (engines.adapter.check_raw_run).
            positions[1:] = positions[1:] * 1.5
        # host_parent: which process drove the case host (tests of compare.run.hosts).
        return RawRun(positions, velocities, forces, steps=schedule.n_steps, wall_time=1e-3,
                      settings={"host_parent": os.getppid()})


def _runs_a_suite(pid: int) -> bool:
    """Whether process ``pid`` may be the one running the suite (pytest, xval): anything but a process
    that multiprocessing's spawn started, as a Dask nanny starts its workers (Linux /proc)."""
    return b"multiprocessing.spawn" not in Path(f"/proc/{pid}/cmdline").read_bytes()


MISBEHAVING = MisbehavingEngine()


class OwnTimesEngine(MisbehavingEngine):
    """Returns the reference solution sampled at times of its own (each scheduled time after the first,
    less a third of the sample interval), as a plug-in that overrides ``simulate`` may: a case is
    compared with the reference at the trajectory's times, not the schedule's."""

    name = "own-times"
    variants = {"exact": {"mode": "exact"}}

    def simulate(self, scene: Scene, dt: float, *, variant=None, options=None, sample_interval=None):
        from dataclasses import replace

        from engines.reference.reference import solve

        trajectory = super().simulate(scene, dt, variant=variant, options=options, sample_interval=sample_interval)
        t = trajectory.t.copy()
        t[1:] -= (t[1] - t[0]) / 3
        positions, velocities, forces = solve(scene).at(t)
        return replace(trajectory, t=t, positions=positions, velocities=velocities, constraint_forces=forces)


OWN_TIMES = OwnTimesEngine()


#: Lines the printing stand-in writes before it does what its variant says.
PRINTED = 40
PRINTING_MODES = ("segfault", "hang", "answer")


def printed_line(k: int) -> str:
    """The printing stand-in's line ``k`` (0-based), as kept in a record (no newline)."""
    return f"stand-in engine line {k} through {('printf', 'fd 2', 'print')[k % 3]}"


class PrintingEngine(MisbehavingEngine):
    """Prints PRINTED lines as an engine's library does, on fds 1 and 2 (C stdio's printf, buffered by C; a write(2);
    Python's print, buffered by Python; the last line through printf), then: segfault: reads address 0, so
    the kernel sends SIGSEGV; hang: sleeps for an hour; answer: answers like ``exact``.
    pidfile: a file it appends its process id to before printing, so a test can check the process ended."""

    name = "printing"
    needs_warm_up = False  # so each case prints its lines once, as its own
    options = {"mode": Option("mode", "answer", "what it does once it has printed", kind="str",
                              choices=PRINTING_MODES),
               "pidfile": Option("pidfile", "", "a file to append this process's id to ('' for none)", kind="str")}
    variants = {mode: {"mode": mode} for mode in PRINTING_MODES}

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        if settings["pidfile"]:
            with open(settings["pidfile"], "a") as pids:
                pids.write(f"{os.getpid()}\n")
        libc = ctypes.CDLL(None)
        for k in range(PRINTED):
            line = printed_line(k)
            if k % 3 == 0:
                libc.printf(b"%s\n", line.encode())
            elif k % 3 == 1:
                os.write(2, f"{line}\n".encode())
            else:
                print(line, file=sys.stdout)
        if settings["mode"] == "segfault":
            ctypes.string_at(0)
        if settings["mode"] == "hang":
            time.sleep(3600)
        return super()._run(scene, schedule, {"mode": "exact"})


PRINTING = PrintingEngine()
