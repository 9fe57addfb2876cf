"""What `xval model survey` of pybullet_data's robot models costs (target: at most 5 minutes on 2 cores).

The whole command, `xval model survey <every URDF with two or more moving joints and every MJCF file in
pybullet_data> --jobs 2 --states 100 --format json --quiet`, in a fresh process: wall time, CPU time of
the command and everything it started (user + system), and the machine's load before and after. The set
is scripts/model_survey.py's.
"""

from __future__ import annotations

import importlib.util
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
XVAL = str(Path(sys.executable).parent / "xval")
TARGET = 300.0


def pybullet_data_set() -> list[str]:
    spec = importlib.util.spec_from_file_location("scripts_model_survey", ROOT / "scripts" / "model_survey.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module.pybullet_data_set()


def main() -> None:
    models = pybullet_data_set()
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([XVAL, "model", "survey", *models, "--jobs", "2", "--states", "100", "--format", "json",
                           "--quiet"], capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    counts = json.loads(done.stdout)["counts"]
    print(f"xval model survey: {len(models)} files of pybullet_data, --jobs 2, 100 states, on {os.cpu_count()} CPUs")
    print(f"  load average before {load:.1f}, after {os.getloadavg()[0]:.1f}")
    print(f"  wall {wall:.1f} s (target {TARGET:g} s: {'met' if wall <= TARGET else 'missed'}); CPU {cpu:.1f} s")
    print(f"  exit code {done.returncode}; counts {counts}")


if __name__ == "__main__":
    main()
