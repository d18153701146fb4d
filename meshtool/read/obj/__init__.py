"""Wavefront OBJ/MTL: reading, triangulation and writing."""

from meshtool.read.obj.mtl import Material, MtlData, TextureMap, parse_mtl
from meshtool.read.obj.parse import parse_obj
from meshtool.read.obj.triangulate import Triangulation, triangulate_polygons
from meshtool.read.source_mesh import SourceMesh

__all__ = [
    "Material",
    "MtlData",
    "SourceMesh",
    "TextureMap",
    "Triangulation",
    "parse_mtl",
    "parse_obj",
    "triangulate_polygons",
]
