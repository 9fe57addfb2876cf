"""CI mode (XVAL_CI=1, which .ci/run sets): everything the tests need is here, or the run fails at once.

Loaded for every pytest run (pyproject.toml: ``-p ci_mode``). Outside CI mode it does nothing: a
developer without chromium sees the browser tests skipped, with the reason (``-rs``). In CI mode:

- before any test runs, each requirement below is checked; the missing ones end the run with one line
  naming them and how to install them (exit code 3);
- a test that skips anyway fails instead, with its skip reason: CI cannot go green by leaving
  something out.

Pinocchio (``pin``) and DART (``dartpy``) are required once pyproject.toml lists them.
"""

from __future__ import annotations

import glob
import importlib.util
import os
import shutil
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def ci_mode() -> bool:
    return os.environ.get("XVAL_CI", "") not in ("", "0")


def chromium() -> str | None:
    """Debian's chromium: ``$XVAL_CHROMIUM`` when set (empty: none, to test its absence), else on PATH or
    /usr/bin/chromium."""
    if "XVAL_CHROMIUM" in os.environ:
        return os.environ["XVAL_CHROMIUM"] or None
    return shutil.which("chromium") or ("/usr/bin/chromium" if os.access("/usr/bin/chromium", os.X_OK) else None)


def postgres_binaries() -> Path | None:
    """The directory holding initdb and pg_ctl: on PATH, or Debian's /usr/lib/postgresql/<version>/bin."""
    found = shutil.which("initdb")
    if found and shutil.which("pg_ctl"):
        return Path(found).resolve().parent
    for candidate in sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True):
        if Path(candidate, "initdb").exists() and Path(candidate, "pg_ctl").exists():
            return Path(candidate)
    return None


def _module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def _declared(distribution: str) -> bool:
    """Whether pyproject.toml names ``distribution`` among xval's dependencies or extras."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    requirements = [*project.get("dependencies", []),
                    *(r for extra in project.get("optional-dependencies", {}).values() for r in extra)]
    names = {r.split(";")[0].split("[")[0].split("<")[0].split(">")[0].split("=")[0].split("~")[0].strip().lower()
             for r in requirements}
    return distribution in names


def missing() -> list[str]:
    """What CI needs and this machine lacks, each as "what (how to get it)"."""
    checks = [
        ("Drake", _module("pydrake"), "pip install 'xval[drake]'; make installs it"),
        ("MJX", _module("mujoco.mjx") and _module("jax"), "pip install 'xval[mjx]'; make installs it"),
        ("chromium", chromium() is not None, "apt-get install chromium; .ci/run does"),
        ("PostgreSQL", postgres_binaries() is not None, "apt-get install postgresql; .ci/run does"),
        ("the postgres extra", _module("sqlalchemy") and _module("psycopg"), "pip install 'xval[postgres]'"),
        ("g++", shutil.which("g++") is not None, "apt-get install g++; .ci/run does"),
    ]
    if _declared("pin"):
        checks.append(("Pinocchio", _module("pinocchio"), "pip install pin; make installs it"))
    if _declared("dartpy"):
        checks.append(("DART", _module("dartpy"), "pip install dartpy; make installs it"))
    return [f"{what} ({how})" for what, present, how in checks if not present]


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist starts its workers
def pytest_sessionstart(session: pytest.Session) -> None:
    if ci_mode() and not hasattr(session.config, "workerinput"):  # once, in the controlling process
        lacking = missing()
        if lacking:
            # One line on stderr, exit code 3, before any test or worker starts (pytest.exit prints it twice).
            sys.stderr.write("XVAL_CI=1: missing " + "; ".join(lacking) + "\n")
            sys.stderr.flush()
            os._exit(3)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:
    outcome = yield
    report = outcome.get_result()
    if ci_mode() and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped in CI mode (XVAL_CI=1), which allows no skip: {reason}"
    return None
