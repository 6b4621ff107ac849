"""Exports of a reconstructed run: 3DGS PLY (splat viewers), VTK ImageData (ParaView), OpenVDB (Blender, Houdini)
and raw NPZ arrays.

Formats are described in docs/export-formats.md. Only this package writes those formats.
"""
from .fields import sample_fields
from .npz import read_frame_npz, write_frame_npz
from .ply import read_gaussians_ply, write_gaussians_ply
from .vdb import read_vdb, write_vdb
from .vti import grid_points, read_vti, write_vti

__all__ = ["grid_points", "read_frame_npz", "read_gaussians_ply", "read_vdb", "read_vti", "sample_fields",
           "write_frame_npz", "write_gaussians_ply", "write_vdb", "write_vti"]
