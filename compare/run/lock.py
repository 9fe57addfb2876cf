"""One ``xval run`` at a time per results directory: an advisory lock on ``DIR/.lock`` holding the pid.

Two runs writing the same directory would run each case twice and could
interleave ``run.json``; the second is refused at once (exit 2) with the
first's pid. The lock is ``flock`` on an open file, so the kernel releases
it however the holder ends (``kill -9`` included): a stale lock file never
blocks a later ``--resume``.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from engines.errors import UserError

LOCK_NAME = ".lock"


class RunLock:
    """Held from :meth:`acquire` to :meth:`release` (or the end of the process)."""

    def __init__(self, directory: str | os.PathLike) -> None:
        self.directory = Path(directory)
        self.fd: int | None = None

    def acquire(self) -> "RunLock":
        """Lock the directory (created if missing); UserError naming the holder's pid when another run has it.

        A path that exists but is not a directory is left for the results
        store to refuse with its own message.
        """
        if self.directory.exists() and not self.directory.is_dir():
            return self
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.directory / LOCK_NAME, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        except OSError as exc:
            raise UserError(f"--output: cannot create {self.directory} ({exc.strerror}); choose a writable directory") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise UserError(
                f"--output: {self.directory} is being written by another xval run (pid {holder}); "
                f"wait for it to finish, or stop it, then run again with --resume"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self.fd = fd
        return self

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the only descriptor releases the flock
            self.fd = None

    def __enter__(self) -> "RunLock":
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
