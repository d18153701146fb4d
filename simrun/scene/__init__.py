"""TOML scene files: reading and writing scenes, the saved world state, TOML line numbers."""
