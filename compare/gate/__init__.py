"""Baselines and the regression gate: a run's gate-relevant entries, and the rules that compare two (docs/gate.md)."""
