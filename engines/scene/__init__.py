"""The scene language: particles, constraints, scenes, their catalog and limits, trajectories, and readers of a scene's topology."""
