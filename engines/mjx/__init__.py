"""MJX's home: its adapter (MuJoCo's model, stepped in JAX)."""
