"""``xval probe``: hidden damping, told apart from integrator error (compare/stability/dissipation.py)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from compare.cli import engine_option_option, param_option, parse_assignments, scene_from_params
from engines.files import atomic_write_text, check_writable
from compare.stability.dissipation import DEFAULT_DTS, DEFAULT_DURATION, Dissipation, probe
from engines import registry
from engines.errors import UserError


def table(result: Dissipation) -> str:
    """The probe as text: one line per dt, then the extrapolation and the verdict."""
    lines = [f"{result.engine} on {result.scene} ({result.duration:g} s)"
             + (f", options {', '.join(f'{k}={v}' for k, v in result.options.items())}" if result.options else ""),
             f"{'dt (s)':>10}  {'status':<9} energy-loss rate (E*/s)"]
    for p in result.points:
        rate = f"{p.rate:+.3e}" if p.rate is not None else (p.message or "-")
        lines.append(f"{p.dt:>10.3g}  {p.status:<9} {rate}")
    if result.rate is None:
        lines.append(f"no verdict: {result.reason}")
    else:
        lines.append(f"extrapolated to dt -> 0: {result.rate:+.3e} ± {result.uncertainty:.2e} E*/s")
        lines.append(f"hidden_dissipation: {str(result.hidden_dissipation).lower()}")
        lines.append(f"rule: {result.rule}")
    return "\n".join(lines)


@click.command("probe")
@click.argument("engine_id", metavar="ENGINE/VARIANT")
@engine_option_option()
@click.option("--scene", "scene_name", default="bead", show_default=True, help="Catalog scene (see 'xval scenes').")
@param_option()
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=DEFAULT_DURATION,
              show_default=True, help="Seconds simulated at each dt.")
@click.option("--dt", "dts", multiple=True, type=click.FloatRange(min=0, min_open=True),
              help=f"Time step (s); repeatable, at least 3 (default: {', '.join(f'{d:g}' for d in DEFAULT_DTS)}).")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
@click.option("--output", default=None, metavar="DIR",
              help="Also store the result as DIR/probe-ENGINE-VARIANT.json (a results directory: "
                   "'xval report DIR' lists hidden dissipation among its problems).")
def command(engine_id, options, scene_name, params, duration, dts, fmt, output) -> None:
    """Is ENGINE/VARIANT's energy loss its time step, or damping it adds on its own?

    Runs the scene at several time steps over a long horizon, measures the
    energy-loss rate at each (E* per second) and extrapolates it to dt -> 0:
    hidden_dissipation is true when that rate is clearly above zero (the rule
    is printed). Exit 0 with a verdict, 1 without one (too few runs ended ok), 2 for bad input.
    """
    overrides = parse_assignments(params, "--param")
    overrides["duration"] = duration
    scene = scene_from_params(scene_name, overrides)
    engine, variant = registry.resolve(engine_id)
    engine_options = parse_assignments(options, "--option")
    engine.check(scene, variant, engine_options)
    steps = tuple(dts) or DEFAULT_DTS
    if len(set(steps)) < 3:
        raise UserError(f"--dt: give at least 3 different time steps (got {len(set(steps))}), or none for the defaults")
    target = None
    if output is not None:
        name = f"probe-{engine.name}-{variant}.json".replace("/", "-")
        target = check_writable(Path(output) / name)
    result = probe(engine_id if "/" in engine_id else f"{engine_id}/{variant}", scene, engine_options, steps)
    document = json.dumps(result.to_dict(), indent=2)
    if target is not None:
        atomic_write_text(target, json.dumps(result.to_file(), indent=2) + "\n")
    click.echo(document if fmt == "json" else table(result))
    if result.hidden_dissipation is None:
        raise click.exceptions.Exit(1)
