"""The one import of MuJoCo in xval (``mujoco`` and its ``rollout``), with no OpenGL backend.

xval never renders with MuJoCo. With MUJOCO_GL unset, importing mujoco loads an OpenGL backend
(GLFW, whose binding starts a Python process to probe its library) in every run; "disable" skips
it. Set for the import only, and only when the user has not chosen a backend, so outside programs
xval starts see the environment they were given.
"""

from __future__ import annotations

import os

_GL_UNSET = "MUJOCO_GL" not in os.environ
if _GL_UNSET:
    os.environ["MUJOCO_GL"] = "disable"
try:
    import mujoco
    from mujoco import rollout as mj_rollout
finally:
    if _GL_UNSET:
        del os.environ["MUJOCO_GL"]

__all__ = ["mujoco", "mj_rollout"]
