"""xval: cross-validation of constrained-dynamics solvers."""
