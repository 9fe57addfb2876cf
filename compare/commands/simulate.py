"""``xval simulate``: one scene, one engine, one time step, written as CSV."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import click

from compare.cli import parse_assignments
from compare.results.export import trajectory_csv
from compare.results.files import atomic_write_text, check_writable
from compare.results.metrics import constraint_error, energy_drift
from engines import catalog, registry
from engines.adapter import check_time_step
from engines.command import command_engine
from engines.errors import UserError


@click.command("simulate")
@click.argument("scene_name", metavar="SCENE")
@click.option("--engine", "engine_id", default="reference", show_default=True,
              help="ENGINE or ENGINE/VARIANT, e.g. mujoco/hinge-rk4 (see 'xval engines').")
@click.option("--dt", required=True, help="Time step in seconds, e.g. 1e-3.")
@click.option("--duration", default=None, help="Simulated time in seconds (default: the scene's).")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="Scene parameter (see 'xval scenes'); repeatable.")
@click.option("--option", "options", multiple=True, metavar="NAME=VALUE",
              help="Engine option (see 'xval engines'); repeatable.")
@click.option("--sample-interval", default=None, type=float,
              help="Seconds between stored samples (default 0.01; at least one step).")
@click.option("--command", "program", default=None, metavar='"PROG ARGS"',
              help="Run an outside program speaking the process protocol (docs/protocol.md) instead of --engine; "
                   "split like a shell would, run without one, in the current directory.")
@click.option("--forces", is_flag=True, help="Also write the constraint forces f{k}_x..z (NaN when not reported).")
@click.option("--output", required=True, help="CSV file to write.")
def command(scene_name, engine_id, dt, duration, params, options, sample_interval, program, forces, output) -> None:
    """Simulate SCENE with one engine and write one CSV row per sample.

    Exit code 0 when the run ends ok, 1 when it ends unstable or failed (the
    CSV still holds the samples up to the end; for --command, the line
    names the command, its exit code and its last stderr line), 2 for bad input.
    """
    overrides = parse_assignments(params, "--param")
    if duration is not None:
        overrides["duration"] = duration
    scene = catalog.build(scene_name, overrides)
    check_time_step(dt, scene.duration)
    if program is not None:
        engine, variant = _command_engine(program, engine_id)
    else:
        engine, variant = registry.resolve(engine_id)
    engine_options = parse_assignments(options, "--option")
    engine.check(scene, variant, engine_options)
    path = check_writable(output)

    trajectory = engine.simulate(
        scene, float(dt), variant=variant, options=engine_options, sample_interval=sample_interval
    )
    atomic_write_text(path, trajectory_csv(scene, trajectory, forces=forces))

    info = trajectory.info
    summary = f"{info.variant} on {scene.name}: {info.status}, {trajectory.n_samples} samples to {path}"
    if trajectory.n_samples:
        drift = energy_drift(scene, trajectory.positions, trajectory.velocities)
        error = constraint_error(scene, trajectory.positions)
        summary += (
            f"; {info.steps} steps in {info.wall_time:.3g} s; energy drift {drift:.2e} E*;"
            f" constraint error {error:.2e} m"
        )
    if info.message:
        summary += f" ({info.message})"
    click.echo(summary)
    if info.status != "ok":
        raise click.exceptions.Exit(1)


def _command_engine(program: str, engine_id: str):
    """The command engine for ``--command "prog args"`` (label: the program's file name), and its variant."""
    if engine_id != "reference":
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
