"""``xval model check``: each engine's import of a model file against Pinocchio's dynamics and the file itself."""
