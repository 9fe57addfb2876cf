"""``xval scenes``: the catalog, with every parameter's default and unit."""

from __future__ import annotations

import click

from engines.scene.catalog import CATALOG


@click.command("scenes")
def command() -> None:
    """List the catalog scenes and their parameters (angles in degrees from the downward vertical)."""
    for entry in CATALOG.values():
        click.echo(f"{entry.name}: {entry.doc}")
        for p in entry.parameters:
            default = f"{p.default:g}" if isinstance(p.default, float) else str(p.default)
            unit = f" {p.unit}" if p.unit else ""
            click.echo(f"    {p.name:<10} = {default:<8}{unit:<8} {p.doc}")
        click.echo("")
