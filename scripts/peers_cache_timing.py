"""A suite run twice on one fresh cache directory: what a kept cache saves (the figures docs/engines.md quotes).

    .venv/bin/python scripts/peers_cache_timing.py [suites/peers.toml] [--jobs 2] [--cache DIR] [--reduced]
        [--keep DIR]

Runs ``xval run SUITE --jobs N`` twice with ``XVAL_CACHE_DIR`` set to one new,
empty directory (or ``--cache``, emptied first): the first run compiles and
solves everything (MJX's stepping loops into ``<cache>/jax``, ours' kernels,
the references), the second finds them kept. For each run it prints the wall
time, the CPU time of the process tree, and the MJX cases' summed
``jit_compile_time`` (seconds spent compiling or loading a compiled loop from
the cache) and how many MJX cases compiled more than 0.5 s, the files the run
wrote into the cache directory by folder (``jax`` compiled loops, ``numba``
kernels, ``reference`` solutions, ``ours``: JAX keeps every compile there, so
a run that writes none compiled and solved nothing), with the load average
before and after.

``--keep DIR`` writes the second run's results directory to DIR (which must not exist) and
keeps it; both runs' results are otherwise deleted at the end.

``--summarize DIR [DIR ...]`` runs nothing: it prints, for results directories already made
(the two runs', say), where each run's time went, per engine: cases, timeouts, the cases' summed
elapsed time in their hosts (building, compiling, stepping, reading), summed stepping wall and CPU
time, and MJX's summed ``jit_compile_time``. The same table ends each timing run.

``--reduced`` runs a smaller copy of the suite instead (written to the
cache's parent folder and printed): without its ``chain-32`` scene, and with
time steps from 1e-2 to 1e-3 s (two per decade) and tolerances from 1e-4 to
1e-8: every MJX model structure, precision and integrator of the full suite
is still compiled, in a fraction of its stepping.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from compare.results.record import CaseRecord
from compare.run.results import load_results

ROOT = Path(__file__).resolve().parents[1]


def _jit_compile_time(record: CaseRecord) -> float | None:
    """s: the case's ``jit_compile_time`` (MJX records it in its run's settings), None where it has none."""
    seconds = ((record.run_info or {}).get("settings") or {}).get("jit_compile_time")
    return None if seconds is None else float(seconds)


def _mjx_compiles(records: list[CaseRecord]) -> tuple[float, int, int]:
    """(summed jit_compile_time s, MJX cases, cases over 0.5 s) of a run's case records: the cases that record
    a compile time (MJX's cases that ran; a skipped one records none)."""
    compiles = [seconds for seconds in map(_jit_compile_time, records) if seconds is not None]
    return sum(compiles), len(compiles), sum(seconds > 0.5 for seconds in compiles)


def engine_table(records: list[CaseRecord]) -> list[str]:
    """Lines: per engine of a run's case records, cases, timeouts and summed seconds (see the module notes)."""
    rows: dict[str, list[float]] = {}
    for record in records:
        row = rows.setdefault(record.case.engine.split("/")[0], [0, 0, 0.0, 0.0, 0.0, 0.0])
        row[0] += 1
        row[1] += record.status == "timeout"
        row[2] += record.elapsed or 0.0
        row[3] += (record.run_info or {}).get("wall_time") or 0.0
        row[4] += sum(t for t in record.cpu_times or () if t is not None)
        row[5] += _jit_compile_time(record) or 0.0
    lines = [f"  {'engine':<10} {'cases':>5} {'timeouts':>8} {'elapsed s':>10} {'stepping s':>10} "
             f"{'stepping CPU s':>14} {'jit compile s':>13}"]
    for engine, (cases, timeouts, elapsed, wall, cpu, jit) in sorted(rows.items(), key=lambda item: -item[1][2]):
        lines.append(f"  {engine:<10} {cases:5d} {timeouts:8d} {elapsed:10.1f} {wall:10.1f} {cpu:14.1f} {jit:13.1f}")
    return lines


def _reduced(suite: Path, target: Path) -> Path:
    """``suite`` without its chain-32 scene, dt 1e-2..1e-3 and tolerances 1e-4..1e-8, written to ``target``."""
    text = suite.read_text(encoding="utf-8")
    chain = text.index('[[scenes]]\nid = "chain-32"')
    text = text[:chain] + text[text.index("[[engines]]", chain):]
    text = re.sub(r"^dt = .*$", "dt = { from = 1e-2, to = 1e-3, per_decade = 2 }", text, count=1, flags=re.M)
    text = re.sub(r"^tolerance = .*$", "tolerance = { from = 1e-4, to = 1e-8, per_decade = 1 }", text, count=1,
                  flags=re.M)
    target.write_text(text, encoding="utf-8")
    return target


def _written(cache: Path, since: float) -> str:
    """Files under ``cache`` modified at or after ``since`` (epoch s), counted by top-level folder."""
    counts: dict[str, int] = {}
    for path in cache.rglob("*"):
        if path.is_file() and path.stat().st_mtime >= since:
            folder = path.relative_to(cache).parts[0]
            counts[folder] = counts.get(folder, 0) + 1
    detail = ", ".join(f"{folder} {n}" for folder, n in sorted(counts.items()))
    return f"{sum(counts.values())} files written to the cache" + (f" ({detail})" if detail else "")


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("suite", nargs="?", default=str(ROOT / "suites" / "peers.toml"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path, default=None, help="cache directory (emptied first)")
    parser.add_argument("--reduced", action="store_true", help="a smaller copy of the suite (see above)")
    parser.add_argument("--keep", type=Path, default=None, help="the second run's results directory (kept)")
    parser.add_argument("--summarize", type=Path, nargs="+", default=None, metavar="DIR",
                        help="print where these results directories' time went, and run nothing")
    args = parser.parse_args()
    if args.summarize:
        for output in args.summarize:
            print(f"{output}:")
            print("\n".join(engine_table(load_results(output).records)))
        return
    if args.keep is not None and args.keep.exists():
        parser.error(f"--keep: {args.keep} exists; name a new directory")
    cache = args.cache or Path(tempfile.mkdtemp(prefix="xval-cache-timing-")) / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    if args.reduced:
        args.suite = str(_reduced(Path(args.suite), cache.parent / "reduced.toml"))
    env = {**os.environ, "XVAL_CACHE_DIR": str(cache)}
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    xval = Path(sys.executable).with_name("xval")
    print(f"suite {args.suite}, --jobs {args.jobs}, cache {cache} (empty before run 1), {os.cpu_count()} cores")
    walls = []
    with tempfile.TemporaryDirectory() as out:
        for run in (1, 2):
            output = args.keep if run == 2 and args.keep is not None else Path(out) / f"run{run}"
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            load = _load()
            since = time.time()
            start = time.perf_counter()
            done = subprocess.run([str(xval), "run", args.suite, "--jobs", str(args.jobs), "--output", str(output)],
                                  env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            wall = time.perf_counter() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            lines = [line for line in done.stdout.splitlines() if line.strip()]
            records = load_results(output).records
            compile_s, cases, slow = _mjx_compiles(records)
            walls.append(wall)
            print(f"run {run}: exit {done.returncode}, wall {wall:.1f} s, CPU {cpu:.1f} s; MJX cases {cases}, "
                  f"jit_compile_time summed {compile_s:.1f} s, {slow} over 0.5 s; "
                  f"load before {load}, after {_load()}")
            print(f"  {_written(cache, since)}")
            print(f"  its last line: {lines[-1] if lines else '(nothing printed)'}")
            print("\n".join(engine_table(records)))
    print(f"second run / first run, wall: {walls[1] / walls[0]:.2f} (first {walls[0] / walls[1]:.2f}x slower)")


if __name__ == "__main__":
    main()
