"""MJX's home: its own derivatives (gradients.py)."""
