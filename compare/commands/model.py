"""``xval model check``: where each engine's import of a robot model disagrees with Pinocchio's dynamics."""

from __future__ import annotations

import json

import click

from compare.model.parity import QUANTITIES, TOLERANCE, ParityReport, check
from engines.model.importers import ENGINES


@click.group("model")
def command() -> None:
    """Robot models (URDF, MJCF): how each engine imports them."""


@command.command("check")
@click.argument("model", metavar="MODEL")
@click.option("--engine", "engines", multiple=True, type=click.Choice(ENGINES),
              help="Engine to compare with Pinocchio (repeatable; default: all).")
@click.option("--states", default=100, show_default=True, type=click.IntRange(1, 100000),
              help="Number of sampled states (q within limits, v, tau).")
@click.option("--seed", default=0, show_default=True, type=int, help="Seed of the sampled states.")
@click.option("--balance-inertia", is_flag=True,
              help="Let MuJoCo balance inertias that violate A + B >= C (its balanceinertia) instead of refusing them.")
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True)
def check_command(model, engines, states, seed, balance_inertia, output_format) -> None:
    """Compare each engine's M(q), bias b(q, v) and forward dynamics with Pinocchio's on MODEL.

    MODEL is a URDF or MJCF file, or pybullet_data:<path> for a model PyBullet
    ships (e.g. pybullet_data:kuka_iiwa/model.urdf). Exit code 0 when every
    engine agrees (relative difference <= 1e-6 in all three), 1 when one does
    not (or cannot load the file), 2 for bad input.
    """
    report = check(model, tuple(engines) or ENGINES, states=states, seed=seed, balance_inertia=balance_inertia)
    click.echo(json.dumps(report.to_dict(), indent=1, ensure_ascii=False) if output_format == "json" else render(report))
    raise click.exceptions.Exit(report.exit_code)


def render(report: ParityReport) -> str:
    lines = [f"model {report.model} ({report.name}: {len(report.moving_joints)} moving joints), model reference "
             f"{report.model_reference.engine} {report.model_reference.version}, {report.states} states "
             f"(seed {report.seed})"]
    header = ["engine", "version", "loaded", "M", "bias", "forward", "agrees"]
    rows = [[e.engine, e.version, "yes" if e.loaded else "no",
             *(_cell(getattr(e, q)) for q in QUANTITIES), "yes" if e.agrees else "no"] for e in report.engines]
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header))]
    lines += ["  ".join(c.ljust(w) if k < 3 else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths))).rstrip()
              for r in [header, *rows]]
    lines.append(f"M, bias, forward: largest |engine - {report.model_reference.engine}| over states and entries, divided by "
                 f"the largest |{report.model_reference.engine}|; agrees when all three are <= {TOLERANCE:g}")
    for e in report.engines:
        if e.message:
            lines.append(f"{e.engine}: {e.message}")
    if report.diagnosis or report.model_reference.diagnosis:
        lines.append("diagnosis (mass properties at q = 0 in the world frame, against the file):")
        lines += [f"  {line}" for line in (*report.diagnosis, *report.model_reference.diagnosis)]
    lines += [f"note: {note}" for note in report.notes]
    return "\n".join(lines)


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.1e}"
