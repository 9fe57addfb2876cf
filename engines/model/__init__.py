"""Robot models (URDF, MJCF): what a file says, shared by every engine.

``description`` (what the file says), ``urdf`` / ``mjcf`` (readers),
``source`` (where the file is, the text engines get), ``kinematics`` and
``inertia`` (frames and mass properties of a description), ``loaded`` (the
shape every engine's import answers in), ``pinocchio`` (the model
reference's import), ``importers`` (the imports ``xval model check``
compares, reached through the registry), ``scene`` / ``stepping`` (a model
as a scene, and the one loop that steps it), ``dynamics`` (the reference's
dynamics of a model). Each engine's own import of a file and its stepper
live in its home, engines/<engine>/model.py.
"""
