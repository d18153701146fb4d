"""Wavefront OBJ/MTL: reading, triangulation and writing."""

from meshtool.read.obj.mtl import Material, MtlData, TextureMap, parse_mtl
from meshtool.read.obj.parse import ObjData, parse_obj
from meshtool.read.obj.triangulate import Triangulation, triangulate_polygons

__all__ = [
    "Material",
    "MtlData",
    "ObjData",
    "TextureMap",
    "Triangulation",
    "parse_mtl",
    "parse_obj",
    "triangulate_polygons",
]
