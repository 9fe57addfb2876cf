"""`xval probe` for every built-in engine variant on the bead: the table in docs/engines.md.

Run:  .venv/bin/python scripts/probe_table.py      (about a minute: every variant, 4 time steps, 20 s each)

Prints the Markdown table docs/engines.md quotes. The quick run (tests/test_docs_figures.py)
probes the variants in QUICK only. Rates are E* per second (positive: lost), extrapolated to
dt -> 0 with their uncertainty σ; a rate smaller than 3σ is noise, so only the verdict is
checked there, and the rate too where the verdict is true.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quoted import Row, report  # noqa: E402

from compare.stability.dissipation import RULE, probe  # noqa: E402
from engines import registry  # noqa: E402
from engines.scene import catalog  # noqa: E402

BUILTIN = ("ours", "mujoco", "pybullet", "pymunk", "drake", "mjx")
QUICK = ("mujoco/hinge", "mujoco/connect", "pymunk/pin", "pybullet/p2p")
SCENE = catalog.build("bead", {"duration": 20.0})
#: Measured as a user would set it, with the rest: pymunk with its own damping option.
EXTRA = (("pymunk/pin", {"damping": 0.9}, "pymunk/pin, damping = 0.9"),)


def variants() -> list[tuple[str, dict, str]]:
    out = []
    for name in BUILTIN:
        engine = registry.get_engine(name)
        out += [(vid, {}, vid) for vid in engine.variant_ids()]
    return out + list(EXTRA)


def _key(label: str) -> str:
    return label.replace(" ", "").replace(",", "_")


def figures(quick: bool = False) -> dict[str, float]:
    f: dict[str, float] = {}
    for vid, options, label in variants():
        if quick and vid not in QUICK and label not in dict((e[2], 1) for e in EXTRA):
            continue
        result = probe(vid, SCENE, options, isolate=False)
        k = _key(label)
        if result.hidden_dissipation is None:
            f[f"{k}.verdict"] = float("nan")
            continue
        f[f"{k}.verdict"] = float(result.hidden_dissipation)
        f[f"{k}.rate"] = result.rate
        f[f"{k}.sigma"] = result.uncertainty
    return f


def table(f: dict[str, float]) -> str:
    lines = ["| variant | hidden dissipation | rate (E*/s) | σ (E*/s) |", "|---|---|---|---|"]
    for _vid, _options, label in variants():
        k = _key(label)
        if f.get(f"{k}.verdict") != f.get(f"{k}.verdict"):  # NaN: no verdict
            lines.append(f"| `{label}` | no verdict | | |")
        elif f"{k}.verdict" in f:
            verdict = "true" if f[f"{k}.verdict"] else "false"
            lines.append(f"| `{label}` | {verdict} | {f[f'{k}.rate']:.2g} | {f[f'{k}.sigma']:.1g} |")
    return "\n".join(lines)


def _rows() -> list[Row]:
    rows = []
    for _vid, _options, label in variants():
        k = _key(label)
        true_rows = {"mujoco/connect", "pymunk/pin, damping = 0.9", "mujoco/connect-rk4"}
        keys = (f"{k}.verdict", f"{k}.rate", f"{k}.sigma") if label in true_rows else (f"{k}.verdict", None, None)
        rows.append(Row("docs/engines.md", f"`{label}`", keys, HEADING))
    return rows


HEADING = "## Hidden dissipation: `xval probe`"
QUOTES: list = []
ROWS = _rows()
SLOW = {key for r in ROWS for key in r.keys if key}


def main() -> None:
    f = figures()
    print(f"### xval probe on the 60° bead, 20 s, dt = 4, 2, 1, 0.5 ms\n\n{table(f)}\n\nRule: {RULE}.")
    report(f, QUOTES, ROWS)


if __name__ == "__main__":
    main()
