"""Progress of a run: one rich bar on a terminal, a few milestone lines otherwise, a line per case when asked.

``xval run`` picks one with :func:`progress_for`: the default is a single
bar (a terminal) or a line at every tenth of the run (logs, CI, pipes);
``--verbose`` prints a line per case; ``--quiet`` prints nothing while
running. What went wrong is listed once, at the end, by the run's summary
(compare.results.verdict), not case by case.
"""

from __future__ import annotations

import sys
from typing import Any, Protocol, TextIO

from compare.results.record import PROBLEMS, CaseRecord, Status, engine_output_lines


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
        # --verbose is the one mode that shows what the engine printed (kept in the record in every mode).
        for line in engine_output_lines(record):
            print(f"    {line}", file=self.stream, flush=True)

    def stop(self) -> None:
        pass


class MilestoneProgress(PlainProgress):
    """``running: 93/462 cases (20 %), 12 not ok`` at every tenth of the run: a log gets ~10 lines, not one per case."""

    def __init__(self, stream: TextIO, steps: int = 10) -> None:
        super().__init__(stream)
        self.steps = steps
        self.not_ok = 0

    def advance(self, record: CaseRecord) -> None:
        reached = self.done * self.steps // max(self.total, 1)  # tenths of the run done before this case
        self.done += 1
        if record.status in PROBLEMS:
            self.not_ok += 1
        if self.total and self.done * self.steps // self.total > reached:
            percent = 100 * self.done // self.total
            bad = f", {self.not_ok} not ok" if self.not_ok else ""
            print(f"running: {self.done}/{self.total} cases ({percent} %){bad}", file=self.stream, flush=True)


class RichProgress:
    """One bar: cases done, not ok so far, time left, the case just finished. Nothing else is printed."""

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
        if record.status in PROBLEMS:
            self.failures += 1
        label = f"{self.failures} not ok" if self.failures else ""
        self.bar.update(self.task, advance=1, failures=label, last=describe(record)[:60])

    def stop(self) -> None:
        self.bar.stop()


#: What ``xval run`` may be asked to show while it runs.
MODES = ("bar", "quiet", "verbose")


def progress_for(stream: TextIO | None = None, mode: str = "bar") -> Progress:
    """The progress display for ``mode``: "bar" (a RichProgress on a terminal, a MilestoneProgress otherwise),
    "verbose" (a PlainProgress: a line per case) or "quiet" (nothing)."""
    stream = stream or sys.stderr
    if mode == "quiet":
        return NullProgress()
    if mode == "verbose":
        return PlainProgress(stream)
    return RichProgress(stream) if stream.isatty() else MilestoneProgress(stream)
