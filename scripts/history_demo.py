"""``make history-demo``: the project's own accuracy story, asv-style.

For each of the last N commits of this repository (first-parent, oldest
first): a temporary ``git worktree`` of that commit, a virtual environment
of its own with that commit's xval installed into it, ``xval run
suites/smoke.toml`` with that commit's xval, and the finished run appended
to one history (with this checkout's xval, which reads every results schema
the commits wrote). Then the history's trend page. Commits already in the
history (same suite, same machine, clean) are not run again, so a second
``make history-demo`` only adds what is new.

    .venv/bin/python scripts/history_demo.py --commits 4 \\
        --history results/history-demo/history.sqlite --output results/history-demo/trend.html

Takes a few minutes per commit (a fresh environment, then the smoke suite);
it is not part of ``make test``.
"""

from __future__ import annotations

import argparse
import signal
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import os
import platform

from compare.history.origin import machine_of, tree_origin
from compare.history.store import AlreadyRecorded, History
from compare.run.results import load_results
from compare.run.environment import cpu_name

ROOT = Path(__file__).resolve().parent.parent
SUITE = "suites/smoke.toml"
SUITE_NAME = "smoke"


def git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def recorded_commits(location: str, suite: str, machine: str) -> set[str]:
    if not Path(location).exists():
        return set()
    with History.open(location) as history:
        return {r.origin.commit for r in history.runs(suite=suite, machine=machine) if not r.origin.dirty}


#: Seconds per case: a fresh environment compiles ours' numba kernels on first use, which the
#: smoke suite's 60 s does not allow for on a loaded machine (the cost measured excludes it).
CASE_TIMEOUT = 900


def quietly(argv: list[str], cwd: Path | None = None) -> None:
    """Run ``argv`` in its own process group, output captured; the whole group is killed if we are stopped."""
    process = subprocess.Popen(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    try:
        out, err = process.communicate()
    except BaseException:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    if process.returncode != 0:
        raise subprocess.CalledProcessError(process.returncode, argv, out, err)


def run_commit(commit: str, scratch: Path, jobs: int) -> Path:
    """Check ``commit`` out, install it into its own environment, run the smoke suite; returns the results directory."""
    source, venv, output = scratch / "src", scratch / "venv", scratch / "results"
    git("worktree", "add", "--detach", "--force", str(source), commit)
    quietly([sys.executable, "-m", "venv", str(venv)])
    quietly([str(venv / "bin" / "python"), "-m", "pip", "install", "--quiet", "-e", str(source)])
    quietly([str(venv / "bin" / "xval"), "run", str(source / SUITE), "--output", str(output), "--jobs", str(jobs),
             "--timeout", str(CASE_TIMEOUT)], cwd=source)
    return output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commits", type=int, default=4, help="how many of the last commits (default 4)")
    parser.add_argument("--history", default=str(ROOT / "results" / "history-demo" / "history.sqlite"))
    parser.add_argument("--output", default=str(ROOT / "results" / "history-demo" / "trend.html"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--rev", default="HEAD", help="the newest commit to run (default HEAD)")
    args = parser.parse_args()
    # Stopped (make interrupted, CI timeout): unwind, so each worktree and environment is removed.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    commits = git("rev-list", "--first-parent", "-n", str(args.commits), args.rev).split()[::-1]
    Path(args.history).parent.mkdir(parents=True, exist_ok=True)
    here = machine_of({"environment": {"cpu": cpu_name(), "cpu_count": os.cpu_count(), "machine": platform.machine()}})
    done = recorded_commits(args.history, SUITE_NAME, here.fingerprint)
    for number, commit in enumerate(commits, 1):
        scratch = Path(tempfile.mkdtemp(prefix="xval-history-demo-"))
        started = time.perf_counter()
        try:
            title = git("show", "-s", "--format=%h %s", commit)[:90]
            print(f"[{number}/{len(commits)}] {title}", flush=True)
            if commit in done:
                print("    already in the history")
                continue
            try:
                output = run_commit(commit, scratch, args.jobs)
            except subprocess.CalledProcessError as exc:
                last = (exc.stderr or exc.stdout or "").strip().splitlines()[-1:] or [""]
                print(f"    skipped: {' '.join(map(str, exc.cmd[:3]))} … failed at this commit (exit {exc.returncode}): {last[0]}")
                continue
            results = load_results(output)
            origin = tree_origin(scratch / "src")
            with History.open(args.history, create=True) as history:
                try:
                    run = history.add(results, origin, source=f"{SUITE} at {commit[:10]}")
                except AlreadyRecorded as exc:
                    print(f"    {exc}")
                    continue
            print(f"    run {run.id}: {results.counts()} in {time.perf_counter() - started:.0f} s")
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(scratch / "src")], cwd=ROOT, capture_output=True)
            shutil.rmtree(scratch, ignore_errors=True)
    from reports.history import write_history_report

    written = write_history_report(args.history, args.output)
    print(f"history report: {written.path} ({written.runs} runs, {written.steps} step changes)")


if __name__ == "__main__":
    main()
