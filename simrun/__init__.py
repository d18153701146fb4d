"""simrun: MuJoCo worlds built on ``mujoco.MjSpec`` for assets made by meshtool."""

__version__ = "0.1.0"

__all__ = ["__version__"]
