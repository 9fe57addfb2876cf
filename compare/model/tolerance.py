"""The one tolerance of ``xval model check`` and the bounds derived from it (docs/models.md, "One tolerance").

M and the bias agree when max |ΔM| / S_M and max |Δb| / S_b are ≤ TOLERANCE
(S_M = max |M_ref|, S_b = max(|b_ref|, |τ|) over the sample). An engine that
solves M̃ q̈̃ = τ − b̃ has Δq̈ = −M̃⁻¹(ΔM q̈ + Δb); M and b within the
tolerance bound it, at each state k, by TOLERANCE · (n S_M ‖q̈_k‖₂ + √n S_b)
/ λ_min(M_k): the forward difference max |Δq̈| / S_a (S_a = max |q̈_ref|)
agrees when ≤ TOLERANCE · A, A the largest of these over S_a (M's
conditioning enters through λ_min). The diagnosis names a link's difference
when it can move an entry of M by DIAGNOSED · S_M, a tenth of the
tolerance; the description accepts a principal moment negative by
PSD (= DIAGNOSED) of the model's largest: less than the check can see.
"""

from __future__ import annotations

import numpy as np

from engines.model.description import PSD_TOLERANCE

#: Largest relative difference of M and the bias (and, times the amplification, of q̈) that still agrees:
#: far above float64 round-off (measured 1e-16 .. 1e-13), far below any import mistake (the smallest seen, 1e-4).
TOLERANCE = 1e-6
#: A link's difference is named by the diagnosis when it can change an entry of M by this much of S_M.
DIAGNOSED = TOLERANCE / 10
#: Negative principal moments accepted, relative to the model's largest principal moment (the description's,
#: engines/model/description.py, which cannot import this layer; a test holds them equal).
PSD = PSD_TOLERANCE


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
