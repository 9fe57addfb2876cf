"""Files written whole or not at all, and the user cache directory: the one copy of each in xval.

Standard library only, at the bottom of the layers (ours ← engines ← compare ←
reports) so every layer writes through the same code: ours for its generated
kernels, the reference for the solutions it keeps, compare for every output
(through :mod:`engines.files`, since compare does not name ours). It imports nothing
but the standard library; importing it runs ``ours/__init__`` (numpy), so the layers above import it
where they write.
"""

from __future__ import annotations

import itertools
import os
import stat
import tempfile
from pathlib import Path

_TEMPORARY_NUMBERS = itertools.count()


def cache_dir() -> Path:
    """The user cache directory of xval (created if missing): ``$XVAL_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/xval``, else ``~/.cache/xval``; a temporary folder when none can be created."""
    explicit = os.environ.get("XVAL_CACHE_DIR")
    if explicit:
        candidates = [Path(explicit)]
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        candidates = [Path(base) / "xval"]
    candidates.append(Path(tempfile.gettempdir()) / f"xval-cache-{os.getuid() if hasattr(os, 'getuid') else 0}")
    for folder in candidates:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return folder
    return candidates[-1]


def _temporary_beside(target: Path, mode: int | None) -> tuple[int, Path]:
    """(fd open for writing, path) of a new file ``.NAME.<pid>.<n>.tmp`` beside ``target``.

    mode : the permissions to give it, or None for a new file's: 0666 less the
    umask (and a default ACL), applied by the kernel as it creates the file,
    as for any file the user creates.
    """
    for _ in range(1000):
        tmp = target.parent / f".{target.name[:200]}.{os.getpid()}.{next(_TEMPORARY_NUMBERS)}.tmp"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666 if mode is None else 0o600)
        except FileExistsError:  # left by a killed process whose pid this one now has
            continue
        if mode is not None:
            os.fchmod(fd, mode)
        return fd, tmp
    raise FileExistsError(17, "no free temporary name", str(target.parent))


def atomic_write(path: str | os.PathLike, data: str | bytes, *, durable: bool = True) -> None:
    """Write ``data`` (str, written as UTF-8 without newline translation, or bytes) to ``path`` so that
    no reader sees half of it; raises OSError (the caller decides whether a failed write matters).

    A regular file: a temporary beside it (in a folder that exists), written,
    fsynced when ``durable``, renamed into place; the temporary is removed if
    anything fails, and the old file stays as it was. An existing file keeps
    its mode; a new one gets the umask's. A symlink: its final target is
    written, the link kept. A device or FIFO: written in place. A directory:
    IsADirectoryError.

    durable : fsync before the rename, so that even a machine that loses power
        keeps either the old file or the whole new one. Without it a killed
        process still leaves one or the other (the rename is atomic); only a
        crash of the machine itself may leave the new name on an empty file.
    """
    binary = isinstance(data, bytes)
    target = Path(path)
    if target.is_symlink():
        target = target.resolve()  # write through the link; os.replace on the link would replace the link
    try:
        info = target.stat()
    except FileNotFoundError:
        info = None
    if info is not None and not stat.S_ISREG(info.st_mode):
        if stat.S_ISDIR(info.st_mode):
            raise IsADirectoryError(21, "is a directory", str(target))
        with open(target, "wb" if binary else "w", newline=None if binary else "") as handle:
            handle.write(data)  # a device or FIFO is written, never replaced
        return
    fd, tmp = _temporary_beside(target, stat.S_IMODE(info.st_mode) if info is not None else None)
    try:
        with os.fdopen(fd, "wb" if binary else "w", newline=None if binary else "") as handle:
            handle.write(data)
            handle.flush()
            if durable:
                os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
