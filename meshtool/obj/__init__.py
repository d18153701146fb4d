"""Wavefront OBJ/MTL: reading, triangulation and writing."""

from meshtool.obj.mtl import Material, MtlData, TextureMap, parse_mtl
from meshtool.obj.parse import ObjData, parse_obj
from meshtool.obj.triangulate import Triangulation, triangulate_polygons

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
