"""Grading trajectories a user already has (protocol CSV files) against xval's reference.

A file may come from any program, at any time step and any sample times:
the reference is evaluated at the file's own times (its dense DOP853
solution), and the metrics are compare's own (:func:`compare.results.metrics.case_metrics`),
so the numbers mean what they mean in ``xval show``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from engines.external import protocol
from engines.adapter import INITIAL_STATE_TOLERANCE
from engines.errors import UserError
from engines.reference.reference import DEFAULT_ATOL, DEFAULT_RTOL, solve
from engines.model.scene import ModelScene
from engines.scene.scene import Scene
from engines.scene.trajectory import RunInfo, Status, Trajectory

from compare.results import declared
from compare.results.metrics import DEFAULT_DELTA, case_metrics

#: Metric names of a score, as ``xval show --format json`` names them (force errors only with force columns);
#: any declared metric with a ``compute`` function (compare.results.declared) follows them.
SCORE_METRICS = (
    "position_error_final", "position_error_rms", "position_error_linf", "divergence_time",
    "energy_drift", "constraint_error", "constraint_force_error", "constraint_force_error_relative",
)
#: |t[0]| accepted as "the first row is t = 0", relative to the file's last time.
START_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Loaded:
    """One file read and matched to the scene: its columns, where it came from, and what it says of itself."""

    path: str
    state: protocol.StateColumns
    lines: np.ndarray
    comments: dict[str, str]
    joint_states: np.ndarray | None = None  # (n, 2·nq) of a model scene's file


def load(path: str | Path, scene: Scene) -> Loaded:
    """Read ``path`` as protocol CSV for ``scene``; UserError (exit 2) naming the file, line and column."""
    where = str(path)
    try:
        text = Path(path).read_bytes()
    except FileNotFoundError:
        raise UserError(f"{where}: no such file; give CSV files written by your program or by 'xval simulate'") from None
    except OSError as exc:
        raise UserError(f"{where}: cannot read it ({exc.strerror})") from None
    try:
        table = protocol.read_csv(text, where)
        if scene.is_model:
            return _load_model_run(where, table, scene)
        state = protocol.match_columns(table, scene, where)
    except protocol.ProtocolError as exc:
        raise UserError(str(exc)) from None
    loaded = Loaded(where, state, table.data_lines, dict(table.comments))
    _check_times(loaded)
    _check_start(loaded, scene)
    return loaded


def _load_model_run(where: str, table: protocol.Table, scene: ModelScene) -> Loaded:
    """A model run's file: its joint columns, and the link frames computed from them (rows up to the
    first non-finite one); UserError when row 0 is not the scene's (q0, v0)."""
    from compare.results.model_csv import joint_states

    states = joint_states(table, scene, where)
    nq = states.shape[1] // 2
    n = len(states)
    positions = np.full((n, len(scene.frames), 3), np.nan)
    velocities = positions.copy()
    finite = np.flatnonzero(np.isfinite(states).all(axis=1))
    if len(finite):
        positions[finite], velocities[finite] = scene.frame_states(states[finite, :nq], states[finite, nq:])
    state = protocol.StateColumns(table.column("t").copy(), positions, velocities, None)
    loaded = Loaded(where, state, table.data_lines, dict(table.comments), states)
    _check_times(loaded)
    start = np.concatenate([scene.initial_q, scene.initial_v])
    if not np.allclose(states[0], start, rtol=0, atol=INITIAL_STATE_TOLERANCE):
        raise UserError(f"{where}: line {int(table.data_lines[0])} (sample 0): q and v are not the scene's initial "
                        f"state; pass the --param q0.JOINT / v0.JOINT values the file was made with")
    return loaded


def _check_times(loaded: Loaded) -> None:
    t, lines, where = loaded.state.t, loaded.lines, loaded.path
    if len(t) == 0:
        raise UserError(f"{where}: no rows; write one row per sample, the first at t = 0")
    finite = np.isfinite(t)
    if not finite.all():
        k = int(np.argmin(finite))
        raise UserError(f"{where}: line {int(lines[k])} (sample {k}), column 't': {float(t[k])!r} is not a time; "
                        f"write the sample's time in seconds")
    if abs(t[0]) > START_TOLERANCE * max(abs(t[-1]), 1.0):
        raise UserError(f"{where}: line {int(lines[0])} (sample 0), column 't': the first row is at t = {float(t[0])!r} s; "
                        f"the first row must be the initial state at t = 0")
    steps = np.diff(t)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0)) + 1
        raise UserError(f"{where}: line {int(lines[k])} (sample {k}), column 't': {float(t[k])!r} s does not follow "
                        f"{float(t[k - 1])!r} s; rows must be in increasing time")


def _check_start(loaded: Loaded, scene: Scene) -> None:
    """UserError when row 0 is not ``scene``'s initial state (another scene, or other --param values)."""
    q0, v0 = loaded.state.positions[0], loaded.state.velocities[0]
    if not (np.isfinite(q0).all() and np.isfinite(v0).all()):
        raise UserError(f"{loaded.path}: line {int(loaded.lines[0])} (sample 0): the initial state is not finite")
    try:
        protocol.check_initial_state(scene, q0, v0, loaded.path, int(loaded.lines[0]),
                                     "pass the scene parameters the file was made with (--param NAME=VALUE)",
                                     INITIAL_STATE_TOLERANCE)
    except protocol.ProtocolError as exc:
        raise UserError(str(exc)) from None


def score(paths: Sequence[str | Path], scene: Scene, *, delta: float = DEFAULT_DELTA,
          rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> list[dict[str, Any]]:
    """One row per file: ``file``, ``scene``, ``status``, ``message``, ``n_samples``, ``t_end`` (s) and
    :data:`SCORE_METRICS` (None when not defined: force errors without force columns, divergence never).

    Every file is read and checked before the reference is solved (once, to the
    latest time of any file). A file whose state turns non-finite is
    ``unstable``: it is graded on the rows before, as a suite grades an
    unstable run.
    """
    loaded = [load(path, scene) for path in paths]
    t_end = max(float(item.state.t[-1]) for item in loaded)
    solution = solve(scene.with_duration(max(t_end, 1e-9)), rtol, atol)
    return [_row(item, scene, solution, delta) for item in loaded]


def _row(item: Loaded, scene: Scene, solution: Any, delta: float) -> dict[str, Any]:
    state = item.state
    first_bad = protocol.first_nonfinite_row(state.positions, state.velocities)
    n = len(state.t) if first_bad is None else first_bad
    forces = None if state.forces is None else state.forces[:n]
    info = RunInfo(engine="file", variant=f"file/{Path(item.path).name}", engine_version=item.comments.get("version", ""),
                   dt=math.nan)
    joints = None if item.joint_states is None else item.joint_states[:n]
    trajectory = Trajectory(state.t[:n], state.positions[:n], state.velocities[:n], info, forces, joints)
    ref_positions, _, ref_forces = solution.at(state.t)
    metrics, series = case_metrics(scene, trajectory, ref_positions, ref_forces, scheduled_times=state.t,
                                   wall_times=[], delta=delta)
    computed = declared.computed_extras(declared.MetricInputs(scene, trajectory, ref_positions[:n],
                                                              series.position_error))
    values = {**metrics.to_dict(), **computed}
    extra = [name for name in computed if name not in SCORE_METRICS]
    status, message = Status.OK, ""
    if first_bad is not None:
        status = Status.UNSTABLE
        message = f"non-finite state at t = {state.t[first_bad]:.6g} s (line {int(item.lines[first_bad])})"
    return {
        "file": item.path,
        "scene": scene.name,
        "status": status.value,
        "message": message,
        "n_samples": int(n),
        "t_end": float(state.t[-1]),
        **{name: values.get(name) for name in (*SCORE_METRICS, *extra)},
    }
