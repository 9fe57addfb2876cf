"""MJX's home: its adapter (MuJoCo's model, stepped in JAX) and its own derivatives (gradients.py)."""
