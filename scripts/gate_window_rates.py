"""How often the history window's timing gate fails an unchanged run, and how often it catches a 2× slowdown.

docs/history.md quotes what this prints. On the smoke suite (suites/smoke.toml, with reference/dop853 run
through the stand-in of scripts/slowed_engines.py so that it can be slowed without
changing its case):

1. WINDOW runs fill a fresh history (``xval run ... --history H``).
2. RERUNS unchanged runs, each added to the history and gated against the window of the 5 runs before it
   (``xval gate DIR --history H --window 5``): a failed gate is a false alarm.
3. SLOWED runs with that variant's CPU doubled (``XVAL_SLOWDOWN=2``), each gated against the
   window and not added: a failed gate is a detection.

Both at the machine's present load and with 2× its cores in busy-loop neighbours (each bounded: it ends
by itself after LOAD_SECONDS, and is killed by pid at the end). About 4 s a run on an idle 2-core
machine: 45 runs per load, some 3 min idle and twice that loaded.

    python scripts/gate_window_rates.py [--reruns N] [--slowed N] [--loads 0,2]

(--loads: neighbours per core, each one measured in turn.)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from quoted import load_quotes, report  # noqa: E402

#: Runs in the window (xval gate --window's default) and filled before the first gated run.
WINDOW = 5
RERUNS = 20
SLOWED = 20
#: s a neighbour busy-loops at most, whatever happens to this script.
LOAD_SECONDS = 3600
LOAD = f"import time\nend = time.monotonic() + {LOAD_SECONDS}\nwhile time.monotonic() < end: pass\n"
XVAL = [sys.executable, "-c", "from compare.cli import main; main()"]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), str(ROOT)])}
#: The variant slowed, as the suite names it: the smoke suite's only variant whose cases step longer than the
#: gate's resolution together (compare.gate.gate.CASE_RESOLUTION; ~35 ms over its 6 cases). ours' variants
#: (~1.5 ms each) are shown, not gated: a slowdown of theirs is below what the gate can tell on this suite.
SLOWED_VARIANT = "slowed_engines:REFERENCE/dop853"


def suite_text() -> str:
    """suites/smoke.toml with reference/dop853 run through its stand-in (the same solver and options)."""
    text = (ROOT / "suites" / "smoke.toml").read_text()
    assert 'id = "reference/dop853"' in text, "suites/smoke.toml no longer runs reference/dop853"
    return text.replace('id = "reference/dop853"', f'id = "{SLOWED_VARIANT}"')


def xval(*args: object, slowdown: int = 1) -> subprocess.CompletedProcess:
    env = {**ENV, "XVAL_SLOWDOWN": str(slowdown)}
    return subprocess.run(XVAL + [str(a) for a in args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=1200)


def run(suite: Path, out: Path, history: Path | None, slowdown: int = 1) -> None:
    extra = ["--history", history] if history is not None else []
    done = xval("run", suite, "--output", out, "--quiet", "--jobs", 1, *extra, slowdown=slowdown)
    if done.returncode != 0:
        raise SystemExit(f"xval run failed: {done.stderr.strip()[-500:]}")


def gated(out: Path, history: Path) -> tuple[bool, list[str]]:
    """(whether the gate failed, the variants it found slower)."""
    done = xval("gate", out, "--history", history, "--window", WINDOW)
    if done.returncode not in (0, 1):
        raise SystemExit(f"xval gate failed: {done.stderr.strip()[-500:]}")
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith("worse") and "slower" in line]
    return done.returncode == 1, sorted({row[2] for row in rows if len(row) > 2})


def measure(per_core: float, reruns: int, slowed: int) -> dict[str, float]:
    """With ``per_core`` neighbours per core: {"false_alarms": unchanged runs that failed, "detections": slowed
    runs that failed on the slowed variant, "misattributed": slowed runs that failed on another variant too}."""
    neighbours = [subprocess.Popen([sys.executable, "-c", LOAD]) for _ in range(round(per_core * (os.cpu_count() or 1)))]
    label = f"{per_core:g} busy loops per core" if neighbours else "no added load"
    try:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            suite = root / "smoke.toml"
            suite.write_text(suite_text())
            history = root / "history.sqlite"
            started = time.monotonic()
            for k in range(WINDOW):
                run(suite, root / f"window-{k}", history)
            alarms = 0
            for k in range(reruns):
                out = root / f"rerun-{k}"
                run(suite, out, history)
                failed, worse = gated(out, history)
                alarms += failed
                print(f"  {label}: unchanged run {k + 1}: gate {'FAILED' if failed else 'passed'}"
                      + (f" ({', '.join(worse)} slower)" if worse else ""), flush=True)
            caught, others = 0, 0
            for k in range(slowed):
                out = root / f"slowed-{k}"
                run(suite, out, None, slowdown=2)
                failed, worse = gated(out, history)
                caught += failed and SLOWED_VARIANT in worse
                others += any(name != SLOWED_VARIANT for name in worse)
                print(f"  {label}: {SLOWED_VARIANT} 2× slower, run {k + 1}: gate {'FAILED' if failed else 'passed'}"
                      + (f" ({', '.join(worse)} slower)" if worse else ""), flush=True)
            load = os.getloadavg()[0]
            print(f"{label} (load average {load:.1f} at the end, {time.monotonic() - started:.0f} s): "
                  f"{alarms} of {reruns} unchanged runs failed the gate; {caught} of {slowed} slowed runs failed it "
                  f"on the slowed variant ({others} of them also on another variant)")
            return {"false_alarms": float(alarms), "detections": float(caught), "misattributed": float(others)}
    finally:
        for neighbour in neighbours:
            neighbour.kill()
            neighbour.wait()


SLOW = {f"{what}_{load}" for what in ("false_alarms", "detections", "misattributed") for load in ("idle", "loaded")}


def figures(quick: bool = False, reruns: int = RERUNS, slowed: int = SLOWED, loads: tuple[float, ...] = (0, 2),
            ) -> dict[str, float]:
    """The counts of :func:`measure` (of ``reruns`` unchanged and ``slowed`` slowed runs), idle (no load added)
    and loaded (2 busy loops per core)."""
    if quick:
        return {}
    found = {}
    for per_core in loads:
        name = "idle" if per_core == 0 else "loaded"
        for key, value in measure(per_core, reruns, slowed).items():
            found[f"{key}_{name}"] = value
    return found


QUOTES = load_quotes(__file__)
ROWS: list = []


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reruns", type=int, default=RERUNS)
    parser.add_argument("--slowed", type=int, default=SLOWED)
    parser.add_argument("--loads", default="0,2", help="busy loops per core, comma-separated (0: none added)")
    args = parser.parse_args()
    loads = tuple(float(x) for x in args.loads.split(","))
    found = figures(reruns=args.reruns, slowed=args.slowed, loads=loads)
    for key, value in found.items():
        print(f"{key} = {value:g}")
    if set(found) == SLOW:
        report(found, QUOTES, ROWS)


if __name__ == "__main__":
    main()
