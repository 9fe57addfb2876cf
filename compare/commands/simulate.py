"""``xval simulate``: one scene, one engine, one time step, written as CSV."""

from __future__ import annotations

import click

from compare.cli import parse_assignments
from compare.results.export import trajectory_csv
from compare.results.files import atomic_write_text, check_writable
from compare.results.metrics import constraint_error, energy_drift
from engines import catalog, registry
from engines.adapter import check_time_step


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
@click.option("--output", required=True, help="CSV file to write.")
def command(scene_name, engine_id, dt, duration, params, options, sample_interval, output) -> None:
    """Simulate SCENE with one engine and write one CSV row per sample.

    Exit code 0 when the run ends ok, 1 when it ends unstable or failed (the
    CSV still holds the samples up to the end), 2 for bad input.
    """
    overrides = parse_assignments(params, "--param")
    if duration is not None:
        overrides["duration"] = duration
    scene = catalog.build(scene_name, overrides)
    check_time_step(dt, scene.duration)
    engine, variant = registry.resolve(engine_id)
    engine_options = parse_assignments(options, "--option")
    engine.check(scene, variant, engine_options)
    path = check_writable(output)

    trajectory = engine.simulate(
        scene, float(dt), variant=variant, options=engine_options, sample_interval=sample_interval
    )
    atomic_write_text(path, trajectory_csv(scene, trajectory))

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
