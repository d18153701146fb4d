"""The repair stage: triangles in metres, small parts, PNG textures and their roles, the asset record."""
