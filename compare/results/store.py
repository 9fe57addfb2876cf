"""A results directory: one versioned JSON record per case, written atomically as each case finishes.

Layout::

    DIR/run.json          schema version, suite name and fingerprint, environment,
                          started / finished timestamps, case counts
    DIR/suite.toml        the suite file exactly as it was run
    DIR/cases/<id>.json   one record per finished case (any status)

Each record is written to a temporary file and renamed into place, so a run
killed at any instant leaves only whole records; ``--resume`` runs the cases
that have none. Records carry ``schema_version``; a reader meeting another
version raises a UserError saying what to do (asv's ``api_version``).
"""

from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import numpy as np
import orjson

from engines.errors import UserError

from engines.files import atomic_write_text
from compare.results.record import SCHEMA_VERSION, CaseRecord, check_schema, status_counts


def now() -> str:
    """The current time, ISO 8601 with the UTC offset."""
    return _dt.datetime.now(_dt.timezone.utc).astimezone().isoformat(timespec="seconds")


def case_file_name(case_id: str) -> str:
    """A file name for ``case_id``: readable, filesystem-safe, and unique (a short hash of the id)."""
    readable = re.sub(r"[^A-Za-z0-9._=-]+", "_", case_id)[:120]
    digest = hashlib.sha1(case_id.encode()).hexdigest()[:8]
    return f"{readable}-{digest}.json"


def jsonable(value: Any) -> Any:
    """``value`` with numpy scalars and arrays as Python numbers and lists, tuples as lists,
    non-finite floats as None (JSON has no NaN) and anything else unknown as its str()."""
    # The exact built-in types first (a record's series are lists of thousands of floats): one
    # type() lookup and math.isfinite instead of a chain of isinstance and np.isfinite per number.
    kind = type(value)
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is list or kind is tuple:
        return [jsonable(v) for v in value]
    if value is None or kind is str or kind is int or kind is bool:
        return value
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


class ResultsDir:
    """A results directory being written by a run."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.cases = path / "cases"

    @classmethod
    def open_for_run(cls, path: str | Path, suite_source: str, run_header: dict[str, Any], resume: bool) -> "ResultsDir":
        """Create ``path`` for a new run, or reopen it with ``resume``.

        Without ``resume`` a directory that already holds a run is refused (so
        finished results are never overwritten by accident); with it, the
        stored suite fingerprint must match ``run_header["suite"]["fingerprint"]``.
        """
        path = Path(path)
        results = cls(path)
        run_file = path / "run.json"
        if path.exists() and not path.is_dir():
            raise UserError(f"--output: {path} is a file; give a directory for the results")
        if run_file.exists():
            if not resume:
                raise UserError(
                    f"--output: {path} already holds results; pass --resume to finish that run, "
                    f"or choose another directory"
                )
            stored = read_json(run_file)
            check_schema(stored, run_file)
            want = run_header["suite"]["fingerprint"]
            if stored["suite"]["fingerprint"] != want:
                raise UserError(
                    f"--resume: {path} holds results of a different suite (fingerprint "
                    f"{stored['suite']['fingerprint']}, this suite is {want}); run into a new --output directory"
                )
            # Keep the original start time and environment; note the resumption.
            stored.setdefault("resumed", []).append(now())
            stored["finished"] = None
            results.write_header(stored)
            return results
        try:
            results.cases.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"--output: cannot create {path} ({exc.strerror}); choose a writable directory") from None
        atomic_write_text(path / "suite.toml", suite_source)
        results.write_header({"schema_version": SCHEMA_VERSION, **run_header, "started": now(), "finished": None})
        return results

    def write_header(self, header: dict[str, Any]) -> None:
        atomic_write_text(self.path / "run.json", json.dumps(header, indent=1, sort_keys=True) + "\n")

    def header(self) -> dict[str, Any]:
        return read_json(self.path / "run.json")

    def done_records(self) -> dict[Path, CaseRecord]:
        """The whole, readable records already here, by file (a damaged one's case is run again)."""
        return dict(read_records(self.cases, skip_damaged=True))

    def write_case(self, record: CaseRecord) -> Path:
        """Write one case record (:meth:`CaseRecord.to_json`) atomically; returns its path."""
        target = self.cases / case_file_name(record.case.id)
        # orjson: a tenth of json.dumps' CPU on a record's ~5,000 numbers, and it writes the series'
        # numpy arrays (a SeriesView's, to_json(arrays=True)) as lists itself, NaN as null.
        document = orjson.dumps(record.to_json(arrays=True),
                                option=orjson.OPT_APPEND_NEWLINE | orjson.OPT_SERIALIZE_NUMPY)
        atomic_write_text(target, document, durable=False)
        return target

    def finish(self, counts: dict[str, int]) -> dict[str, Any]:
        """Mark the run finished with its status ``counts``; returns run.json as written."""
        header = self.header()
        header["finished"] = now()
        header["counts"] = counts
        self.write_header(header)
        return header


def read_json(path: Path) -> dict[str, Any]:
    """The JSON object in ``path``; UserError naming the file when it is missing, not UTF-8 or not JSON."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: not found") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not UTF-8 text; it is not an xval results file") from None
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}); delete it and run with --resume") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot be read ({exc.strerror})") from None


def read_records(cases_dir: Path, *, skip_damaged: bool = False) -> Iterator[tuple[Path, CaseRecord]]:
    """(file, typed record) for every case file under ``cases_dir``, in file order: the one loop over them.

    Temporary files of an interrupted write are not case files. A damaged file raises UserError naming
    it, or is passed over with ``skip_damaged`` (a resumed run runs its case again).
    """
    if not cases_dir.is_dir():
        return
    for file in sorted(cases_dir.glob("*.json")):
        try:
            record = CaseRecord.from_json(read_json(file), file)
        except (UserError, ValueError):
            if skip_damaged:
                continue
            raise
        yield file, record


def iter_records(cases_dir: Path) -> Iterable[CaseRecord]:
    """Every case record under ``cases_dir``, typed; UserError naming a damaged file."""
    return (record for _, record in read_records(cases_dir))


def read_run(path: str | Path) -> tuple[Path, dict[str, Any], list[CaseRecord]]:
    """A results directory's (path, run.json's header, typed case records), read once; UserError when it is
    not one, is damaged, or has another schema version (compare.run.results.load_results wraps them)."""
    path = Path(path)
    run_file = path / "run.json"
    if not run_file.exists():
        raise UserError(f"{path}: not a results directory (no run.json); give the --output directory of 'xval run'")
    header = read_json(run_file)
    check_schema(header, run_file)
    return path, header, list(iter_records(path / "cases"))


def results_inputs(directory: str | os.PathLike) -> list[Path]:
    """The files of a results directory a command reads (run.json, suite.toml, every case file):
    what an output must never replace. Other files in the directory (report.html) may be written."""
    root = Path(directory)
    return [root / "run.json", root / "suite.toml", root / "cases"]
