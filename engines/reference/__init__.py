"""The ground truth: the reference engine, its mechanism models and compiled kernels, and closed-form answers."""
