"""Gradients: engines' Jacobians of their outputs against the reference's, classed (measure.py)."""
