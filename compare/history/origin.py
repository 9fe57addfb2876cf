"""Where a run came from: the commit it ran at (with a dirty flag), that commit's date, and the machine.

The commit is the one recorded when the run was made whenever possible:

- ``xval run --history`` asks git, right after the run, for the commit of the
  working tree the suite file lives in (so a project keeping its own suite in
  its own repository gets its own commit, not xval's);
- ``xval history add DIR`` takes ``environment.git_commit`` from DIR/run.json
  (the xval checkout that made the run, recorded at run time), or the
  ``--commit`` given (a suite kept in another repository, added later).

Details: docs/history.md, "Module notes", ``compare/history/origin.py``.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from compare.gate.baseline import MACHINE_FIELDS

#: Suffix git_commit strings carry when tracked files had uncommitted changes.
DIRTY = "+dirty"


@dataclass(frozen=True)
class Origin:
    """commit : full SHA (None when unknown); dirty : tracked files had changes; date : the commit's committer date (ISO 8601) or None."""

    commit: str | None
    dirty: bool
    date: str | None = None

    @classmethod
    def parse(cls, text: str | None, date: str | None = None) -> "Origin":
        """From ``SHA`` or ``SHA+dirty`` (the spelling of run.json's git_commit)."""
        if not text:
            return cls(None, False, date)
        dirty = text.endswith(DIRTY)
        return cls(text[: -len(DIRTY)] if dirty else text, dirty, date)

    @property
    def short(self) -> str:
        """10 hex digits, ``*`` appended when dirty; ``?`` when unknown."""
        if self.commit is None:
            return "?"
        return self.commit[:10] + ("*" if self.dirty else "")


def _git(directory: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(directory), *args], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def commit_date(directory: Path, commit: str) -> str | None:
    """The committer date of ``commit`` (ISO 8601) in the repository at ``directory``; None if git cannot tell."""
    return _git(directory, "show", "-s", "--format=%cI", commit) or None


def tree_origin(path: str | Path) -> Origin | None:
    """The commit of the git working tree holding ``path`` (a file or directory), with its dirty flag; None outside git."""
    path = Path(path)
    directory = path if path.is_dir() else path.parent
    if not directory.is_dir():
        return None
    head = _git(directory, "rev-parse", "HEAD")
    if not head:
        return None
    status = _git(directory, "status", "--porcelain", "--untracked-files=no")
    return Origin(head, bool(status), commit_date(directory, head))


def recorded_origin(header: Mapping[str, Any]) -> Origin:
    """The commit run.json recorded (environment.git_commit); its date when this checkout knows the commit."""
    origin = Origin.parse((header.get("environment") or {}).get("git_commit"))
    if origin.commit is None:
        return origin
    from compare.run.environment import PROJECT_ROOT  # the checkout whose commit run.json records

    return Origin(origin.commit, origin.dirty, commit_date(PROJECT_ROOT, origin.commit))


def given_origin(text: str) -> Origin:
    """From ``--commit SHA[+dirty]``; the date when the current directory's repository knows the commit."""
    origin = Origin.parse(text.strip())
    date = commit_date(Path.cwd(), origin.commit) if origin.commit else None
    return Origin(origin.commit, origin.dirty, date)


@dataclass(frozen=True)
class Machine:
    """fingerprint : 12 hex digits of the MACHINE_FIELDS; name : them in words; fields : the values."""

    fingerprint: str
    name: str
    fields: Mapping[str, Any]


def machine_of(header: Mapping[str, Any]) -> Machine:
    """The machine a run was made on, from run.json's environment."""
    environment = header.get("environment") or {}
    fields = {k: environment.get(k) for k in MACHINE_FIELDS}
    digest = hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:12]
    name = f"{fields.get('cpu') or 'unknown CPU'} ×{fields.get('cpu_count')} {fields.get('machine') or ''}".strip()
    return Machine(digest, name, fields)
