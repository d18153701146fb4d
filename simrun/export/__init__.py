"""Exports of a world: MJCF (the one MJCF builder), USD, GLB, and the meshes they share."""
