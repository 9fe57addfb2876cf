"""The file helpers of :mod:`ours.files` for the layers above engines (compare and reports do not name ours).

Importing this module loads the ours package (and numpy): import it where it is used.
"""

from ours.files import atomic_write, cache_dir

__all__ = ["atomic_write", "cache_dir"]
