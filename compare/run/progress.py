"""Progress of a run: a rich bar on a terminal, one plain line per case otherwise (logs, CI, pipes)."""

from __future__ import annotations

import sys
from typing import Any, Protocol, TextIO

from compare.results.record import CaseRecord, Status


class Progress(Protocol):
    """What the runner calls: ``start`` once, ``advance`` per finished case, ``stop`` at the end."""

    def start(self, total: int, already_done: int) -> None: ...

    def advance(self, record: CaseRecord) -> None: ...

    def stop(self) -> None: ...


def describe(record: CaseRecord) -> str:
    """``bead · mujoco/hinge-euler · dt=0.001: ok`` (with the message when not ok)."""
    case = record.case
    text = f"{case.scene_id} · {case.engine} · dt={case.dt:g}: {record.status.value}"
    if record.status is not Status.OK and record.message:
        text += f" ({record.message})"
    return text


class NullProgress:
    def start(self, total: int, already_done: int) -> None:
        pass

    def advance(self, record: CaseRecord) -> None:
        pass

    def stop(self) -> None:
        pass


class PlainProgress:
    """``[  12/210] bead · ours/rk4 · dt=0.01: ok`` lines, flushed as they come."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.done = 0
        self.total = 0

    def start(self, total: int, already_done: int) -> None:
        self.total, self.done = total, already_done
        if already_done:
            print(f"resuming: {already_done} of {total} cases already done", file=self.stream, flush=True)

    def advance(self, record: CaseRecord) -> None:
        self.done += 1
        width = len(str(self.total))
        print(f"[{self.done:>{width}}/{self.total}] {describe(record)}", file=self.stream, flush=True)

    def stop(self) -> None:
        pass


class RichProgress:
    """A bar with cases done, failures so far and time left."""

    def __init__(self, stream: TextIO) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        self.console = Console(file=stream)
        self.failures = 0
        self.bar = Progress(
            TextColumn("running"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[failures]}"),
            TimeRemainingColumn(),
            TextColumn("{task.fields[last]}", style="dim"),
            console=self.console,
            transient=True,
        )
        self.task: Any = None

    def start(self, total: int, already_done: int) -> None:
        self.bar.start()
        self.task = self.bar.add_task("cases", total=total, completed=already_done, failures="", last="")

    def advance(self, record: CaseRecord) -> None:
        if record.status in (Status.FAILED, Status.TIMEOUT, Status.UNSTABLE):
            self.failures += 1
            self.console.print(f"[yellow]{describe(record)}[/yellow]", highlight=False)
        label = f"{self.failures} not ok" if self.failures else ""
        self.bar.update(self.task, advance=1, failures=label, last=describe(record)[:60])

    def stop(self) -> None:
        self.bar.stop()


def progress_for(stream: TextIO | None = None) -> Progress:
    """A RichProgress on a terminal, a PlainProgress otherwise."""
    stream = stream or sys.stderr
    return RichProgress(stream) if stream.isatty() else PlainProgress(stream)

