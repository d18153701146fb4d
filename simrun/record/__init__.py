"""Recordings: ``.simlog`` files and what they export to (GLB, USD, HTML player, MCAP)."""
