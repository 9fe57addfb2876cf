"""The harness's file helpers: writing files so that a reader never sees half of one, refusing bad output
paths up front, and reading the files a user names with one error for each way that fails.

Every file is written by :func:`ours.files.atomic_write` (with the user cache directory, the one part
of them ours itself needs: ours imports nothing above it); this module adds what only the layers above
ours need (errors that are UserErrors, ``-`` for standard output). It imports ours where it writes,
for cost: ours loads numpy, which a command must not do before its start-up (compare/run/startup.py).

Rules every output follows: it never replaces one of the command's inputs (UserError, exit 2, before
any work); ``-`` is standard output; a symlink is written through and stays a link; a path that is
not a regular file is never replaced by one (a directory is refused, a device or FIFO written in
place); a new file gets ``0666 & ~umask``, an existing one keeps its mode (docs/reliability.md).
"""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path
from typing import Iterable

from engines.errors import UserError

#: The output path that means standard output.
STDOUT = "-"


def _inside(path: Path, directory: Path) -> bool:
    try:
        path.relative_to(directory)
        return True
    except ValueError:
        return False


def check_not_input(path: str | os.PathLike, inputs: Iterable[str | os.PathLike], flag: str = "--output") -> None:
    """UserError when ``path`` is (or, for an input directory, lies inside) one of ``inputs``.

    Paths are compared after resolving symlinks, so a link to an input is caught too.
    """
    if str(path) == STDOUT:
        return
    target = Path(path).resolve()
    for given in inputs:
        if given is None or str(given) == STDOUT:
            continue
        source = Path(given).resolve()
        if target == source or (source.is_dir() and _inside(target, source)):
            what = f"inside the input directory {given}" if target != source else f"the input {given}"
            raise UserError(f"{flag}: {path} is {what}; writing it would replace what this command reads; "
                            f"choose another path")


def check_writable(path: str | os.PathLike, flag: str = "--output", inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Raise UserError now, before any work, when ``path`` cannot be written (or is one of ``inputs``).

    Returns the path to give :func:`atomic_write_text`; ``-`` is returned as is (standard output).
    """
    if not str(path).strip():
        raise UserError(f"{flag}: the path is empty; give a file name")
    if str(path) == STDOUT:
        return Path(STDOUT)
    name = Path(path).name
    if len(name.encode()) > 255:
        raise UserError(f"{flag}: the file name {name[:40]}... is {len(name.encode())} bytes, "
                        f"longer than the 255 a file system allows; choose a shorter name")
    check_not_input(path, inputs, flag)
    target = Path(path)
    real = target.resolve() if target.is_symlink() else target
    parent = real.parent if str(real.parent) else Path(".")
    if real.is_dir():
        raise UserError(f"{flag}: {target} is a directory; give a file name")
    if not parent.is_dir():
        raise UserError(f"{flag}: directory {parent} does not exist; create it or choose another path")
    if real.exists() and not stat.S_ISREG(real.stat().st_mode):
        if not os.access(real, os.W_OK):
            raise UserError(f"{flag}: {target} is not writable; choose a path you can write")
        return target  # a device or FIFO: written in place
    if not os.access(parent, os.W_OK) or (real.exists() and not os.access(real, os.W_OK)):
        raise UserError(f"{flag}: {target} is not writable; choose a path you can write")
    return target


def read_user_text(path: Path, where: str, fix: str, directory_fix: str | None = None) -> str:
    """The UTF-8 text of a file the user named; UserError ``<where>: <what is wrong>; <fix>`` otherwise.

    where : how the message names the file (``--baseline: PATH``); fix : what the user should do instead;
    directory_fix : the fix when ``path`` is a directory, where ``fix`` would not do (default ``fix``).
    """
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        problem = "no such file"
    except UnicodeDecodeError as exc:
        problem = f"not UTF-8 text (byte {exc.start})"
    except IsADirectoryError:
        problem, fix = "is a directory", directory_fix or fix
    except OSError as exc:
        problem = f"cannot read it ({exc.strerror})"
    raise UserError(f"{where}: {problem}; {fix}")


def atomic_write_text(path: str | os.PathLike, text: str | bytes, *, durable: bool = True) -> None:
    """Write ``text`` (str, or bytes already encoded as UTF-8) to ``path`` so that no reader sees half
    of it (the rules in the module docstring).

    A regular file: a temporary beside it, written, fsynced when ``durable``,
    renamed into place. ``-``: standard output. A symlink: its final target, the
    link kept. A device or FIFO: written in place.

    durable : fsync before the rename, so that even a machine that loses power
        keeps either the old file or the whole new one. Without it a killed
        process still leaves one or the other (the rename is atomic); only a
        crash of the machine itself may leave the new name on an empty file.
        A run's case records are written without it (one fsync per case was a
        visible part of the run's own CPU), since a damaged record is not
        counted as done and ``--resume`` runs its case again.
    """
    if str(path) == STDOUT:
        if isinstance(text, bytes):
            sys.stdout.flush()
            sys.stdout.buffer.write(text)
            sys.stdout.buffer.flush()
        else:
            sys.stdout.write(text)
            sys.stdout.flush()
        return
    # Imported here, not at the top, for cost: it loads the ours package (numpy with it), which a command must
    # not do before its start-up (compare/run/startup.py); by the time anything is written, numpy is loaded.
    from ours.files import atomic_write

    atomic_write(path, text, durable=durable)


def remove_stale_temporaries(directory: str | os.PathLike) -> list[Path]:
    """Delete the temporary files (``.NAME.*.tmp``) an atomic write left when its process was killed.

    Only called under the run's lock (compare/run/lock.py), so no writer of
    this directory is alive. Returns the paths removed.
    """
    removed = []
    for tmp in Path(directory).rglob(".*.tmp"):
        if tmp.is_file() and not tmp.is_symlink():
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed
