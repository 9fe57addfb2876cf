"""A blow-up is ``unstable`` in every adapter, with one line naming the cause, never ``failed``.

Engines report a blown-up state three ways: a non-finite sample (Engine.simulate cuts the run there),
stopping early (MuJoCo's warnings, pymunk's runaway check), or their own finiteness check raising
(Drake's DRAKE_THROW_UNLESS(AllFinite(q_v)), which pydrake raises as SystemExit). The first two are
tested per engine in their own files; this file covers Drake, the third way, and numerical warnings.
"""

from __future__ import annotations

import numpy as np
import pytest

from engines.scene import catalog
from engines.adapter import blow_up_cause

pytest.importorskip("pydrake", reason="Drake is not installed: pip install 'xval[drake]'")


def _drake_finiteness_error() -> BaseException:
    """What pydrake raises when handed a non-finite state (its AllFinite(q_v) assertion)."""
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint, SpatialInertia

    plant = MultibodyPlant(0.0)
    body = plant.AddRigidBody("link", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
    plant.AddJoint(RevoluteJoint("pin", plant.world_frame(), body.body_frame(), [0.0, 1.0, 0.0]))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    try:
        plant.SetPositionsAndVelocities(context, np.array([np.nan, 0.0]))
    except BaseException as exc:  # SystemExit: not an Exception
        return exc
    raise AssertionError("pydrake accepted a NaN state")


def test_drakes_finiteness_assertion_is_a_blow_up_named_in_one_line():
    error = _drake_finiteness_error()
    assert "AllFinite(q_v)" in str(error) and len(str(error)) > 200  # the raw message: a C++ file path and all
    cause = blow_up_cause(error)
    assert cause == f"non-finite state (the engine's own check: {type(error).__name__}: condition 'AllFinite(q_v)' failed)"
    assert blow_up_cause(RuntimeError("the solver did not converge")) is None
    assert blow_up_cause(FloatingPointError("overflow encountered in multiply")) is not None


def test_drake_discrete_chain_32_at_a_large_step_is_unstable_not_failed():
    from engines.drake.adapter import ENGINE as DRAKE

    # suites/peers.toml's chain-32 at dt 1e-2 (the case): the discrete plant's state goes non-finite.
    scene = catalog.build("chain", {"n": 32, "length": 0.03125, "mass": 0.03125, "duration": 1.0})
    run = DRAKE.simulate(scene, 1e-2, variant="discrete")
    assert run.info.status == "unstable"
    assert run.info.message.startswith("non-finite state at t = ") and "\n" not in run.info.message
    assert 0 < run.n_samples < 101 and np.isfinite(run.positions).all()  # the samples before the blow-up are kept


def test_numerical_warnings_become_one_note_in_the_message():
    import warnings

    from engines.adapter import warning_note

    with warnings.catch_warnings(record=True) as heard:
        warnings.simplefilter("always")
        with np.errstate(all="warn"):
            big = np.array([1e200, 1e300])
            _ = big * big  # numpy's overflow warning, twice: once in the note, counted
            _ = big * big
    assert warning_note(heard) == "warnings: overflow encountered in multiply (RuntimeWarning, 2×)"
    assert warning_note([]) == ""


def test_a_run_that_overflows_numpy_keeps_the_warning_in_the_record_and_prints_nothing(tmp_path, capfd):
    from compare.run.results import load_results
    from compare.run.runner import run_suite
    from compare.suite.reader import parse_suite

    # pymunk's explicit 1 mm bead at 1e4 rad/s and a 50 ms step runs away to ~1e200 m before its runaway
    # check stops it; squaring such speeds for the energy overflows numpy.
    suite = parse_suite('name = "overflow"\nduration = 0.5\ndt = [5e-2]\n[[scenes]]\nscene = "bead"\n'
                        'parameters = { radius = 1e-3, omega0 = 1e4 }\n[[engines]]\nid = "pymunk"\n')
    with np.errstate(all="warn"):
        run_suite(suite, tmp_path / "r", jobs=1, isolate=False)
    out, err = capfd.readouterr()
    assert "Warning" not in out + err
    [record] = load_results(tmp_path / "r").records
    assert record.status.value in ("ok", "unstable")
