"""Engines from outside xval: programs speaking the process protocol, and third-party plugins."""
