"""Exports of a reconstructed run: 3DGS PLY (splat viewers), VTK ImageData (ParaView) and raw NPZ arrays.

Formats are described in docs/export-formats.md. Only this package writes those formats.
"""
from .npz import read_frame_npz, write_frame_npz
from .ply import read_gaussians_ply, write_gaussians_ply
from .vti import grid_points, read_vti, write_vti

__all__ = ["grid_points", "read_frame_npz", "read_gaussians_ply", "read_vti", "write_frame_npz",
           "write_gaussians_ply", "write_vti"]
