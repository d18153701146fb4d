"""Writers of what meshtool exports: OBJ/MTL, glTF, USD (the ``.mbin`` writer is :mod:`meshtool.packfile`)."""
