"""``xval model survey``: ``xval model check`` over many files, one row per file.

Each file is checked as ``xval model check`` checks it (reading it, the
reference and every engine in child processes of their own), in a pool of
``jobs`` worker processes or on a Dask cluster (compare/run/cluster.py).
A file's row says one of: ``agrees`` (every engine), ``disagrees`` (the
engines, and the cause: the diagnosis, or the engine's message when it did
not load), ``refused`` (the reason the user must fix), ``crashed`` (the
engine and how: a signal, a hang), or ``failed`` (xval itself raised: a bug
of xval's, never expected).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import re
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

from engines.errors import UserError
from engines.model.source import PREFIX

#: File name endings a folder is searched for; a file qualifies when its root element is <robot> or <mujoco>.
SUFFIXES = (".urdf", ".xml")
#: The outcomes of a file, in the order the counts are printed.
OUTCOMES = ("agrees", "disagrees", "refused", "crashed", "failed")
_ROOT = re.compile(rb"<(robot|mujoco)[\s>/]")


@dataclass(frozen=True)
class SurveyRow:
    """One file's outcome. engines : those concerned (disagreeing, crashed). reason : why, in one line."""

    model: str
    outcome: str
    engines: tuple[str, ...] = ()
    reason: str = ""
    moving_joints: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "engines": list(self.engines)}


def find_models(paths: Iterable[str]) -> list[str]:
    """The model files among ``paths``: each file as given; each folder searched recursively for files ending in
    SUFFIXES whose root element is URDF's <robot> or MJCF's <mujoco>; ``pybullet_data:<path>`` a file or folder
    under pybullet_data's. UserError for a path that does not exist."""
    found: list[str] = []
    for text in paths:
        path = Path(text)
        if text.startswith(PREFIX):  # a file or folder PyBullet ships: pybullet_data: alone is all of them
            import pybullet_data

            path = Path(pybullet_data.getDataPath()) / text[len(PREFIX):]
            text = str(path)
        if path.is_file():
            found.append(text)
        elif path.is_dir():
            found += sorted(str(p) for p in path.rglob("*") if p.suffix.lower() in SUFFIXES and p.is_file()
                            and _looks_like_a_model(p))
        else:
            raise UserError(f"model survey: {text}: no such file or folder; give model files or folders holding them")
    return found


def _looks_like_a_model(path: Path) -> bool:
    try:
        with open(path, "rb") as stream:
            head = stream.read(1 << 16)
    except OSError:
        return False
    return _ROOT.search(head) is not None


def survey_one(model: str, states: int, seed: int, timeout: float) -> SurveyRow:
    """Check one file; never raises (an exception of xval's own is the row ``failed``)."""
    from compare.model.parity import CheckCrashed, check

    try:
        report = check(model, states=states, seed=seed, timeout=timeout)
    except UserError as exc:
        return SurveyRow(model, "refused", reason=str(exc))
    except CheckCrashed as exc:
        return SurveyRow(model, "crashed", (exc.part,), exc.failure)
    except Exception as exc:  # noqa: BLE001 - a bug of xval's: kept as the row, with where it was raised
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return SurveyRow(model, "failed", ("xval",), f"{type(exc).__name__}: {exc} ({where.filename}:{where.lineno})")
    joints = len(report.moving_joints)
    crashed = [e for e in report.engines if e.failure]
    if crashed:
        return SurveyRow(model, "crashed", tuple(e.engine for e in crashed),
                         "; ".join(f"{e.engine} {e.message}" for e in crashed), joints)
    differing = [e for e in report.engines if not e.agrees]
    if not differing:
        return SurveyRow(model, "agrees", moving_joints=joints)
    causes = [e.message or "; ".join(line.removeprefix(f"{e.engine}: ") for line in e.diagnosis) or "no diagnosis"
              for e in differing]
    return SurveyRow(model, "disagrees", tuple(e.engine for e in differing),
                     "; ".join(f"{e.engine}: {cause}" for e, cause in zip(differing, causes)), joints)


def _prepare_worker() -> None:
    """Import every model engine once in this worker (quietly), so the children forked per file inherit them.
    The worker's stdout is pointed at its stderr: the xval process's stdout carries only the table or JSON."""
    from engines.model.importers import ENGINES, REFERENCE, importer
    from engines.model.loaded import Refused
    from engines.stdio import flush_all, quiet_output

    flush_all()
    os.dup2(2, 1)
    with quiet_output():
        for name in (*ENGINES, REFERENCE):
            try:
                importer(name)
            except Refused:  # not installed: each file's row says so
                pass


def survey(models: list[str], *, states: int, seed: int, timeout: float, jobs: int | None = None,
           scheduler: str | None = None, advance: Callable[[SurveyRow], None] = lambda row: None) -> list[SurveyRow]:
    """Every file's row, in the order of ``models``; ``advance`` is called as each file finishes."""
    rows: dict[str, SurveyRow] = {}
    if scheduler is not None:
        from compare.run.cluster import connect

        with connect(scheduler, jobs=jobs) as cluster:
            _collect(cluster.executor, models, states, seed, timeout, rows, advance)
    else:
        from compare.run.runner import default_jobs

        workers = max(1, min(jobs or default_jobs(), len(models) or 1))
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: nothing inherited from this one's threads
        with cf.ProcessPoolExecutor(workers, mp_context=context, initializer=_prepare_worker) as pool:
            _collect(pool, models, states, seed, timeout, rows, advance)
    return [rows[m] for m in models]


def _collect(executor: cf.Executor, models: list[str], states: int, seed: int, timeout: float,
             rows: dict[str, SurveyRow], advance: Callable[[SurveyRow], None]) -> None:
    futures = {executor.submit(survey_one, os.path.abspath(m), states, seed, timeout): m for m in models}
    for future in cf.as_completed(futures):
        model = futures[future]
        try:
            row = future.result()
            row = SurveyRow(model, row.outcome, row.engines, row.reason, row.moving_joints)
        except Exception as exc:  # noqa: BLE001 - a worker that died: the file's row, the survey goes on
            row = SurveyRow(model, "failed", ("xval",), f"{type(exc).__name__}: {exc}")
        rows[model] = row
        advance(row)


def counts(rows: list[SurveyRow]) -> dict[str, int]:
    """Files per outcome, every outcome listed."""
    return {outcome: sum(row.outcome == outcome for row in rows) for outcome in OUTCOMES}
