"""``xval engines``: each engine, whether it is installed, its version, variants and capabilities."""

from __future__ import annotations

import click

from engines import registry


@click.command("engines")
def command() -> None:
    """List engines, their versions, variants and what they can express."""
    for name in registry.engine_names():
        found = registry.status(name)
        if found.engine is None:
            click.echo(f"{name}: unavailable ({found.reason})")
            click.echo("")
            continue
        engine = found.engine
        capabilities = ", ".join(sorted(engine.capabilities)) or "planar scenes only"
        click.echo(f"{name} {engine.version()}  [{found.origin}]  can express: {capabilities}")
        for variant in engine.variants:
            doc = engine.variant_docs.get(variant, "")
            click.echo(f"    {name}/{variant:<28} {doc}")
        if engine.options:
            click.echo(f"    options: {', '.join(engine.options)}")
        click.echo("")
