"""Where results were produced: Python, numpy, every engine's version, CPU, platform, git commit."""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any, Collection

import numpy as np

from engines import registry

#: The project checkout whose commit is recorded (the directory above compare/).
PROJECT_ROOT = Path(__file__).resolve().parent.parent


def cpu_name() -> str:
    """The CPU model as the OS reports it ('' when unknown)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def git_commit(root: Path = PROJECT_ROOT) -> str | None:
    """The checkout's HEAD commit, with ``+dirty`` when tracked files changed; None outside git."""
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


#: The lock file ``make`` installs from (exact versions of every dependency; ``make lock`` writes it).
LOCK_FILE = Path(__file__).resolve().parents[2] / "requirements.lock"


def lock_hash(path: Path = LOCK_FILE) -> str | None:
    """``sha256:<hex>`` of the lock file the environment was installed from, None when there is none
    (xval installed from a wheel): two runs with the same hash ran on the same versions of everything."""
    try:
        return "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def engine_versions(used: Collection[str] | None = None) -> dict[str, str]:
    """Engine name -> version string, or ``unavailable: <reason>``.

    used : the engines a run uses (None: all). An optional built-in outside it
        (Drake, MJX) is not imported: its entry reads ``not used by this run
        (drake 1.51.1 installed)`` from the installed distribution, or says it
        is not installed.
    """
    versions = {}
    for name in registry.engine_names():
        if used is not None and name not in used and name in registry.DISTRIBUTION:
            versions[name] = _installed(name)
            continue
        found = registry.status(name)
        if found.engine is None:
            versions[name] = f"unavailable: {found.reason}"
        else:
            try:
                versions[name] = found.engine.version()
            except Exception as exc:  # a broken version() must not stop a run
                versions[name] = f"unknown: {exc}"
    return versions


def _installed(name: str) -> str:
    """What run.json says of an optional engine the run does not use (read without importing it)."""
    distribution = registry.DISTRIBUTION[name]
    try:
        return f"not used by this run ({distribution} {importlib.metadata.version(distribution)} installed)"
    except importlib.metadata.PackageNotFoundError:
        return f"unavailable: {distribution} is not installed; install it with: {registry.INSTALL[name]}"


def environment(used: Collection[str] | None = None) -> dict[str, Any]:
    """A JSON-ready description of this machine and software.

    used : the engine names the run uses (see :func:`engine_versions`); None: every engine.
    """
    return {
        "python": sys.version.split()[0],
        "python_implementation": platform.python_implementation(),
        "numpy": np.__version__,
        "engines": engine_versions(used),
        "cpu": cpu_name(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "git_commit": git_commit(),
        "lock": lock_hash(),
    }
