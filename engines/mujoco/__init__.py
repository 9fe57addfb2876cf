"""MuJoCo's home: its own derivatives (gradients.py)."""
