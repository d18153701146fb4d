"""URDF import: locating and reading a robot's meshes, its links' geometry, and writing the robot."""
