"""Where the harness's CPU goes, phase by phase: a diagnostic for bench_harness.py.

Runs ``xval run suites/default.toml --jobs 1`` as ``bench_harness.one_run`` does
(numba's and the references' caches warm, an uncounted run first), with a
prelude in that child process that times, in CPU seconds (time.process_time
and time.thread_time, so waiting is not counted), the phases of the ``xval``
process and of its case host, and prints them beside the summed stepping time:

``xval`` process:
- start-up: from the interpreter's start to the preload
  (``compare.run.runner.preload_engines``): the imports (click, numpy and
  scipy.linalg, the runner; MuJoCo, PyBullet and pymunk, which loading the
  suite imports with their adapters), planning, and the run's header
  (``compare.run.environment``: engine versions, the git commit);
- preload: numba imported and ours' kernels loaded from its cache (numba
  setting up its compiler's tables the first time), and the reference's
  solver when some scene's solution is not kept;
- forking the host: from the preload to the cases loop (the case host forked);
- records: turning each answer into a record and writing it
  (``compare.run.runner._Writer.write``: metrics, rounding, JSON, the file);
- dispatch: the rest of the cases loop (sending tasks, waiting on the hosts'
  pipes, reading and unpickling their answers);
- end: after the loop (the verdict printed, the run's header written).

case host (one with ``--jobs 1``; its answers' own measures):
- stepping: the engines' stepping loops, wall clock (``wall_times`` summed);
- in cases, outside stepping: the rest of each case's ``simulate`` (building
  the model, reading the samples, checking the run), CPU;
- warm-ups: each engine variant's first, two-step run;
- references: the scenes' reference tasks (their kept solutions read and sampled);
- pipes: receiving tasks and sending answers (pickling included);
- the rest: the host's other CPU (its memory limit set per task, page faults
  after the fork, its loop). The prelude's own bookkeeping in the host (a
  file written after each task, as a host is not waited for) is left out.

other processes: the rest of the xval process's descendants (the ``git``
commands that record the run's commit).

The stepping is wall time and the rest CPU time, as in bench_harness.py's ratio:
time a host spends descheduled while it steps counts as stepping, so on a
loaded machine "in cases, outside stepping" (the case's CPU less its
stepping's wall time) comes out too small, even below zero.

    .venv/bin/python bench/bench_harness_split.py [--runs N]
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from bench_harness import one_run, runs_argument

#: Run in the xval child before xval itself: time its phases and its case host's, and write both to
#: files in the directory SPLIT_DIR (the host's after each task, as it is not waited for).
PRELUDE = r"""
import os as _os, time as _time, json as _json, atexit as _atexit, resource as _resource
from compare.run import startup as _startup
_startup.load_blas_single_threaded()  # what `xval run` does first (before anything imports numpy)
import multiprocessing.connection as _mc
import compare.run.isolation as _iso
import compare.run.runner as _runner
_MAIN = _os.getpid()
_xval = {"records": 0.0}
_host = {"simulate": 0.0, "warm_up": 0.0, "references": 0.0, "pipes": 0.0, "probe": 0.0}
def _timed(table, key, clock):
    def wrap(function):
        def timed(*args, **kwargs):
            start = clock()
            try:
                return function(*args, **kwargs)
            finally:
                table[key] += clock() - start
        return timed
    return wrap
def _in_host(function):
    def pipe(self, *args):
        if _os.getpid() == _MAIN:
            return function(self, *args)
        start = _time.process_time()
        try:
            return function(self, *args)
        finally:
            _host["pipes"] += _time.process_time() - start
    return pipe
_mc.Connection.send, _mc.Connection.recv = _in_host(_mc.Connection.send), _in_host(_mc.Connection.recv)
_iso.simulate = _timed(_host, "simulate", _time.process_time)(_iso.simulate)
_iso.warm_up = _timed(_host, "warm_up", _time.process_time)(_iso.warm_up)
_run_in_host = _iso._run_in_host
def _host_task(task):
    start = _time.process_time()
    answer = _run_in_host(task)
    if isinstance(task, _iso.ReferenceTask):
        _host["references"] += _time.process_time() - start
    start = _time.process_time()
    usage = _resource.getrusage(_resource.RUSAGE_SELF)
    with open(_os.path.join(SPLIT_DIR, f"host-{_os.getpid()}.json"), "w") as handle:
        _json.dump({**_host, "cpu": usage.ru_utime + usage.ru_stime}, handle)
    _host["probe"] += _time.process_time() - start  # written with the next task's figures
    return answer
_iso._run_in_host = _host_task
_runner._Writer.write = _timed(_xval, "records", _time.thread_time)(_runner._Writer.write)
_preload, _loop = _runner.preload_engines, _runner._Dispatcher.run
def _preload_timed(*args, **kwargs):
    _xval["preload_start"] = _time.process_time()
    try:
        return _preload(*args, **kwargs)
    finally:
        _xval["preload_end"] = _time.process_time()
def _loop_timed(self):
    _xval["loop_start"] = _time.process_time()
    try:
        return _loop(self)
    finally:
        _xval["loop_end"] = _time.process_time()
_runner.preload_engines, _runner._Dispatcher.run = _preload_timed, _loop_timed
def _write_xval():
    with open(_os.path.join(SPLIT_DIR, "xval.json"), "w") as handle:
        _json.dump({**_xval, "exit": _time.process_time()}, handle)
_atexit.register(_write_xval)
"""


def split_run(scratch: Path) -> dict:
    """bench_harness.one_run's figures, with the phases of the run's processes (s of CPU) under "split"."""
    where = Path(tempfile.mkdtemp(dir=scratch))
    run = one_run(scratch, prelude=PRELUDE.replace("SPLIT_DIR", repr(str(where))))
    xval = json.loads((where / "xval.json").read_text())
    hosts = [json.loads(f.read_text()) for f in where.glob("host-*.json")]
    loop = xval["loop_end"] - xval["loop_start"]
    host = {key: sum(h[key] for h in hosts) for key in ("cpu", "simulate", "warm_up", "references", "pipes", "probe")}
    run["split"] = {
        "xval start-up": xval["preload_start"],
        "xval preload": xval["preload_end"] - xval["preload_start"],
        "xval forking the host": xval["loop_start"] - xval["preload_end"],
        "xval records": xval["records"],
        "xval dispatch": loop - xval["records"],
        "xval end": xval["exit"] - xval["loop_end"],
        "host stepping (wall)": run["stepping"],
        "host in cases, outside stepping": host["simulate"] - run["stepping"],
        "host warm-ups": host["warm_up"],
        "host references": host["references"],
        "host pipes": host["pipes"],
        "host rest": host["cpu"] - host["probe"] - sum(host[k] for k in ("simulate", "warm_up", "references", "pipes")),
        "other processes": run["descendants"] - host["cpu"],
    }
    run["per_case_ms"] = {
        "xval records": 1000 * xval["records"] / run["cases"],
        "host in cases, outside stepping": 1000 * (host["simulate"] - run["stepping"]) / run["cases"],
    }
    return run


def main(argv: list[str]) -> int:
    runs = runs_argument(argv)
    with tempfile.TemporaryDirectory(prefix="bench_harness_split-") as scratch:
        one_run(Path(scratch))  # not counted: numba's and the references' caches filled if empty
        results = [split_run(Path(scratch)) for _ in range(runs)]

    def row(name: str, values: list, form: str = "9.2f") -> None:
        print(f"{name:<34}" + "".join(f"{v:{form}}" for v in values))

    print(f"{'CPU s (stepping: wall s)':<34}" + "".join(f"{f'run {k + 1}':>9}" for k in range(runs)))
    for name in results[0]["split"]:
        row(name, [r["split"][name] for r in results])
    row("whole tree (getrusage)", [r["cpu"] for r in results])
    row("CPU / stepping", [r["cpu"] / r["stepping"] for r in results])
    row("cases", [r["cases"] for r in results], "9d")
    print("\nms a case")
    for name in results[0]["per_case_ms"]:
        row(name, [r["per_case_ms"][name] for r in results])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
