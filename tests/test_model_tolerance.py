"""One tolerance for `xval model check`: M and the bias relative to their scale, q̈ within the bound that M's
conditioning gives (compare/model/tolerance.py derives it; docs/models.md states it), verdicts that no seed
changes, and a diagnosis line for every disagreement."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from compare.model.diagnosis import unexplained
from compare.model.parity import check, read_description
from compare.model.tolerance import TOLERANCE, amplification

MODELS = Path(__file__).resolve().parents[1] / "models"
FIXTURES = Path(__file__).resolve().parent / "fixtures" / "models"


def test_the_amplification_of_a_diagonal_mass_matrix_by_hand():
    """M = diag(4, 0.01), q̈ = (1, 1), S_b = 2: A = (n S_M |q̈| + √n S_b) / (λ_min S_a) = (2·4·√2 + √2·2) / 0.01."""
    a = amplification([np.diag([4.0, 0.01])], [np.array([1.0, 1.0])], 2.0)
    assert a == pytest.approx((2 * 4 * np.sqrt(2) + np.sqrt(2) * 2) / 0.01, rel=1e-12)
    assert amplification([np.diag([1.0, 0.0])], [np.array([1.0, 1.0])], 1.0) == np.inf  # singular: not judged


def test_the_bound_holds_for_every_perturbation_within_the_tolerance():
    """Random ill-conditioned M (condition numbers up to 1e4), M and b perturbed by TOLERANCE of their scales
    (the worst an agreeing engine may be): the change of q̈ stays within TOLERANCE·A of max |q̈|. The bound is
    first order in ΔM; with ‖M⁻¹ΔM‖₂ ≤ ½ (true at these conditionings), ‖M̃⁻¹‖ ≤ 2‖M⁻¹‖, hence the 2."""
    rng = np.random.default_rng(1)
    for _ in range(200):
        n = int(rng.integers(2, 8))
        basis, _ = np.linalg.qr(rng.standard_normal((n, n)))
        m = basis @ np.diag(10.0 ** rng.uniform(-4, 0, n)) @ basis.T
        b, qdd = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        tau = m @ qdd + b
        s_m, s_b = np.abs(m).max(), max(np.abs(b).max(), np.abs(tau).max())
        d_m = rng.uniform(-1, 1, (n, n))
        d_m = TOLERANCE * s_m * (d_m + d_m.T) / np.abs(d_m + d_m.T).max()
        d_b = TOLERANCE * s_b * rng.uniform(-1, 1, n)
        assert np.linalg.norm(np.linalg.solve(m, d_m), 2) <= 0.5
        moved = np.linalg.solve(m + d_m, tau - b - d_b)
        bound = TOLERANCE * amplification([m], [qdd], s_b) * np.abs(qdd).max()
        assert np.abs(moved - qdd).max() <= 2 * bound


@pytest.mark.parametrize("model", [str(MODELS / "pitfalls/no_inertial.urdf"), "pybullet_data:franka_panda/panda.urdf",
                                   "pybullet_data:kuka_iiwa/model.urdf", str(FIXTURES / "tiny_product.urdf")])
def test_no_verdict_changes_with_the_seed(model):
    verdicts = {seed: [(e.engine, e.loaded, e.agrees) for e in check(model, states=20, seed=seed).engines]
                for seed in range(5)}
    assert all(v == verdicts[0] for v in verdicts.values()), verdicts


def test_every_disagreement_has_a_diagnosis_line():
    """Each engine that loads and disagrees has a line: the cause by link, or where its largest difference is."""
    for model in (str(MODELS / "pitfalls/no_inertial.urdf"), str(FIXTURES / "acrobot.xml"),
                  "pybullet_data:franka_panda/panda.urdf"):
        report = check(model, states=10)
        for entry in report.engines:
            if entry.loaded and not entry.agrees and not entry.failure:
                assert entry.diagnosis, (model, entry.engine)


def test_the_line_of_a_difference_no_link_explains_names_the_joint_and_its_link():
    _, model = read_description(str(FIXTURES / "same_name.urdf"))
    assert unexplained(model, "bias", 1) == "cause not found: largest difference at joint elbow, link elbow (in the bias)"
    assert unexplained(model, "mass_matrix", 0) == ("cause not found: largest difference at joint shoulder, "
                                                    "link shoulder (in M)")
