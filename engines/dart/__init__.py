"""DART's home: its adapter, its import of model files."""
