"""Entities that are not robots: single shapes, the environment (ground, sky, lights, cameras), meshes."""
