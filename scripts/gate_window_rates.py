"""How often the history window's timing gate fails an unchanged run, and how often it catches a 2× slowdown.

docs/history.md quotes what this prints. On the smoke suite (suites/smoke.toml, with ours/rattle run
through the stand-in of scripts/slowed_engines.py so that it can be slowed without changing its case):

1. WINDOW runs fill a fresh history (``xval run ... --history H``).
2. RERUNS unchanged runs, each added to the history and gated against the window of the 5 runs before it
   (``xval gate DIR --history H --window 5``): a failed gate is a false alarm.
3. SLOWED runs with ours/rattle's stepping done twice over (``XVAL_SLOWDOWN=2``), each gated against the
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
#: The variant slowed, as the suite names it.
SLOWED_VARIANT = "slowed_engines:OURS/rattle"


def suite_text() -> str:
    """suites/smoke.toml with ours/rattle run through its stand-in (the same physics and options)."""
    text = (ROOT / "suites" / "smoke.toml").read_text()
    assert 'id = "ours/rattle"' in text, "suites/smoke.toml no longer runs ours/rattle"
    return text.replace('id = "ours/rattle"', f'id = "{SLOWED_VARIANT}"')


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
    """(whether the gate failed, its worse rows' lines)."""
    done = xval("gate", out, "--history", history, "--window", WINDOW)
    if done.returncode not in (0, 1):
        raise SystemExit(f"xval gate failed: {done.stderr.strip()[-500:]}")
    worse = [line.strip() for line in done.stdout.splitlines() if "worse" in line and "slower" in line]
    return done.returncode == 1, worse


def measure(per_core: float, reruns: int, slowed: int) -> dict[str, float]:
    """{"false_alarms": failed / reruns, "detections": failed / slowed} with ``per_core`` neighbours per core."""
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
                print(f"  {label}: unchanged run {k + 1}: gate {'FAILED' if failed else 'passed'}", flush=True)
                for line in worse[:3]:
                    print(f"    {line}")
            caught = 0
            for k in range(slowed):
                out = root / f"slowed-{k}"
                run(suite, out, None, slowdown=2)
                failed, worse = gated(out, history)
                caught += failed
                print(f"  {label}: {SLOWED_VARIANT} 2× slower, run {k + 1}: gate {'FAILED' if failed else 'passed'}"
                      + (f" ({len(worse)} cases worse)" if failed else ""), flush=True)
            load = os.getloadavg()[0]
            print(f"{label} (load average {load:.1f} at the end, {time.monotonic() - started:.0f} s): "
                  f"{alarms} of {reruns} unchanged runs failed the gate; {caught} of {slowed} slowed runs failed it")
            return {"false_alarms": alarms / reruns if reruns else 0.0, "detections": caught / slowed if slowed else 0.0}
    finally:
        for neighbour in neighbours:
            neighbour.kill()
            neighbour.wait()


SLOW = {"false_alarms_idle", "detections_idle", "false_alarms_loaded", "detections_loaded"}


def figures(quick: bool = False, reruns: int = RERUNS, slowed: int = SLOWED, loads: tuple[float, ...] = (0, 2),
            ) -> dict[str, float]:
    """The false-alarm and detection rates (fractions) idle (no added load) and loaded (2 busy loops per core)."""
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
        print(f"{key} = {value:.2f}")
    if set(found) == SLOW:
        report(found, QUOTES, ROWS)


if __name__ == "__main__":
    main()
