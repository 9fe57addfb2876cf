"""``xval grad``: an engine's derivatives of its outputs at T with respect to scene parameters, against the reference's."""

from __future__ import annotations

import json
import math

import click
import numpy as np

from compare.cli import Seconds, engine_option_option, model_option, param_option, parse_assignments, scene_from_params
from compare.gradients.measure import GradientCase, engine_case, reference_case
from engines import registry
from engines.adapter import check_time_step
from engines.errors import UserError
from engines.reference.sensitivity import bound_sensitivity


@click.command("grad")
@click.argument("scene_name", metavar="SCENE", required=False)
@model_option("Differentiate")
@click.option("--engine", "engine_id", default=None,
              help="ENGINE or ENGINE/VARIANT (see 'xval engines'); without it (and without --command), the reference.")
@click.option("--command", "program", default=None, metavar='"PROG ARGS"',
              help="An outside program speaking the process protocol (docs/protocol.md), differentiated by "
                   "central differences of its rollouts.")
@click.option("--dt", required=True, help="Time step in seconds, e.g. 1e-3 (the engine also runs at dt/2).")
@click.option("--duration", required=True, type=Seconds(), help="T, s: the outputs' time.")
@click.option("--wrt", required=True, metavar="P1,P2,...",
              help="Scene parameters to differentiate by (see 'xval scenes'): initial angles and rates, g, masses, "
                   "lengths; a model's q0.JOINT, v0.JOINT (a quaternion's q0 by its turns q0.JOINT.rx, .ry, .rz, a base's "
                   "position q0.BASE.x; a ball's or base's v0 per entry, v0.JOINT.wx); per SI unit (per radian for angles).")
@param_option()
@engine_option_option()
@click.option("--format", "output_format", type=click.Choice(["table", "json"]), default="table", show_default=True,
              help="table: per parameter, the error and its class; json: one object with both Jacobians.")
def command(scene_name, model, engine_id, program, dt, duration, wrt, params, options, output_format) -> None:
    """d outputs(T) / d parameters of SCENE (or of --model's q0.JOINT, v0.JOINT) from one engine (its own derivatives where it has them, central
    differences of its rollouts otherwise), against the reference's variational equations; classed correct,
    chaotic, wrong or nan (docs/gradients.md)."""
    overrides = parse_assignments(params, "--param")
    if (scene_name is None) == (model is None):
        raise UserError("give a catalog SCENE (see 'xval scenes') or --model MODEL, one of them")
    if model is not None:
        from compare.commands.simulate import _model_scene

        scene = _model_scene(model, overrides, str(duration))
    else:
        overrides["duration"] = str(duration)
        scene = scene_from_params(scene_name, overrides)
    check_time_step(dt, scene.duration)
    names = [name.strip() for name in wrt.split(",") if name.strip()]
    if program is not None:
        from compare.commands.simulate import _command_engine

        engine, variant = _command_engine(program, engine_id)
    elif engine_id is not None:
        engine, variant = registry.resolve(engine_id)
    else:
        engine, variant = None, None
    engine_options = parse_assignments(options, "--option")
    if engine is None and engine_options:
        raise UserError("--option needs --engine: the reference takes none here")
    if engine is not None:
        engine.check(scene, variant, engine_options)
    bound = bound_sensitivity(scene, names)
    if engine is None:
        case = reference_case(scene, float(dt), names, bound)
    else:
        case = engine_case(engine, variant, engine_options, scene, float(dt), names, bound)
    click.echo(json.dumps(case.to_json(), indent=1) if output_format == "json" else format_case(case))


def format_case(case: GradientCase) -> str:
    """The table: one line per parameter (its error at dt and dt/2 and class), then the whole Jacobian's."""
    half = "" if case.error_half is None else f", {_g(case.error_half)} at dt/2"
    lines = [
        f"{case.engine} on {case.scene}: d outputs({case.duration:g} s) / d ({', '.join(case.wrt)}) at dt "
        f"{case.dt:g} s, by {case.method}",
        f"{'parameter':<12} {'|J_ref| col':>12} {'rel. error':>11}  class",
    ]
    norms = np.linalg.norm(case.reference_jacobian, axis=0)
    for name, norm, error, klass in zip(case.wrt, norms, case.column_errors, case.column_classes):
        lines.append(f"{name:<12} {norm:>12.4g} {_g(error):>11}  {klass}")
    horizon = "none within the run" if case.horizon is None else f"{case.horizon:g} s"
    lines.append(f"error {_g(case.error)} (relative Frobenius at T{half}); class {case.klass}")
    if case.error_over_time is not None and case.times is not None:
        within = case.times <= (case.horizon if case.horizon is not None else case.duration)
        errors = np.nan_to_num(case.error_over_time[within & (case.times > 0)], nan=np.inf)
        if len(errors):
            worst = int(np.argmax(errors))
            lines.append(f"over time: largest error {_g(errors[worst])} at t = "
                         f"{case.times[within & (case.times > 0)][worst]:g} s (at the samples, within the horizon)")
    if case.first_nonfinite is not None:
        lines.append(f"first NaN or infinity: t = {case.first_nonfinite[0]:g} s, parameter {case.first_nonfinite[1]}")
    if case.self_consistency is not None:
        lines.append(f"self-consistency {_g(case.self_consistency)} (own derivatives against differences of own rollouts)")
    grew = "" if case.growth is None else (f", |J| grew {case.growth:.3g}x (ln of it over T: "
                                           f"{math.log(case.growth) / case.duration:.2g} /s)")
    lines.append(f"reference: own error {_g(case.reference_error)}{grew}, horizon {horizon}")
    return "\n".join(lines)


def _g(x: float) -> str:
    return f"{x:.2e}"
