"""The one tolerance of ``xval model check``, and the bounds derived from it (docs/models.md, "One tolerance").

M and the bias are judged relative to their scale over the sample: d_M =
max |ΔM| / S_M (S_M = max |M_ref| over states and entries), d_b = max |Δb| /
S_b (S_b = max |b_ref|, at least max |τ|). Both agree when ≤ TOLERANCE.

Forward dynamics inherit the bound. An engine that solves its own
M̃ q̈̃ = τ − b̃ with M̃ = M + ΔM, b̃ = b + Δb has Δq̈ = −M̃⁻¹(ΔM q̈ + Δb), so
with ‖ΔM‖₂ ≤ n·max|ΔM| ≤ n·TOLERANCE·S_M and ‖Δb‖₂ ≤ √n·TOLERANCE·S_b,

    ‖Δq̈_k‖₂ ≤ TOLERANCE · (n S_M ‖q̈_k‖₂ + √n S_b) / λ_min(M_k)

at each state k (to first order in ΔM; λ_min(M_k) = 1 / ‖M_k⁻¹‖₂, so
M's conditioning enters). The forward difference d_a = max |Δq̈| / S_a
(S_a = max |q̈_ref|) therefore agrees when ≤ TOLERANCE · A, with the
amplification A = max_k (n S_M ‖q̈_k‖₂ + √n S_b) / (λ_min(M_k) S_a) ≥ 1.

The diagnosis counts a link's difference when it can move an entry of M by
more than DIAGNOSED · S_M (a tenth of the tolerance): every difference large
enough to break agreement is looked at, and one below it cannot alone.
A file's inertia is accepted as positive semidefinite when its smallest
principal moment is ≥ −PSD · (the largest principal moment of any link in the
model): a negative part that small changes M by less than the check can see.
"""

from __future__ import annotations

import numpy as np

#: Largest relative difference of M and the bias (and, times the amplification, of q̈) that still agrees:
#: far above float64 round-off (measured 1e-16 .. 1e-13), far below any import mistake (the smallest seen, 1e-4).
TOLERANCE = 1e-6
#: A link's difference is named by the diagnosis when it can change an entry of M by this much of S_M.
DIAGNOSED = TOLERANCE / 10
#: Negative principal moments accepted, relative to the model's largest principal moment.
PSD = DIAGNOSED


def amplification(mass_matrices: list[np.ndarray], accelerations: list[np.ndarray], bias_scale: float) -> float:
    """A, the factor by which M and bias differences of TOLERANCE can move q̈ (relative to max |q̈_ref|);
    inf when an M is singular (forward dynamics are then not judged)."""
    n = len(accelerations[0]) if accelerations else 0
    s_m = max(float(np.abs(m).max(initial=0.0)) for m in mass_matrices)
    s_a = max(float(np.abs(a).max(initial=0.0)) for a in accelerations)
    worst = 0.0
    for m, a in zip(mass_matrices, accelerations):
        smallest = float(np.linalg.eigvalsh((m + m.T) / 2)[0])
        if smallest <= 0 or s_a == 0:
            return float("inf")
        worst = max(worst, (n * s_m * float(np.linalg.norm(a)) + np.sqrt(n) * bias_scale) / (smallest * s_a))
    return max(worst, 1.0)
