"""The process protocol, version 1 (docs/protocol.md is the normative text): the document and the CSV.

xval writes one JSON document (:func:`document`) to a program's stdin; the
program writes CSV to its stdout. The same CSV columns are what
``xval simulate`` writes and ``xval score`` reads:

``t, p0_x, p0_y, p0_z, v0_x, v0_y, v0_z, p1_x, …`` (every particle, in scene
order), optionally ``f0_x, f0_y, f0_z, …`` (the force constraint k exerts on
its first particle, ``Pin.particle`` / ``Rod.a``, N), optionally ``energy``
(J) and ``constraint_error`` (m), which xval writes and ignores on reading
(it recomputes both). Lines starting with ``#`` are comments; ``# wall_time
= S`` and ``# version = V`` are read, other keys ignored.

Details: docs/engines.md, "Adapter notes", ``engines/external/protocol.py``.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from engines.scene.scene import Scene

#: The protocol version this xval writes in the document's ``protocol`` field and reads back.
PROTOCOL_VERSION = 1
#: Largest |t − step·dt| accepted in a row, relative to max(step·dt, dt).
TIME_TOLERANCE = 1e-9
#: Columns xval writes after the state (derived quantities); accepted and ignored on reading.
DERIVED_COLUMNS = ("energy", "constraint_error")
#: Comment keys the reader understands (``# key = value``).
COMMENT_KEYS = ("wall_time", "version")

_AXES = "xyz"
_KEY_VALUE = re.compile(r"#[ \t]*([A-Za-z_][A-Za-z0-9_]*)[ \t]*[=:][ \t]*(.*?)[ \t\r\n]*$")


class ProtocolError(ValueError):
    """Text that breaks the protocol; the message names the line, sample and column, and the fix."""


# -- the document -----------------------------------------------------------------


def document(scene: Scene, dt: float, steps: int, sample_steps: Sequence[int],
             options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The protocol-v1 document for one run.

    dt : s; steps : steps to take; sample_steps : (n_samples,) step indices
    at which a row is wanted (0 first, ``steps`` last); options : passed
    through untouched (JSON values).
    """
    return {
        "protocol": PROTOCOL_VERSION,
        "scene": scene.to_dict(),
        "dt": float(dt),
        "steps": int(steps),
        "sample_steps": [int(s) for s in sample_steps],
        "options": dict(options or {}),
    }


# -- columns ----------------------------------------------------------------------


def state_columns(n_particles: int) -> list[str]:
    """``t``, then ``p{i}_x p{i}_y p{i}_z v{i}_x v{i}_y v{i}_z`` for each particle i."""
    columns = ["t"]
    for i in range(n_particles):
        columns += [f"p{i}_{a}" for a in _AXES] + [f"v{i}_{a}" for a in _AXES]
    return columns


def force_columns(n_constraints: int) -> list[str]:
    """``f{k}_x f{k}_y f{k}_z`` for each constraint k."""
    return [f"f{k}_{a}" for k in range(n_constraints) for a in _AXES]


def columns(scene: Scene, *, forces: bool = False, derived: bool = False) -> list[str]:
    """The protocol's columns for ``scene``: the state, then forces and derived columns when asked."""
    out = state_columns(len(scene.particles))
    if forces:
        out += force_columns(len(scene.constraints))
    if derived:
        out += list(DERIVED_COLUMNS)
    return out


# -- writing ----------------------------------------------------------------------


def write_csv(header: Sequence[str], table: np.ndarray, comments: Mapping[str, Any] | None = None) -> str:
    """CSV text: ``# key = value`` comment lines, the header, one line per row of ``table``.

    table : (n_rows, len(header)) float64. Every number is written with
    ``repr`` (shortest text that reads back to the same float; ``nan``,
    ``inf``), by one ``%`` operation rather than a loop over rows.
    """
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(header):
        raise ValueError(f"write_csv: table has shape {table.shape}, expected (n, {len(header)})")
    lines = [f"# {key} = {value}\n" for key, value in (comments or {}).items()]
    lines.append(",".join(header) + "\n")
    if table.size:
        row = ",".join(["%r"] * table.shape[1]) + "\n"
        lines.append((row * table.shape[0]) % tuple(table.ravel().tolist()))
    return "".join(lines)


# -- reading ----------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    """A CSV as read: ``header`` (column names), ``values`` (n_rows, n_columns) float64, and comments.

    comments : every ``# key = value`` line (the last value of a key wins).
    data_lines : (n_rows,) 1-based line numbers of the rows in the text,
        for messages (comment lines and the header are counted).
    header_line : 1-based line number of the header.
    """

    header: tuple[str, ...]
    values: np.ndarray
    comments: Mapping[str, str] = field(default_factory=dict)
    data_lines: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    header_line: int = 1

    @property
    def n_rows(self) -> int:
        return self.values.shape[0]

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.header.index(name)]

    def wall_time(self) -> float | None:
        """The ``# wall_time`` comment in s, or None; ProtocolError when it is not a finite number >= 0."""
        raw = self.comments.get("wall_time")
        if raw is None:
            return None
        try:
            value = float(raw)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < 0:
            raise ProtocolError(f"'# wall_time = {raw}' is not a number of seconds >= 0; write e.g. '# wall_time = 0.0123'")
        return value


def read_csv(text: str | bytes, where: str = "the CSV") -> Table:
    """Parse protocol CSV text into a :class:`Table`; ProtocolError naming the line and column when it is bad.

    where : how to name the text in messages (``stdout of command/my-bead``, a file path).
    Checks: a header line of unique, non-empty names; every row has as many
    fields as the header; every field is a number (``nan`` and ``inf``
    included: whether they are allowed is the caller's business). Comment
    lines (``#`` in the first column) may appear anywhere; blank lines only
    before the header and at the end.

    The work is vectorised: comments are found with ``bytes.find`` (one call
    per comment, not per row), fields per row are counted with numpy on the
    bytes, and the numbers are converted by ``numpy.fromstring`` in C.
    """
    if isinstance(text, str):
        raw = text.encode("utf-8", "surrogateescape")
    else:
        raw = bytes(text)
    if b"\r" in raw:
        raw = raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    body, comments, comment_lines = _strip_comments(raw)
    lead, stop = 0, len(body)  # blank lines before the header and at the end (indices, not copies)
    while lead < stop and body[lead] == 10:
        lead += 1
    while stop > lead and body[stop - 1] == 10:
        stop -= 1
    header_end = body.find(b"\n", lead, stop)
    header_end = stop if header_end < 0 else header_end
    header_raw, data = body[lead:header_end], body[header_end + 1:stop]
    if not header_raw.strip():
        raise ProtocolError(f"{where}: no header line; the first line that is not a '#' comment must name the "
                            f"columns (t,p0_x,p0_y,p0_z,v0_x,...)")
    try:
        header = tuple(name.strip() for name in header_raw.decode("utf-8").split(","))
    except UnicodeDecodeError:
        header = ("",)  # reported below, with its line
    buffer = np.frombuffer(data, dtype=np.uint8)
    newlines = np.flatnonzero(buffer == 10)
    n_rows = len(newlines) + 1 if data else 0
    # Original 1-based line number of the header and of each row: the lines that are not comments, in order.
    lines = np.arange(1, lead + 2 + n_rows + len(comment_lines), dtype=np.int64)
    lines = np.delete(lines, [c - 1 for c in comment_lines if c <= len(lines)])
    header_line, data_lines = int(lines[lead]), lines[lead + 1:lead + 1 + n_rows]
    if header == ("",) and header_raw.strip():
        raise ProtocolError(f"{where}: header (line {header_line}) is not UTF-8 text; write plain ASCII CSV")
    _check_header(header, f"{where}: header (line {header_line})")
    n_columns = len(header)
    if not data:
        return Table(header, np.zeros((0, n_columns)), comments, np.zeros(0, dtype=np.int64), header_line)
    starts = np.concatenate(([0], newlines + 1))
    commas = np.flatnonzero(buffer == 44)
    fields = np.diff(np.searchsorted(commas, np.append(starts, len(buffer)))) + 1  # commas per row, + 1
    if (fields != n_columns).any():
        k = int(np.argmax(fields != n_columns))
        end = newlines[k] if k < len(newlines) else len(buffer)
        row = data[starts[k]:end]
        what = "is empty" if not row.strip() else f"has {int(fields[k])} fields"
        hint = (f"column {header[int(fields[k])]!r} is missing" if fields[k] < n_columns
                else f"there is a field after the last column {header[-1]!r}")
        raise ProtocolError(f"{where}: line {int(data_lines[k])} (sample {k}) {what}, the header has {n_columns}; "
                            f"{hint}")
    values = _numbers(data.replace(b"\n", b","), n_rows * n_columns)
    if values is None:
        _find_bad_number(data, header, data_lines, where)
    return Table(header, values.reshape(n_rows, n_columns), comments, data_lines, header_line)


def _strip_comments(raw: bytes) -> tuple[bytes, dict[str, str], list[int]]:
    """(raw without its comment lines, the ``# key = value`` comments, the comments' 1-based line numbers).

    One ``find`` per comment line, never a pass per row in Python.
    """
    if b"#" not in raw or (not raw.startswith(b"#") and b"\n#" not in raw):  # memchr first: no '#' at all
        return raw, {}, []
    comments: dict[str, str] = {}
    lines: list[int] = []
    kept: list[bytes] = []
    position = 0           # where the text not yet kept starts
    line, counted = 1, 0   # the line number at offset `counted`
    start = 0 if raw.startswith(b"#") else _next_comment(raw, 0)
    while start is not None:
        line += raw.count(b"\n", counted, start)
        counted = start
        end = raw.find(b"\n", start)
        end = len(raw) if end < 0 else end + 1
        kept.append(raw[position:start])
        position = end
        match = _KEY_VALUE.match(raw[start:end].decode("utf-8", "replace"))
        if match:
            comments[match.group(1)] = match.group(2)
        lines.append(line)
        start = _next_comment(raw, end - 1)
    kept.append(raw[position:])
    return b"".join(kept), comments, lines


def _next_comment(raw: bytes, offset: int) -> int | None:
    found = raw.find(b"\n#", offset)
    return None if found < 0 else found + 1


def _numbers(flat: bytes, expected: int) -> np.ndarray | None:
    """The comma-separated numbers of ``flat`` as float64, or None when one is not a number (or the count is off)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(flat, dtype=np.float64, sep=",")
        except (ValueError, DeprecationWarning):
            return None
    return values if values.size == expected else None


def _check_header(header: tuple[str, ...], where: str) -> None:
    for index, name in enumerate(header):
        if not name:
            raise ProtocolError(f"{where}, column {index + 1} has no name; the header is the column names "
                                f"separated by commas, with no trailing comma")
        if _is_number(name):
            raise ProtocolError(f"{where}, column {index + 1} is the number {name!r}, not a name; the first line "
                                f"that is not a comment must name the columns (t,p0_x,p0_y,p0_z,v0_x,...)")
    seen: dict[str, int] = {}
    for index, name in enumerate(header):
        if name in seen:
            raise ProtocolError(f"{where}: column {name!r} appears twice (columns {seen[name] + 1} and {index + 1})")
        seen[name] = index


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _find_bad_number(data: bytes, header: tuple[str, ...], data_lines: np.ndarray, where: str) -> None:
    """Raise ProtocolError naming the first field that is not a number (the slow path, only for bad text)."""
    for sample, row in enumerate(data.split(b"\n")):
        for index, token in enumerate(row.split(b",")):
            text = token.decode("utf-8", "replace")
            if _numbers(token, 1) is None:
                raise ProtocolError(f"{where}: line {int(data_lines[sample])} (sample {sample}), column "
                                    f"{header[index]!r}: {text.strip()!r} is not a number")
    raise ProtocolError(f"{where}: a field is not a number")


# -- a table as a trajectory --------------------------------------------------------


@dataclass(frozen=True)
class StateColumns:
    """A table's columns matched to a scene.

    t : (n,) s; positions, velocities : (n, P, 3) m, m/s; forces : (n, C, 3) N
    (NaN for a constraint whose columns are absent), or None when the table
    has no force columns at all.
    """

    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    forces: np.ndarray | None


def match_columns(table: Table, scene: Scene, where: str = "the CSV") -> StateColumns:
    """Split ``table`` into time, state and forces for ``scene``; ProtocolError naming a missing or extra column.

    Columns are found by name, in any order. Required: ``t`` and the six
    state columns of every particle. Optional: the three force columns of
    any constraint (all three or none), ``energy`` and ``constraint_error``.
    """
    n_p, n_c = len(scene.particles), len(scene.constraints)
    index = {name: k for k, name in enumerate(table.header)}
    where = f"{where}: header (line {table.header_line})"
    required = state_columns(n_p)
    missing = [name for name in required if name not in index]
    if missing:
        raise ProtocolError(f"{where}, missing column {missing[0]!r}"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
                            + f"; the scene {scene.name!r} has {n_p} particle(s): write t and p{{i}}_x..z, "
                              f"v{{i}}_x..z for i = 0..{n_p - 1}")
    known = set(required) | set(force_columns(n_c)) | set(DERIVED_COLUMNS)
    for k, name in enumerate(table.header):
        if name not in known:
            raise ProtocolError(f"{where}, extra column {name!r} (column {k + 1}); {_extra_hint(name, n_p, n_c)}")
    reported = [c for c in range(n_c) if any(f"f{c}_{a}" in index for a in _AXES)]
    for c in reported:
        for a in _AXES:
            if f"f{c}_{a}" not in index:
                raise ProtocolError(f"{where}, missing column 'f{c}_{a}'; write all three of f{c}_x, f{c}_y, f{c}_z "
                                    f"or none of them")
    values = table.values
    n = table.n_rows
    state = values[:, [index[name] for name in required[1:]]].reshape(n, n_p, 2, 3)
    forces = None
    if reported:
        forces = np.full((n, n_c, 3), np.nan)
        forces[:, reported] = values[:, [index[f"f{c}_{a}"] for c in reported for a in _AXES]].reshape(
            n, len(reported), 3)
    return StateColumns(values[:, index["t"]].copy(), state[:, :, 0].copy(), state[:, :, 1].copy(), forces)


def _extra_hint(name: str, n_p: int, n_c: int) -> str:
    m = re.fullmatch(r"([pvf])(\d+)_([xyz])", name)
    if m and m.group(1) in "pv":
        return f"the scene has particles 0..{n_p - 1}"
    if m:
        return f"the scene has constraints 0..{n_c - 1}" if n_c else "the scene has no constraints"
    return ("the columns are t, p{i}_x..z and v{i}_x..z per particle, optionally f{k}_x..z per constraint, "
            "energy, constraint_error")


def check_times(t: np.ndarray, sample_steps: np.ndarray, dt: float, lines: np.ndarray, where: str,
                upto: int | None = None) -> None:
    """ProtocolError naming the first row whose time is not ``sample_steps[k] · dt`` (to :data:`TIME_TOLERANCE`).

    t : (n,) s from the table; sample_steps : (≥ n,); lines : (n,) line numbers;
    upto : check only the first ``upto`` rows (those before a non-finite state),
    plus the row at ``upto`` when its time is finite.
    """
    n = len(t)
    stop = n if upto is None else min(n, upto + 1)
    expected = np.asarray(sample_steps[:stop], dtype=np.float64) * dt
    got = t[:stop]
    bad = ~(np.abs(got - expected) <= TIME_TOLERANCE * np.maximum(np.abs(expected), dt))
    if upto is not None and upto < n and not math.isfinite(got[-1]):
        bad[-1] = False  # the first non-finite row may have a non-finite time too
    if bad.any():
        k = int(np.argmax(bad))
        raise ProtocolError(
            f"{where}: line {int(lines[k])} (sample {k}), column 't': {float(got[k])!r} s is not the time of sample step "
            f"{int(sample_steps[k])} ({float(expected[k])!r} s = {int(sample_steps[k])} x dt); write one row per entry of "
            f"sample_steps, t = step * dt"
        )


def check_initial_state(scene: Scene, positions: np.ndarray, velocities: np.ndarray, where: str, line: int,
                        hint: str, tolerance: float = 1e-6) -> None:
    """ProtocolError naming the column when the first row (positions, velocities: (P, 3)) is not the scene's initial state.

    tolerance : a fraction of the scene's length L (positions) or of its speed
    scale max(|v0|, √(gL)) (velocities), as engines.adapter checks every engine.
    hint : what to do about it (differs between a program and a file).
    """
    length = scene.characteristic_length
    speed = max(float(np.abs(scene.initial_velocities).max()),
                math.sqrt(float(np.linalg.norm(scene.gravity)) * length), 1e-3)
    for name, got, want, scale, unit in (("p", positions, scene.initial_positions, length, "m"),
                                         ("v", velocities, scene.initial_velocities, speed, "m/s")):
        off = np.abs(np.asarray(got) - want)
        if not np.isfinite(off).all():
            continue  # unstable from the start: the caller reports it
        if off.max() > tolerance * scale:
            i, a = np.unravel_index(int(np.argmax(off)), off.shape)
            raise ProtocolError(
                f"{where}: line {line} (sample 0), column '{name}{i}_{'xyz'[a]}': {float(got[i, a])!r} {unit} is not "
                f"the initial state of {scene.name!r} ({float(want[i, a])!r} {unit}); {hint}"
            )


def first_nonfinite_row(positions: np.ndarray, velocities: np.ndarray) -> int | None:
    """Index of the first row whose state (positions (n, P, 3), velocities (n, P, 3)) is not all finite, or None."""
    finite = np.isfinite(positions).all(axis=(1, 2)) & np.isfinite(velocities).all(axis=(1, 2))
    return None if finite.all() else int(np.argmin(finite))
