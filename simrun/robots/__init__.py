"""Robots: the robot contract, wheels, differential drives, the catalogue robots, arms, MJCF and URDF robots."""
