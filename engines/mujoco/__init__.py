"""MuJoCo's home: its adapter, its import of model files, its own derivatives (gradients.py)."""
