"""Where a history is: a SQLite file path (default) or a PostgreSQL URL; checked before any work is done.

Light on imports on purpose: ``xval run --history`` checks its option with
:func:`check_option` before running the suite, so a mistyped location fails
in a second, not after the run.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from engines.errors import UserError

#: Where the history is when no --history is given (XVAL_HISTORY overrides).
DEFAULT_LOCATION = "results/history.sqlite"
#: Environment variable naming the default history.
LOCATION_VARIABLE = "XVAL_HISTORY"
#: URL schemes of a PostgreSQL history (an optional +driver may follow, e.g. postgresql+psycopg).
POSTGRES_SCHEMES = ("postgres", "postgresql")


def default_location() -> str:
    return os.environ.get(LOCATION_VARIABLE) or DEFAULT_LOCATION


def parse(location: str | Path | None) -> tuple[str, str]:
    """("sqlite", path) or ("postgresql", url); UserError naming --history for anything else."""
    text = str(location) if location is not None else default_location()
    if text.startswith("sqlite:///"):
        text = text[len("sqlite:///"):]
    if "://" in text:
        scheme = text.split("://", 1)[0]
        if scheme.split("+")[0] not in POSTGRES_SCHEMES:
            raise UserError(f"--history: {scheme}:// is not supported; give a file path (SQLite) or a postgresql:// URL")
        return "postgresql", text
    if not text.strip():
        raise UserError("--history: empty; give a file path (SQLite) or a postgresql:// URL")
    path = Path(text)
    if path.is_dir():
        raise UserError(f"--history: {path} is a directory; give a file, e.g. {path / 'history.sqlite'}")
    return "sqlite", text


def check_option(ctx: Any, param: Any, value: str | None) -> str | None:
    """A click callback: the --history value, refused at once when it cannot be a history location."""
    if value is not None:
        parse(value)
    return value
