"""What writing one case record's file costs, and why it moves: a diagnostic for bench_harness.py.

A run writes each case's record as its own file (``engines.files.atomic_write_text``:
a temporary file, written, renamed into place), between cases whose stepping
and reading fill the CPU's caches with other work. This script writes
record-sized files the same way, with such work between them (sorting a
32 MB array, not timed), and prints the CPU each write took, in µs:

- ``fresh``: into a new directory;
- ``after deleting N``: the same, right after deleting N files (default 3000)
  in a directory beside it, as a test suite or an earlier benchmark run does.

On ext4 without a journal (this machine's root file system) a new file's
inode search skips every inode freed in the last one to six minutes and
reads each one's deletion time from the inode table (``recently_deleted``
in the kernel's fs/ext4/ialloc.c), so the second number grows with N.

With ``--layout K`` it first runs ``xval run suites/default.toml --jobs 1``
(``bench_harness.one_run``) K times each way, alternating which goes first,
and prints the ``xval`` process's own CPU and its system part: as it writes
records (a file per case), and with each record's bytes appended to one file
instead (``compare.results.store``'s write patched in that child process only:
a prototype, for the measurement; no reader of such a directory exists).
These runs come before the deletions below, and every output is kept until
the end.

    .venv/bin/python bench/bench_file_create.py [--writes N] [--deleted N] [--layout K]
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench_harness import one_run
from engines.files import atomic_write_text

#: Bytes of a default-suite record (about what the double pendulum's hold).
RECORD_BYTES = 20_000

#: Run before xval in the child: record files (DIR/cases/*.json) are appended to DIR/cases.jsonl instead.
ONE_FILE = r"""
import os
from compare.run import startup
startup.load_blas_single_threaded()  # what `xval run` does first: numpy must not load before it (store imports it)
import compare.results.store as store
_write, _handles = store.atomic_write_text, {}
def _append(path, text, *, durable=True):
    if path.parent.name != "cases":
        return _write(path, text, durable=durable)
    if path.parent not in _handles:
        _handles[path.parent] = os.open(path.parent.parent / "cases.jsonl", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
    os.write(_handles[path.parent], text)
store.atomic_write_text = _append
"""


def timed_writes(directory: Path, writes: int, churn: np.ndarray) -> float:
    """µs of CPU per record-sized atomic write into ``directory``, with cache-filling work between writes."""
    payload = b"x" * RECORD_BYTES
    total = 0.0
    for i in range(writes):
        churn.sort()
        churn[::7] = -churn[::7]  # unsorted again for the next sort
        start = time.process_time()
        atomic_write_text(directory / f"case-{i:05d}.json", payload, durable=False)
        total += time.process_time() - start
    return 1e6 * total / writes


def delete_many(scratch: Path, n: int) -> None:
    """Create ``n`` empty files in a directory under ``scratch`` and delete them all."""
    doomed = Path(tempfile.mkdtemp(dir=scratch))
    for i in range(n):
        (doomed / f"f{i}").touch()
    shutil.rmtree(doomed)


def layout_runs(scratch: Path, repeats: int) -> None:
    one_run(scratch)  # not counted: numba's and the references' caches filled if empty, as bench_harness does
    print(f"{'run':>3} {'layout':>9} {'xval CPU s':>11} {'xval sys s':>11} {'CPU / stepping':>15}")
    for k in range(repeats):
        order = (("files", ""), ("one-file", ONE_FILE))
        for layout, prelude in order if k % 2 == 0 else order[::-1]:
            run = one_run(scratch, prelude=prelude)
            print(f"{k + 1:>3} {layout:>9} {run['xval']:11.2f} {run['xval_system']:11.2f} "
                  f"{run['cpu'] / run['stepping']:15.2f}", flush=True)


def main(argv: list[str]) -> int:
    writes = int(argv[argv.index("--writes") + 1]) if "--writes" in argv else 200
    deleted = int(argv[argv.index("--deleted") + 1]) if "--deleted" in argv else 3000
    churn = np.random.default_rng(0).random(4_000_000)
    with tempfile.TemporaryDirectory(prefix="bench_file_create-") as tmp:
        scratch = Path(tmp)
        if "--layout" in argv:
            layout_runs(scratch, int(argv[argv.index("--layout") + 1]))
        fresh = timed_writes(Path(tempfile.mkdtemp(dir=scratch)), writes, churn)
        delete_many(scratch, deleted)
        after = timed_writes(Path(tempfile.mkdtemp(dir=scratch)), writes, churn)
        print(f"CPU per record write ({writes} writes of {RECORD_BYTES} bytes, file system of {scratch}):")
        print(f"  fresh directory:          {fresh:8.0f} µs")
        print(f"  after deleting {deleted:>6} files: {after:8.0f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
