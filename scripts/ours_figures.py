"""Figures and the numbers table for docs/ours.md, written as standalone SVG and Markdown.

Run:  .venv/bin/python scripts/ours_figures.py
Writes docs/figures/ours/*.svg (plain SVG line plots: no plotting library or
browser needed to view them) and docs/figures/ours/numbers.md. Uses ``ours``
alone (no engines/): the bead and double pendulum are built here.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy.special import ellipk

import ours
from ours import simulate

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures" / "ours"
# The bead and its release, and the convergence study, are ours_claims.py's (one definition of each).
sys.path.insert(0, str(Path(__file__).resolve().parent))
from ours_claims import BEAD, G, ORDER_DTS, Q0, THETA0, V0, bead_convergence  # noqa: E402
COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf", "#7f7f7f"]


# -- a minimal SVG line plot ----------------------------------------------------------------


def _ticks(lo: float, hi: float, log: bool) -> list[float]:
    if log:
        return [10.0**k for k in range(math.ceil(lo), math.floor(hi) + 1)]
    step = 10 ** math.floor(math.log10((hi - lo) / 4 or 1))
    for mult in (1, 2, 5, 10):
        if (hi - lo) / (step * mult) <= 6:
            step *= mult
            break
    return list(np.arange(math.ceil(lo / step) * step, hi + step / 2, step))


def line_plot(path: Path, title: str, series, xlabel: str, ylabel: str, logx=False, logy=False, floor=None):
    """series: [(label, x, y)]; non-finite or non-positive (on log axes) points are dropped."""
    W, H, L, R, T, B = 760, 440, 80, 230, 40, 55
    fx = (lambda x: np.log10(x)) if logx else (lambda x: np.asarray(x, float))
    fy = (lambda y: np.log10(np.maximum(y, floor) if floor else y)) if logy else (lambda y: np.asarray(y, float))
    cleaned = []
    for label, x, y in series:
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y) & ((x > 0) if logx else True) & ((y > 0) if logy and not floor else True)
        cleaned.append((label, fx(x[ok]), fy(y[ok])))
    xs = np.concatenate([c[1] for c in cleaned])
    ys = np.concatenate([c[2] for c in cleaned])
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(ys.min()), float(ys.max())
    if logy:
        y0, y1 = math.floor(y0), math.ceil(y1)
    if y1 == y0:
        y1 = y0 + 1
    px = lambda x: L + (x - x0) / (x1 - x0) * (W - L - R)
    py = lambda y: H - B - (y - y0) / (y1 - y0) * (H - T - B)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
           f'<rect width="{W}" height="{H}" fill="white"/>',
           f'<text x="{W / 2 - R / 2 + L / 2}" y="22" text-anchor="middle" font-size="15">{title}</text>',
           f'<rect x="{L}" y="{T}" width="{W - L - R}" height="{H - T - B}" fill="none" stroke="black"/>']
    for t in _ticks(x0, x1, False) if not logx else range(math.ceil(x0), math.floor(x1) + 1):
        label = f"1e{t}" if logx else f"{t:g}"
        out += [f'<line x1="{px(t):.1f}" y1="{H - B}" x2="{px(t):.1f}" y2="{T}" stroke="#ddd"/>',
                f'<text x="{px(t):.1f}" y="{H - B + 16}" text-anchor="middle">{label}</text>']
    for t in range(int(y0), int(y1) + 1) if logy else _ticks(y0, y1, False):
        label = f"1e{t}" if logy else f"{t:g}"
        out += [f'<line x1="{L}" y1="{py(t):.1f}" x2="{W - R}" y2="{py(t):.1f}" stroke="#ddd"/>',
                f'<text x="{L - 6}" y="{py(t) + 4:.1f}" text-anchor="end">{label}</text>']
    out += [f'<text x="{(L + W - R) / 2}" y="{H - 15}" text-anchor="middle">{xlabel}</text>',
            f'<text x="18" y="{(T + H - B) / 2}" text-anchor="middle" transform="rotate(-90 18 {(T + H - B) / 2})">{ylabel}</text>']
    for n, (label, x, y) in enumerate(cleaned):
        colour = COLOURS[n % len(COLOURS)]
        if len(x) > 1500:  # keep the files small: thin long series evenly (keeps the envelope's shape)
            keep = np.unique(np.linspace(0, len(x) - 1, 1500).astype(int))
            x, y = x[keep], y[keep]
        points = " ".join(f"{px(a):.1f},{py(b):.1f}" for a, b in zip(x, y))
        marker = len(x) <= 12
        out.append(f'<polyline points="{points}" fill="none" stroke="{colour}" stroke-width="1.5"/>')
        if marker:
            out += [f'<circle cx="{px(a):.1f}" cy="{py(b):.1f}" r="3" fill="{colour}"/>' for a, b in zip(x, y)]
        out += [f'<line x1="{W - R + 12}" y1="{T + 12 + 18 * n}" x2="{W - R + 32}" y2="{T + 12 + 18 * n}" stroke="{colour}" stroke-width="2"/>',
                f'<text x="{W - R + 38}" y="{T + 16 + 18 * n}">{label}</text>']
    out.append("</svg>")
    path.write_text("\n".join(out))


# -- the runs -------------------------------------------------------------------------


def radial_error(run) -> np.ndarray:
    return np.abs(np.linalg.norm(run.q[:, 0], axis=1) - 1.0)


def energy(run) -> np.ndarray:
    return 0.5 * np.sum(run.v[:, 0] ** 2, axis=1) + G * run.q[:, 0, 1]


CURES = [("plain", "euler"), ("plain", "rk4"), ("baumgarte", "symplectic-euler"), ("baumgarte", "rk4"),
         ("projection", "symplectic-euler"), ("rattle", None), ("lagrangian", "rk4")]


def name(method, integrator):
    return method if integrator in (None, "rattle") else f"{method}-{integrator}"


def drift_figure(rows):
    series = []
    for method, integrator in CURES:
        run = simulate(BEAD, Q0, V0, 1e-3, 20_000, 20, method=method, integrator=integrator)
        e = radial_error(run)
        series.append((name(method, integrator), run.t[1:], e[1:]))
        rows.append((name(method, integrator), f"{e.max():.1e}", f"{np.abs(energy(run) - energy(run)[0]).max() / G:.1e}"))
    line_plot(OUT / "drift.svg", "Bead at 60°, dt = 1 ms: distance off the wire", series, "t (s)",
              "| ‖x‖ − r | (m)", logy=True, floor=1e-17)


def order_figure(rows):
    series = []
    for method, integrator, _key, errors, slope in bead_convergence():
        series.append((f"{name(method, integrator)} ({slope:.2f})", ORDER_DTS, errors))
        rows.append((name(method, integrator), f"{slope:.2f}"))
    line_plot(OUT / "orders.svg", "Bead, error at t = 1 s against dt (slope)", series, "dt (s)",
              "position error (m)", logx=True, logy=True)


def energy_figure():
    dt = 5e-3
    rattle = simulate(BEAD, Q0, V0, dt, round(1000 / dt), 20, method="rattle")
    euler = simulate(BEAD, Q0, V0, dt, round(60 / dt), 20, method="baumgarte", integrator="euler")
    symp = simulate(BEAD, Q0, V0, dt, round(1000 / dt), 20, method="baumgarte", integrator="symplectic-euler")
    series = [(name, run.t, np.abs(energy(run) - energy(run)[0]) / G)
              for name, run in (("rattle", rattle), ("baumgarte-symplectic-euler", symp), ("baumgarte-euler", euler))]
    line_plot(OUT / "energy.svg", "Bead, dt = 5 ms: energy error over 1,000 s", series, "t (s)",
              "|E − E₀| / (m g r)", logy=True, floor=1e-12)


def baumgarte_step_figure():
    k_s = 100.0
    series = []
    for label, k_d in (("k_d = 0", 0.0), ("k_d = √k_s", 10.0), ("k_d = 2√k_s (default)", 20.0), ("k_d = 4√k_s", 40.0)):
        run = simulate(BEAD, 1.05 * Q0, V0, 1e-3, 1500, 5, method="baumgarte", integrator="rk4", k_s=k_s, k_d=k_d)
        c = 0.5 * (np.sum(run.q[:, 0] ** 2, axis=1) - 1.0)
        series.append((label, run.t, c / c[0]))
    line_plot(OUT / "baumgarte_start_off.svg", "Released 5% off the wire, k_s = 100 s⁻²: C(t) / C(0)", series,
              "t (s)", "C / C₀")


def gain_sweep_figure(rows):
    k_values = np.logspace(0, 7, 15)
    series_err, series_energy = [], []
    for dt, integrator in ((1e-3, "symplectic-euler"), (1e-3, "rk4"), (1e-2, "symplectic-euler")):
        errors, drifts = [], []
        for k_s in k_values:
            run = simulate(BEAD, Q0, V0, dt, round(20 / dt), max(1, round(0.01 / dt)), method="baumgarte",
                           integrator=integrator, k_s=k_s)
            stable = run.status == "ok" and radial_error(run).max() < 0.5
            errors.append(radial_error(run).max() if stable else np.nan)
            drifts.append(np.abs(energy(run) - energy(run)[0]).max() / G if stable else np.nan)
            rows.append((integrator, f"{dt:g}", f"{k_s:.3g}", f"{2 * math.sqrt(k_s):.3g}",
                         f"{errors[-1]:.1e}" if stable else "unstable", f"{drifts[-1]:.1e}" if stable else "unstable"))
        label = f"{integrator}, dt = {dt:g}"
        series_err.append((label, k_values, np.array(errors)))
        series_energy.append((label, k_values, np.array(drifts)))
    line_plot(OUT / "gains_constraint.svg", "Bead 20 s, k_d = 2√k_s: max distance off the wire", series_err,
              "k_s (1/s²)", "max | ‖x‖ − r | (m)", logx=True, logy=True)
    line_plot(OUT / "gains_energy.svg", "Bead 20 s, k_d = 2√k_s: max energy error (gaps: unstable)",
              series_energy, "k_s (1/s²)", "max |E − E₀| / (m g r)", logx=True, logy=True)


def table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    ours.compile_all()
    drift_rows, order_rows, gain_rows = [], [], []
    drift_figure(drift_rows)
    order_figure(order_rows)
    energy_figure()
    baumgarte_step_figure()
    gain_sweep_figure(gain_rows)
    period_rows = []
    T = 4 * math.sqrt(1 / G) * float(ellipk(math.sin(THETA0 / 2) ** 2))
    for method, integrator in (("rattle", None), ("baumgarte", "rk4"), ("lagrangian", "rk4"), ("baumgarte", "midpoint")):
        run = simulate(BEAD, Q0, V0, 1e-3, 10_000, 1, method=method, integrator=integrator)
        x, vx = run.q[:, 0, 0], run.v[:, 0, 0]
        k = np.nonzero(np.sign(x[:-1]) != np.sign(x[1:]))[0]
        tc = run.t[k] - x[k] / vx[k]
        period = 2 * (tc[-1] - tc[0]) / (len(tc) - 1)
        period_rows.append((name(method, integrator), f"{period:.9f}", f"{period / T - 1:+.1e}"))
    text = "\n\n".join([
        "# ours: numbers behind the figures\n\nGenerated by `scripts/ours_figures.py`; do not edit by hand.",
        f"## Bead period at 60°, dt = 1 ms (elliptic integral: {T:.9f} s)\n\n"
        + table(["variant", "period (s)", "relative error"], period_rows),
        "## Drift cures on the bead, 20 s at dt = 1 ms\n\n"
        + table(["variant", "max distance off the wire (m)", "max energy error / (m g r)"],
                drift_rows),
        "## Observed order on the bead (slope of log error against log dt, finest four steps)\n\n"
        + table(["variant", "slope"], order_rows),
        "## Baumgarte gains on the bead, 20 s, k_d = 2√k_s\n\n"
        + table(["integrator", "dt (s)", "k_s (1/s²)", "k_d (1/s)", "max distance off (m)", "max energy error"],
                gain_rows),
    ])
    (OUT / "numbers.md").write_text(text + "\n")
    print(f"wrote {sorted(p.name for p in OUT.iterdir())} to {OUT}")


if __name__ == "__main__":
    main()
