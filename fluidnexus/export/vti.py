"""VTK XML ImageData (``.vti``) files: fields on a regular grid, for ParaView and other VTK tools.

A file holds point data on the nodes of an axis-aligned grid in world coordinates (metres, +y up, as in
docs/conventions.md): node ``(i, j, k)`` lies at ``origin + (i * dx, j * dy, k * dz)``. Arrays are indexed
``[k, j, i]`` = ``[z, y, x]`` (x varies fastest, VTK's point order), scalars ``[nz, ny, nx]`` and vectors
``[nz, ny, nx, 3]`` with (x, y, z) components. Values are little-endian float32 in one raw appended block
(``header_type="UInt64"``: each array is preceded by its byte count), which ParaView and VTK read directly.
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..atomic import atomic_file
from ..errors import InputError

APPENDED_TAG = b'<AppendedData encoding="raw">'


def grid_points(origin, spacing, shape: tuple[int, int, int]) -> np.ndarray:
    """World coordinates of the grid nodes, for sampling fields to pass to :func:`write_vti`.

    Args:
        origin: (x, y, z) of node (0, 0, 0), metres.
        spacing: (dx, dy, dz) node spacing, metres.
        shape: (nz, ny, nx) number of nodes along z, y, x.

    Returns:
        [nz, ny, nx, 3] float64 (x, y, z) positions.
    """
    nz, ny, nx = shape
    axes = [origin[a] + spacing[a] * np.arange(n, dtype=np.float64) for a, n in enumerate((nx, ny, nz))]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([x, y, z], axis=-1)


def check_grid(origin, spacing, arrays: dict[str, np.ndarray]) -> tuple[int, int, int]:
    """Return the common (nz, ny, nx) of ``arrays``; raise ValueError for a bad grid or array."""
    if origin is None or spacing is None or len(origin) != 3 or len(spacing) != 3 or not np.all(np.isfinite(origin)):
        raise ValueError(f"origin and spacing must be 3 finite numbers, got {origin!r}, {spacing!r}")
    if not all(np.isfinite(s) and s > 0 for s in spacing):
        raise ValueError(f"spacing must be > 0, got {spacing!r}")
    if not arrays:
        raise ValueError("no arrays to write")
    shape = None
    for name, arr in arrays.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise ValueError(f"array name {name!r} must be an identifier")
        if arr.ndim not in (3, 4) or (arr.ndim == 4 and arr.shape[3] != 3) or min(arr.shape[:3]) < 1:
            raise ValueError(f"array {name!r} must be [nz, ny, nx] or [nz, ny, nx, 3], got {arr.shape}")
        if shape not in (None, arr.shape[:3]):
            raise ValueError(f"array {name!r} has grid {arr.shape[:3]}, expected {shape}")
        shape = arr.shape[:3]
    return shape


def write_vti(path: str | Path, origin, spacing, arrays: dict[str, np.ndarray]) -> None:
    """Write point-data arrays on a regular grid as a VTK ImageData file (atomically).

    Args:
        path: the ``.vti`` file to write; its folder is created.
        origin: (x, y, z) of node (0, 0, 0), metres.
        spacing: (dx, dy, dz), metres, > 0.
        arrays: name -> [nz, ny, nx] scalar or [nz, ny, nx, 3] vector field, e.g. ``density`` and ``velocity``
            (m/s). Names must be identifiers; all arrays share one grid. Written as float32.
    """
    arrays = {name: np.asarray(arr) for name, arr in arrays.items()}
    nz, ny, nx = check_grid(origin, spacing, arrays)
    extent = f"0 {nx - 1} 0 {ny - 1} 0 {nz - 1}"
    scalars = next((n for n, a in arrays.items() if a.ndim == 3), None)
    vectors = next((n for n, a in arrays.items() if a.ndim == 4), None)
    defaults = "".join(f" {kind}={quoteattr(n)}" for kind, n in (("Scalars", scalars), ("Vectors", vectors)) if n)
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt64">',
             f'  <ImageData WholeExtent="{extent}" Origin="{" ".join(repr(float(v)) for v in origin)}" '
             f'Spacing="{" ".join(repr(float(v)) for v in spacing)}" Direction="1 0 0 0 1 0 0 0 1">',
             f'    <Piece Extent="{extent}">',
             f"      <PointData{defaults}>"]
    blocks, offset = [], 0
    for name, arr in arrays.items():
        data = np.ascontiguousarray(arr, dtype="<f4").tobytes()
        components = 1 if arr.ndim == 3 else 3
        lines.append(f'        <DataArray type="Float32" Name={quoteattr(name)} NumberOfComponents="{components}" '
                     f'format="appended" offset="{offset}"/>')
        blocks += [np.uint64(len(data)).astype("<u8").tobytes(), data]
        offset += 8 + len(data)
    lines += ["      </PointData>", "      <CellData/>", "    </Piece>", "  </ImageData>",
              "  " + APPENDED_TAG.decode() + "\n   _"]
    with atomic_file(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write("\n".join(lines).encode())
            for block in blocks:
                fh.write(block)
            fh.write(b"\n  </AppendedData>\n</VTKFile>\n")


def read_vti(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Read a file written by :func:`write_vti`.

    Returns:
        ``(origin [3], spacing [3], arrays)`` with arrays shaped as they were written, float32.

    Raises:
        InputError: the file is missing or is not a raw-appended, little-endian, Float32 ImageData file.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "file not found")
    raw = path.read_bytes()
    start = raw.find(APPENDED_TAG)
    if start < 0:
        raise InputError(path, "AppendedData", "no raw appended data block")
    try:
        root = ET.fromstring(raw[:start] + b"</VTKFile>")
    except ET.ParseError as err:
        raise InputError(path, None, f"not a VTK XML file ({err})") from None
    image = root.find("ImageData")
    if root.get("type") != "ImageData" or image is None or root.get("byte_order") != "LittleEndian":
        raise InputError(path, "VTKFile", "not a little-endian ImageData file")
    x0, x1, y0, y1, z0, z1 = (int(v) for v in image.get("WholeExtent").split())
    shape = (z1 - z0 + 1, y1 - y0 + 1, x1 - x0 + 1)
    base = raw.index(b"_", start + len(APPENDED_TAG)) + 1
    arrays = {}
    for node in image.iter("DataArray"):
        if node.get("type") != "Float32" or node.get("format") != "appended":
            raise InputError(path, f"DataArray {node.get('Name')}", "only appended Float32 arrays are read")
        at = base + int(node.get("offset"))
        nbytes = int(np.frombuffer(raw, dtype="<u8", count=1, offset=at)[0])
        values = np.frombuffer(raw, dtype="<f4", count=nbytes // 4, offset=at + 8)
        components = int(node.get("NumberOfComponents", "1"))
        arrays[node.get("Name")] = values.reshape(shape + ((components,) if components > 1 else ())).copy()
    origin = np.array([float(v) for v in image.get("Origin").split()])
    spacing = np.array([float(v) for v in image.get("Spacing").split()])
    return origin, spacing, arrays
