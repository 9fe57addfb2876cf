"""Robot models (URDF, MJCF): the engine-neutral description, its readers, and each engine's import.

``description`` (what the file says), ``urdf`` / ``mjcf`` (readers),
``source`` (where the file is, the text engines get), ``kinematics`` and
``inertia`` (frames and mass properties of a description), one module per
engine that loads the file its own way (``mujoco``, ``pybullet``, ``drake``,
``dart``, ``pinocchio``: the reference), ``loaded`` (their shared shape), ``ours`` (ours' rigid
bodies built from the description), ``scene`` / ``stepping`` / ``steppers`` (a model as a scene).
"""
