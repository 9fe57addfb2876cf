"""``xval score``: grade CSV files a user already has against xval's reference for a scene."""

from __future__ import annotations

import json

import click

from compare.cli import model_option, output_path, param_option, parse_assignments, scene_from_params
from engines.files import STDOUT, atomic_write_text, check_writable
from compare.results.metrics import DEFAULT_DELTA
from compare.results.score import score
from engines.errors import UserError

#: Table columns: (heading, row key).
COLUMNS = (
    ("status", "status"),
    ("samples", "n_samples"),
    ("t_end/s", "t_end"),
    ("final/m", "position_error_final"),
    ("rms/m", "position_error_rms"),
    ("linf/m", "position_error_linf"),
    ("diverged/s", "divergence_time"),
    ("drift/E*", "energy_drift"),
    ("c.err/m", "constraint_error"),
    ("force/N", "constraint_force_error"),
)


@click.command("score")
@click.argument("scene_name", metavar="SCENE", required=False)
@click.argument("files", metavar="FILE.csv...", nargs=-1)
@model_option("Grade runs (CSV columns t, q_<joint>, v_<joint>) of")
@param_option(help="Scene parameter the files were made with (see 'xval scenes'); repeatable.")
@click.option("--delta", default=DEFAULT_DELTA, show_default=True, type=float,
              help="Divergence threshold: the first t with position error > delta * L.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table",
              show_default=True, help="table: one line per file; json: a list of objects, one per file.")
@click.option("--output", default=STDOUT, show_default=True, callback=output_path, metavar="FILE",
              help="Where to write: - for standard output, or a file (never one of the FILE.csv graded).")
def command(scene_name, files, model, params, delta, output_format, output) -> None:
    """Grade CSV files from any program against the reference solution of SCENE.

    Each FILE has the columns t, p{i}_x..z, v{i}_x..z (optionally f{k}_x..z),
    any time step and any sample times, the first row at t = 0.

    The metrics are named as in 'xval show --format json'. Exit code 0 when
    every file was graded, 2 for bad input (a column that does not fit the
    scene, a first row that is not the scene's initial state).
    """
    if model is not None:  # no SCENE: every argument is a file
        files = tuple(f for f in (scene_name, *files) if f is not None)
    if not files or scene_name is None:
        raise UserError("give SCENE (or --model MODEL) and at least one FILE.csv to grade")
    target = check_writable(output, inputs=files)
    if model is not None:
        from compare.commands.simulate import _model_scene

        scene = _model_scene(model, parse_assignments(params, "--param"), None)
    else:
        scene = scene_from_params(scene_name, parse_assignments(params, "--param"))
    rows = score(files, scene, delta=delta)
    text = (json.dumps(rows, indent=1) if output_format == "json" else render(rows)) + "\n"
    if str(target) == STDOUT:
        click.echo(text, nl=False)
    else:
        atomic_write_text(target, text)


def render(rows: list[dict]) -> str:
    """A plain-text table: one line per file, then each file's message."""
    header = ["file", *(heading for heading, _ in COLUMNS)]
    body = [[row["file"], *(_cell(row[key]) for _, key in COLUMNS)] for row in rows]
    widths = [max(len(line[k]) for line in [header, *body]) for k in range(len(header))]
    lines = ["  ".join(cell.ljust(width) if k == 0 else cell.rjust(width)
                       for k, (cell, width) in enumerate(zip(line, widths))).rstrip() for line in [header, *body]]
    lines += [f"  {row['file']}: {row['message']}" for row in rows if row["message"]]
    return "\n".join(lines)


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, int):
        return str(value)
    return f"{value:.2e}"
