"""What writing one case record's file costs, and why it moves: a diagnostic for bench_harness.py.

A run writes each case's record as its own file (``compare.results.files.atomic_write_text``:
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

With ``--layout K`` it also runs ``xval run suites/default.toml --jobs 1``
K times each way, alternating, and prints the ``xval`` process's own CPU
(user + system): as it writes records (a file per case), and with its
``ResultsDir.write_case`` replaced, in that child process only, by an append
of the same bytes to one file (a prototype, for the measurement: readers of
such a directory do not exist). Every output is kept until the end.

    .venv/bin/python bench/bench_file_create.py [--writes N] [--deleted N] [--layout K]
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from compare.results.files import atomic_write_text

ROOT = Path(__file__).resolve().parent.parent
#: Bytes of a default-suite record (about what the double pendulum's hold).
RECORD_BYTES = 20_000

#: ``xval run ... --jobs 1 --quiet`` in a child process that prints its own CPU (user, system) last;
#: argv[1] is "files" (as xval writes) or "one-file" (write_case appends to DIR/cases.jsonl).
XVAL = r"""
import os, resource, sys
layout, out = sys.argv[1], sys.argv[2]
if layout == "one-file":
    import orjson
    import compare.results.store as store
    handles = {}
    def write_case(self, record):
        document = orjson.dumps({"schema_version": store.SCHEMA_VERSION, **record},
                                option=orjson.OPT_APPEND_NEWLINE | orjson.OPT_SERIALIZE_NUMPY)
        if self.path not in handles:
            handles[self.path] = os.open(self.path / "cases.jsonl", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o666)
        os.write(handles[self.path], document)
        return self.cases / store.case_file_name(record["case"]["id"])
    store.ResultsDir.write_case = write_case
from compare.cli import console
try:
    console(["run", "suites/default.toml", "--jobs", "1", "--quiet", "--output", out])
except SystemExit as exc:
    if exc.code not in (0, None):
        raise
own = resource.getrusage(resource.RUSAGE_SELF)
print(own.ru_utime, own.ru_stime)
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
    print(f"\n{'run':>3} {'layout':>9} {'xval user s':>12} {'xval sys s':>11} {'xval CPU s':>11}")
    for k in range(repeats):
        for layout in ("files", "one-file"):
            out = Path(tempfile.mkdtemp(dir=scratch)) / "out"
            done = subprocess.run([sys.executable, "-c", XVAL, layout, str(out)], cwd=ROOT, check=True,
                                  capture_output=True, text=True)
            user, system = (float(x) for x in done.stdout.split()[-2:])
            print(f"{k + 1:>3} {layout:>9} {user:12.2f} {system:11.2f} {user + system:11.2f}", flush=True)


def main(argv: list[str]) -> int:
    writes = int(argv[argv.index("--writes") + 1]) if "--writes" in argv else 200
    deleted = int(argv[argv.index("--deleted") + 1]) if "--deleted" in argv else 3000
    churn = np.random.default_rng(0).random(4_000_000)
    with tempfile.TemporaryDirectory(prefix="bench_file_create-", dir=tempfile.gettempdir()) as tmp:
        scratch = Path(tmp)
        fresh = timed_writes(Path(tempfile.mkdtemp(dir=scratch)), writes, churn)
        delete_many(scratch, deleted)
        after = timed_writes(Path(tempfile.mkdtemp(dir=scratch)), writes, churn)
        print(f"CPU per record write ({writes} writes of {RECORD_BYTES} bytes, file system of {scratch}):")
        print(f"  fresh directory:          {fresh:8.0f} µs")
        print(f"  after deleting {deleted:>6} files: {after:8.0f} µs")
        if "--layout" in argv:
            layout_runs(scratch, int(argv[argv.index("--layout") + 1]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
