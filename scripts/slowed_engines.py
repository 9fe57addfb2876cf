"""MuJoCo, pymunk, ours and the reference with an injectable slowdown, for scripts/timing_gate_noise.py and
scripts/gate_window_rates.py (stand-ins, not engines of their own).

``XVAL_SLOWDOWN = k`` (an integer, default 1) makes each run cost k times the CPU of one: the run, then
a busy loop in the same thread for (k − 1) times the CPU time the run took, its times (wall and CPU) scaled
by k. A build that became k× slower, while the case (scene, variant, options, version) stays the same, so
the gate compares it with the baseline as the same case. (Busy, not asleep: the timing gate compares CPU
time, in which a sleeping thread does not count. Stepping twice over was tried: the second run of a case
of a fraction of a millisecond costs less than the first, and "2×" read 1.2-1.4× in the CPU time.)
"""

from __future__ import annotations

import os
import time
from dataclasses import replace

from engines.mujoco.adapter import MuJoCoEngine
from engines.ours.adapter import OursEngine
from engines.pymunk.adapter import PymunkEngine
from engines.reference.reference import ReferenceEngine


def _slowed(cls):
    class Slowed(cls):
        def _run(self, scene, schedule, settings):
            k = int(os.environ.get("XVAL_SLOWDOWN", "1"))
            started = time.thread_time()
            raw = super(Slowed, self)._run(scene, schedule, settings)
            if k == 1:
                return raw
            spent = time.thread_time() - started
            while time.thread_time() - started < k * spent:
                pass
            return replace(raw, wall_time=k * raw.wall_time, cpu_time=None if raw.cpu_time is None else k * raw.cpu_time)

    Slowed.__name__ = f"Slowed{cls.__name__}"
    return Slowed()


MUJOCO = _slowed(MuJoCoEngine)
PYMUNK = _slowed(PymunkEngine)
OURS = _slowed(OursEngine)
REFERENCE = _slowed(ReferenceEngine)
