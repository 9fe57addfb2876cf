"""``xval simulate``: one scene, one engine, one time step, written as CSV."""

from __future__ import annotations

import re
import shlex
import types
from pathlib import Path

import click
import numpy as np

from compare.cli import Seconds, engine_option_option, model_option, output_path, param_option, parse_assignments, scene_from_params
from compare.results.export import trajectory_columns, trajectory_csv
from engines.files import STDOUT, atomic_write_text, check_writable
from compare.results.measure import apply_bounds
from compare.results.metrics import Bounds, largest, relative_drift
from engines import registry
from engines.adapter import DEFAULT_SAMPLE_INTERVAL, check_time_step
from engines.external.command import command_engine
from engines.errors import UserError
from engines.scene.limits import check_case_size
from engines.scene.trajectory import trajectory_constraint_error, trajectory_energy
from engines.stdio import capture_output


def parse_bounds(pairs: tuple[str, ...]) -> Bounds:
    """``("energy_drift=2", "constraint_error=0.01")`` -> Bounds; UserError naming the bound and its range."""
    values = {"energy_drift": Bounds.energy_drift, "constraint_error": Bounds.constraint_error}
    for name, raw in parse_assignments(pairs, "--bounds").items():
        if name not in values:
            raise UserError(f"--bounds: unknown bound {name!r}; the bounds are: {', '.join(values)}")
        try:
            value = float(raw)
        except ValueError:
            raise UserError(f"--bounds: {name} must be a positive number, got {raw!r}") from None
        if not np.isfinite(value) or value <= 0:
            raise UserError(f"--bounds: {name} must be a positive finite number, got {raw!r}")
        values[name] = value
    return Bounds(**values)


@click.command("simulate")
@click.argument("scene_name", metavar="SCENE", required=False)
@model_option("Simulate")
@click.option("--engine", "engine_id", default=None,
              help="ENGINE or ENGINE/VARIANT, e.g. mujoco/hinge-rk4 (see 'xval engines'); without it (and without "
                   "--command), the reference, which says so.")
@click.option("--dt", required=True, help="Time step in seconds, e.g. 1e-3.")
@click.option("--duration", default=None, help="Simulated time in seconds (default: the scene's).")
@param_option()
@engine_option_option()
@click.option("--sample-interval", default=None, type=Seconds(),
              help="Seconds between stored samples (default 0.01; at least one step).")
@click.option("--command", "program", default=None, metavar='"PROG ARGS"',
              help="Run an outside program speaking the process protocol (docs/protocol.md) instead of --engine; "
                   "split like a shell would, run without one, in the current directory.")
@click.option("--forces", is_flag=True, help="Also write the constraint forces f{k}_x..z (NaN when not reported).")
@click.option("--bounds", "bounds", multiple=True, metavar="NAME=VALUE",
              help=f"Past these an ok run is unstable (exit 1), as in a suite's [bounds]: energy_drift "
                   f"(x E*, default {Bounds.energy_drift:g}) and constraint_error (x L, default "
                   f"{Bounds.constraint_error:g}); repeatable.")
@click.option("--output", required=True, callback=output_path,
              help="CSV file to write, or - for standard output (the summary then goes to standard error).")
@click.option("--lock", "lock", multiple=True, metavar="JOINT",
              help="With --model: weld JOINT at its initial value (repeatable), e.g. a gripper's fingers.")
@click.option("--verbose", "-v", is_flag=True,
              help="Also show what the engine's library printed while it ran (its first and last lines).")
def command(scene_name, model, engine_id, dt, duration, params, options, sample_interval, program, forces, bounds,
            output, lock, verbose) -> None:
    """Simulate SCENE with one engine and write one CSV row per sample.

    What the engine's library prints while it runs (C/C++ warnings, Python
    warnings) is caught and counted in the summary line; --verbose shows it.
    Exit code 0 when the run ends ok, 1 when it ends unstable (a non-finite
    state, or past the bounds) or failed (the CSV still holds the samples up
    to the end; for --command, the line names the command, its exit code and
    its last stderr line), 2 for bad input.
    """
    overrides = parse_assignments(params, "--param")
    if (scene_name is None) == (model is None):
        raise UserError("give a catalog SCENE (see 'xval scenes') or --model MODEL, one of them")
    if lock and model is None:
        raise UserError("--lock welds joints of a model; give --model MODEL")
    if model is not None:
        scene = _model_scene(model, overrides, duration, lock)
    else:
        if duration is not None:
            overrides["duration"] = duration
        scene = scene_from_params(scene_name, overrides)
    check_time_step(dt, scene.duration)
    check_case_size(len(scene.particles), scene.duration, float(dt),
                    DEFAULT_SAMPLE_INTERVAL if sample_interval is None else sample_interval)
    limits = parse_bounds(bounds)
    unnamed = engine_id is None and program is None
    if program is not None:
        engine, variant = _command_engine(program, engine_id)
    else:
        engine, variant = registry.resolve(engine_id or "reference")
    engine_options = parse_assignments(options, "--option")
    engine.check(scene, variant, engine_options)
    path = check_writable(output)

    # What the engine prints is caught, so standard output carries the CSV alone (--output -).
    with capture_output() as captured:
        trajectory = engine.simulate(
            scene, float(dt), variant=variant, options=engine_options, sample_interval=sample_interval
        )
    if trajectory.n_samples:
        text = trajectory_csv(scene, trajectory, forces=forces)
    else:  # failed before its first sample: the header alone
        text = ",".join(trajectory_columns(scene, forces)) + "\n"
    atomic_write_text(path, text)

    info = trajectory.info
    status, message = info.status, info.message
    where = "standard output" if str(path) == STDOUT else str(path)
    details = ""
    if trajectory.n_samples:
        with np.errstate(all="ignore"):  # a run that blew up overflows here; its numbers say so
            drift = largest(relative_drift(scene, trajectory_energy(scene, trajectory)))
            error = largest(trajectory_constraint_error(scene, trajectory))
        status, message = apply_bounds(status, message, types.SimpleNamespace(energy_drift=drift, constraint_error=error),
                                       limits, scene)
        details = (
            f"; {info.steps} steps in {info.wall_time:.3g} s; energy drift {drift:.2e} E*;"
            f" constraint error {error:.2e} m"
        )
    summary = f"{info.variant} on {scene.name}: {status}, {trajectory.n_samples} samples to {where}{details}"
    if unnamed:
        summary = f"no --engine given: ran the reference ({info.variant}). " + summary
    if message:
        summary += f" ({message})"
    printed = captured.output
    if printed:
        summary += (f"; the engine printed {printed.lines} line{'s' if printed.lines != 1 else ''}"
                    + (":" if verbose else " (--verbose shows them)"))
    click.echo(summary, err=str(path) == STDOUT)
    if verbose and printed:
        click.echo("\n".join(f"    {line}" for line in printed.describe()), err=str(path) == STDOUT)
    if status != "ok":
        raise click.exceptions.Exit(1)


def _command_engine(program: str, engine_id: str | None):
    """The command engine for ``--command "prog args"`` (label: the program's file name), and its variant."""
    if engine_id is not None:
        raise UserError("--command and --engine are alternatives; give one of them")
    argv = _split(program)
    # Label it by the program's file: the first argument that is a file here (solvers/bead.py after python3).
    named = next((a for a in argv if "/" in a or Path(a).is_file()), argv[0])
    label = re.sub(r"[^A-Za-z0-9._-]+", "-", Path(named).name).strip("-") or "program"
    engine = command_engine(label, argv, Path.cwd(), capabilities=["3d"], where="--command")
    return engine, engine.spec.label


def _split(program: str) -> list[str]:
    try:
        argv = shlex.split(program)
    except ValueError as exc:
        raise UserError(f"--command: cannot split {program!r}: {exc}") from None
    if not argv:
        raise UserError('--command: give the program and its arguments, e.g. --command "./build/bead --fast"')
    return argv


def _model_scene(model: str, overrides: dict[str, str], duration: str | None, lock: tuple[str, ...] = ()):
    """The model scene of ``--model`` with ``--param q0.JOINT=VALUE`` / ``v0.JOINT=VALUE`` (degrees or metres,
    rad/s or m/s; a ball joint's or floating base's a list, ``q0.J=0,0,0.38,0.92``), ``--param g=VALUE`` (m/s²) and ``--param base=floating`` (a URDF's root); UserError naming a
    parameter that is none of these."""
    from engines.model.scene import DEFAULT_DURATION, model_scene
    from engines.model.loaded import GRAVITY

    state: dict[str, dict[str, str]] = {"q0": {}, "v0": {}}
    gravity: str | float = GRAVITY
    root_joint = "fixed"
    for name, value in overrides.items():
        if name == "g":
            gravity = value
            continue
        if name == "base":
            root_joint = value
            continue
        kind, _, joint = name.partition(".")
        if kind not in state or not joint:
            raise UserError(f"--param {name}: a model takes q0.JOINT=VALUE (degrees, metres for prismatic joints), "
                            f"v0.JOINT=VALUE (rad/s, m/s), g=VALUE (m/s²) and base=fixed|floating (a URDF's root)")
        state[kind][joint] = value
    try:
        seconds = DEFAULT_DURATION if duration is None else float(duration)
    except ValueError:
        raise UserError(f"--duration must be a number of seconds, got {duration!r}") from None
    return model_scene(Path(model.partition(":")[2] or model).stem, model, q0=state["q0"], v0=state["v0"],
                       duration=seconds, g=gravity, lock=lock, root_joint=root_joint)
