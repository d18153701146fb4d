"""The frame stage: the one unit and up-axis decision, with its evidence (consumers, headers, formats, geometry)."""
