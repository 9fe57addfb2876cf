"""Stability search, option gain maps and hidden dissipation: runs judged by the suite's bounds across dt."""
