"""Errors raised by ``ours``: every one is a ValueError that names the field and the fix."""


class OursError(ValueError):
    """Bad input to ``ours``; the message names the field and how to fix it."""


class InvalidPair(OursError):
    """A drift-cure method and an integrator that do not go together (e.g. ``rattle`` with ``rk4``)."""


class ModelError(OursError):
    """A system (masses, gravity, constraints) or a state that breaks a rule of the model."""
