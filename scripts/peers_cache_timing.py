"""A suite run twice on one fresh cache directory: what a kept cache saves (the figures docs/engines.md quotes).

    .venv/bin/python scripts/peers_cache_timing.py [suites/peers.toml] [--jobs 2] [--cache DIR]

Runs ``xval run SUITE --jobs N`` twice with ``XVAL_CACHE_DIR`` set to one new,
empty directory (or ``--cache``, emptied first): the first run compiles and
solves everything (MJX's stepping loops into ``<cache>/jax``, ours' kernels,
the references), the second finds them kept. For each run it prints the wall
time, the CPU time of the process tree, and the MJX cases' summed
``jit_compile_time`` (seconds spent compiling or loading a compiled loop from
the cache) and how many MJX cases compiled more than 0.5 s, with the load
average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _mjx_compiles(output: Path) -> tuple[float, int, int]:
    """(summed jit_compile_time s, MJX cases, cases over 0.5 s) from a run's case records."""
    total, cases, slow = 0.0, 0, 0
    for path in output.rglob("*.json"):
        text = path.read_text(encoding="utf-8", errors="replace")
        if "jit_compile_time" not in text:
            continue
        seconds = _find(json.loads(text), "jit_compile_time")
        if seconds is None:
            continue
        total, cases, slow = total + seconds, cases + 1, slow + (seconds > 0.5)
    return total, cases, slow


def _find(value, key):
    if isinstance(value, dict):
        if key in value and isinstance(value[key], (int, float)):
            return float(value[key])
        value = list(value.values())
    if isinstance(value, list):
        for item in value:
            found = _find(item, key)
            if found is not None:
                return found
    return None


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("suite", nargs="?", default=str(ROOT / "suites" / "peers.toml"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path, default=None, help="cache directory (emptied first)")
    args = parser.parse_args()
    cache = args.cache or Path(tempfile.mkdtemp(prefix="xval-cache-timing-"))
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    env = {**os.environ, "XVAL_CACHE_DIR": str(cache)}
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    xval = Path(sys.executable).with_name("xval")
    print(f"suite {args.suite}, --jobs {args.jobs}, cache {cache} (empty before run 1), {os.cpu_count()} cores")
    walls = []
    with tempfile.TemporaryDirectory() as out:
        for run in (1, 2):
            output = Path(out) / f"run{run}"
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            load = _load()
            start = time.perf_counter()
            done = subprocess.run([str(xval), "run", args.suite, "--jobs", str(args.jobs), "--output", str(output)],
                                  env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            wall = time.perf_counter() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            lines = [line for line in done.stdout.splitlines() if line.strip()]
            compile_s, cases, slow = _mjx_compiles(output)
            walls.append(wall)
            print(f"run {run}: exit {done.returncode}, wall {wall:.1f} s, CPU {cpu:.1f} s; MJX cases {cases}, "
                  f"jit_compile_time summed {compile_s:.1f} s, {slow} over 0.5 s; "
                  f"load before {load}, after {_load()}")
            print(f"  its last line: {lines[-1] if lines else '(nothing printed)'}")
    print(f"second run / first run, wall: {walls[1] / walls[0]:.2f} (first {walls[0] / walls[1]:.2f}x slower)")


if __name__ == "__main__":
    main()
