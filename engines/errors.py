"""Errors shared by every layer above ``ours/``.

``UserError`` is a mistake the user can fix (bad suite file, bad parameter,
unknown engine or scene). The CLI prints its message as one line and exits 2.
"""


class UserError(Exception):
    """A mistake in the user's input; the message names the field and the fix."""


class SceneError(UserError):
    """A scene that violates a rule of the scene language."""


class Unsupported(UserError):
    """An engine cannot express a scene (or a variant cannot): the message says why.

    In a suite this becomes a ``skipped`` case with the reason; at the CLI it
    is a usage error (exit 2).
    """
