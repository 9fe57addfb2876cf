"""What the harness costs around the physics: CPU of ``xval run suites/default.toml --jobs 1``
against the summed stepping time of its cases (target: at most 1.4×).

Runs the suite into a temporary directory in a child process (numba's cache warm:
a first run fills it, and the scenes' references come from their cache) and
reports, per run:

- the CPU time (user + system) of the whole process tree, from the kernel's
  accounting of waited-for children, split into the ``xval`` process itself
  (planning, imports, preloading, building and writing records) and its
  descendants (the case host that runs the engines, any process an engine starts, and the
  ``git`` commands that record the run's commit);
- the sum over cases of the engines' stepping times (``wall_times`` in the
  records), and the ratio of the two;
- per engine, the stepping time and the time the case host spent on the case
  outside stepping (``elapsed`` minus ``wall_times``: building the model,
  reading samples and constraint forces, checking the run).

The stepping times are wall clock: on a machine loaded by other jobs they grow
while CPU time does not, which flatters the ratio. The load average is printed
with each run; compare runs made at similar load. So is the machine's speed
just before each run (``calib ms``: the CPU of a fixed piece of pure-Python
work, the fastest of five): on a shared virtual machine the same build's
ratio moves with it, because the harness's work (the interpreter, the
kernel's file and page work) slows more than the engines' compiled stepping.
Compare runs made at similar speed too. With more than one run it ends with
the median ratio, its range, and how many runs were at or below the target,
1.4: single runs of one build scatter by several hundredths within an hour,
so judge the target by the median of many.

Every run's results directory is kept until the benchmark ends, then all are
deleted together. Deleting one run's 462 record files just before the next
run made that run's record files dearer to create: ext4 without a journal
(this machine's file system) does not reuse an inode freed in the last one to
six minutes, and each new file's inode search walks past every such inode,
in the kernel, on the ``xval`` process's CPU. ``bench/bench_file_create.py``
measures the effect.

With ``--in-process`` it also runs the same cases with no case host
(``run_suite(..., executor=ThreadPoolExecutor(1), isolate=False)``: one
process, what the process hop costs, with the run command's start-up), and
with ``--fixed`` suites/default.toml at one dt of 2 steps (``xval run`` as
above: about what a run costs before its cases, its CPU minus nothing the
cases could save).

    .venv/bin/python bench/bench_harness.py [--runs N] [--in-process] [--fixed]
"""

from __future__ import annotations

import json
import math
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: ``xval`` (compare.cli.console, what the installed program runs) in a child process that, once the
#: run is over (its case hosts joined), writes its own CPU time (and the system part of it) and its
#: descendants' to the file named by its last argument.
XVAL = r"""
import json, resource, sys
from compare.cli import console
report = sys.argv.pop()
try:
    console(sys.argv[1:])
except SystemExit as exc:
    if exc.code not in (0, None):
        raise
own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
with open(report, "w") as handle:
    json.dump({"xval": own.ru_utime + own.ru_stime, "xval_system": own.ru_stime,
               "descendants": children.ru_utime + children.ru_stime}, handle)
"""


#: The default suite's cases in one process (no case host), with the run command's start-up (BLAS with
#: one thread on importing compare.commands.run, no collection while loading; run_suite resumes it) and
#: console's freeze at exit, as in the ``xval`` runs.
IN_PROCESS = r"""
import concurrent.futures as cf, gc, sys
import compare.commands.run
from compare.run import startup
from compare.run.runner import plan, run_suite, preload_engines
from compare.suite.reader import load_suite
startup.defer_collection()
suite = load_suite("suites/default.toml")
preload_engines(suite, plan(suite))
run_suite(suite, sys.argv[1], jobs=1, executor=cf.ThreadPoolExecutor(1), isolate=False)
gc.freeze()
"""

DEFAULT_SUITE = ROOT / "suites" / "default.toml"


def fixed_suite() -> str:
    """suites/default.toml at one dt of two steps (its scenes, engines and sample interval as they are):
    what a run costs besides its cases."""
    text = DEFAULT_SUITE.read_text(encoding="utf-8")
    text, durations = re.subn(r"(?m)^duration = .*$", "duration = 0.02", text)
    text, dts = re.subn(r"(?m)^dt = .*$", "dt = [1e-2]", text)
    if (durations, dts) != (1, 1):
        raise SystemExit(f"{DEFAULT_SUITE}: expected one 'duration =' and one 'dt =' line to replace")
    return text


def in_process_run(scratch: Path) -> tuple[float, float, int]:
    """(CPU s of the process, summed stepping s, cases) of the default suite run in one process,
    into a new directory under ``scratch``."""
    out = Path(tempfile.mkdtemp(dir=scratch)) / "out"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", IN_PROCESS, str(out)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    records = _records(out)
    stepping = sum(sum(record["wall_times"]) for record in records)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), stepping, len(records)


def _records(out: Path) -> list[dict]:
    """The records of the run in ``out``: a file each (or, with bench_file_create.py's one-file
    prototype, a line each of cases.jsonl)."""
    one_file = out / "cases.jsonl"
    if one_file.exists():
        return [json.loads(line) for line in one_file.read_text().splitlines()]
    return [json.loads(f.read_text()) for f in (out / "cases").glob("*.json")]


def one_run(scratch: Path, suite_text: str | None = None, prelude: str = "") -> dict:
    """CPU seconds (whole tree, the xval process and its system part, its descendants), summed stepping
    seconds, cases and per engine [cases, stepping s, outside-stepping s] of ``xval run`` on
    suites/default.toml (or on the suite ``suite_text``), into a new directory under ``scratch``.
    prelude : Python run in the child before xval (bench_file_create.py patches the record writes)."""
    tmp = tempfile.mkdtemp(dir=scratch)
    out, report, suite = Path(tmp) / "default", Path(tmp) / "cpu.json", DEFAULT_SUITE
    if suite_text is not None:
        suite = Path(tmp) / "suite.toml"
        suite.write_text(suite_text, encoding="utf-8")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", prelude + XVAL, "run", str(suite), "--jobs", "1", "--output", str(out),
                    "--quiet", str(report)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    split = json.loads(report.read_text())
    engines: dict[str, list[float]] = defaultdict(lambda: [0, 0.0, 0.0])
    for record in _records(out):
        stepping = sum(record["wall_times"])
        row = engines[record["case"]["engine"].split("/")[0]]
        row[0] += 1
        row[1] += stepping
        row[2] += record["elapsed"] - stepping
    return {
        "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "xval": split["xval"],
        "xval_system": split["xval_system"],
        "descendants": split["descendants"],
        "stepping": sum(row[1] for row in engines.values()),
        "cases": sum(row[0] for row in engines.values()),
        "engines": dict(sorted(engines.items())),
    }


def _interpreter_work() -> float:
    """A fixed piece of pure-Python work (building and reading a dict of 100,000 small lists)."""
    table = {str(i): [i, 2.0 * i] for i in range(100_000)}
    return sum(row[1] for row in table.values())


def machine_speed() -> float:
    """s of CPU for :func:`_interpreter_work`, the fastest of five: how fast this machine runs the
    interpreter now. (The timing gate's calibration kernel, mostly small matrix products, did not
    move while the same build's harness CPU, and this, nearly doubled.)"""
    best = math.inf
    for _ in range(5):
        start = time.process_time()
        _interpreter_work()
        best = min(best, time.process_time() - start)
    return best


def main(argv: list[str]) -> int:
    # Every run's output is kept until the benchmark ends (see the module docstring: a run must not
    # pay for the files the run before it deleted).
    with tempfile.TemporaryDirectory(prefix="bench_harness-") as scratch:
        return _benchmark(argv, Path(scratch))


def runs_argument(argv: list[str], default: int = 2) -> int:
    """The number after ``--runs`` (default ``default``); exits with a one-line error unless it is 1 or more."""
    if "--runs" not in argv:
        return default
    given = argv[argv.index("--runs") + 1] if argv.index("--runs") + 1 < len(argv) else ""
    if not given.isdigit() or int(given) < 1:
        print(f"{Path(sys.argv[0]).name}: --runs: expected a whole number of runs, 1 or more, got {given!r}",
              file=sys.stderr)
        raise SystemExit(2)
    return int(given)


def _benchmark(argv: list[str], scratch: Path) -> int:
    runs = runs_argument(argv)
    # Not counted: fill numba's and the references' caches if they are empty (the fixed suite's
    # scenes are shorter: their references are other files).
    one_run(scratch)
    if "--fixed" in argv:
        one_run(scratch, fixed_suite())
    print(f"{'run':>3} {'CPU s':>7} {'xval s':>7} {'hosts s':>9} {'stepping s':>11} {'CPU / stepping':>15} {'load':>5}"
          f" {'calib ms':>9}")
    last, ratios = None, []
    for k in range(runs):
        speed = machine_speed()
        last = one_run(scratch)
        ratios.append(last["cpu"] / last["stepping"])
        print(f"{k + 1:>3} {last['cpu']:7.2f} {last['xval']:7.2f} {last['descendants']:9.2f} {last['stepping']:11.2f} "
              f"{ratios[-1]:15.2f} {os.getloadavg()[0]:5.1f} {1000 * speed:9.2f}")
    if runs > 1:
        print(f"\nCPU / stepping over {runs} runs: median {statistics.median(ratios):.3f}, "
              f"range {min(ratios):.3f}-{max(ratios):.3f}, {sum(r <= 1.4 for r in ratios)} of {runs} at or below 1.4")
    print(f"\nlast run, by engine: {'cases':>5} {'stepping s':>11} {'outside stepping s':>19} {'ms per case':>12}")
    for name, (cases, stepping, outside) in last["engines"].items():
        print(f"{name:>20} {cases:5d} {stepping:11.2f} {outside:19.2f} {1000 * outside / cases:12.1f}")
    if "--in-process" in argv:
        speed = machine_speed()
        cpu, stepping, cases = in_process_run(scratch)
        print(f"\nin-process: {cases} cases, CPU {cpu:.2f} s, stepping {stepping:.2f} s, CPU / stepping "
              f"{cpu / stepping:.2f}, load {os.getloadavg()[0]:.1f}, calib {1000 * speed:.2f} ms")
    if "--fixed" in argv:
        speed = machine_speed()
        fixed = one_run(scratch, fixed_suite())
        print(f"\nfixed: {fixed['cases']} cases, CPU {fixed['cpu']:.2f} s (xval {fixed['xval']:.2f} s), stepping "
              f"{fixed['stepping']:.2f} s, load {os.getloadavg()[0]:.1f}, calib {1000 * speed:.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
