"""The one import of Pymunk in xval."""

import pymunk

__all__ = ["pymunk"]
