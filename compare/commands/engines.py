"""``xval engines``: each engine (built-in, then installed plugins), where it comes from, whether it loads,
its version, variants and capabilities."""

from __future__ import annotations

import click

from engines import registry


@click.command("engines")
def command() -> None:
    """List engines (built-ins, then plugins registered under the xval.engines entry point), their origin,
    versions, variants and what they can express. A plugin that cannot load is listed as unavailable with the reason.
    """
    for found in registry.statuses():
        origin = f"built-in: {found.origin}" if found.kind == "built-in" else found.origin
        if found.engine is None:
            click.echo(f"{found.name}: unavailable  [{origin}]")
            click.echo(f"    {found.reason}")
            click.echo("")
            continue
        engine = found.engine
        capabilities = ", ".join(sorted(engine.capabilities)) or "planar scenes only"
        click.echo(f"{found.name} {engine.version()}  [{origin}]  can express: {capabilities}")
        for variant in engine.variants:
            doc = engine.variant_docs.get(variant, "")
            click.echo(f"    {found.name}/{variant:<28} {doc}")
        if engine.options:
            click.echo(f"    options: {', '.join(engine.options)}")
        click.echo("")
    click.echo("An engine that is not installed as a plugin can be named by path in a suite: package.module:ATTRIBUTE")
