"""OpenVDB (``.vdb``) files: sparse fields on a regular grid, for Blender, Houdini and other VDB tools.

Written from the OpenVDB file format (file version 224, the layout OpenVDB 10 writes), without the OpenVDB
library, which has no wheel on PyPI:

- Header: int64 magic ``0x56444220``, uint32 file version 224, uint32 library major and minor version (10, 0),
  a byte "has grid offsets" (1), a 36-character unique id, the file metadata (``creator``), the grid count.
- Per grid: the descriptor (name, tree type ``Tree_float_5_4_3`` or ``Tree_vec3s_5_4_3``, no instance parent, and
  the byte offsets of the grid, its voxel buffers and its end), the compression flags (``COMPRESS_ACTIVE_MASK``
  only: no zip, no blosc), the grid metadata, the transform, the tree topology and the leaf buffers.
- Tree: a root node over internal nodes of 32^3 children, internal nodes of 16^3 children and leaves of 8^3 voxels,
  each with its child and value masks (bit ``(x << 2n) + (y << n) + z`` of a node of side ``2^n``, in words of 64
  bits). Only leaves that hold a non-zero voxel are written; a voxel is active when its value is non-zero, and
  inactive voxels read as the background, 0.
- Transform: ``ScaleTranslateMap``: voxel ``(i, j, k)`` (index space, i along x) lies at
  ``origin + (i dx, j dy, k dz)`` in world metres, the node positions of :func:`~fluidnexus.export.vti.grid_points`.

The arrays are the ``.vti`` writer's: ``[nz, ny, nx]`` scalars and ``[nz, ny, nx, 3]`` vectors, node ``(i, j, k)``
at ``[k, j, i]``. A scalar grid is marked as a fog volume (``class``: ``fog volume``), the class of a density.
:func:`read_vdb` reads back what :func:`write_vdb` writes (the tests also read the files with OpenVDB itself).
"""
from __future__ import annotations

import io
import struct
import uuid
from pathlib import Path

import numpy as np

from ..atomic import atomic_file
from ..errors import InputError
from .vti import check_grid

MAGIC = 0x56444220
FILE_VERSION = 224
LIBRARY_VERSION = (10, 0)
COMPRESS_ACTIVE_MASK = 0x2
NO_MASK_OR_INACTIVE_VALS = 0  # per-node flag: every inactive value is the background
NO_MASK_AND_ALL_VALS = 6  # per-node flag: every value follows
LOG2 = (5, 4, 3)  # root children: internal 32^3, then internal 16^3, then leaves 8^3
TREE_TYPES = {1: "Tree_float_5_4_3", 3: "Tree_vec3s_5_4_3"}


# ---- writing --------------------------------------------------------------------------------------------------
def write_vdb(path: str | Path, origin, spacing, arrays: dict[str, np.ndarray]) -> None:
    """Write fields on a regular grid as an OpenVDB file, one grid per array (atomically).

    Args:
        path: the ``.vdb`` file to write; its folder is created.
        origin: (x, y, z) of node (0, 0, 0), metres.
        spacing: (dx, dy, dz) node spacing, metres, > 0.
        arrays: name -> [nz, ny, nx] scalar or [nz, ny, nx, 3] vector field, e.g. ``density`` and ``velocity``
            (m/s); written as float32 (``FloatGrid``, ``Vec3SGrid``) under the array's name.
    """
    arrays = {name: np.asarray(arr, dtype=np.float32) for name, arr in arrays.items()}
    check_grid(origin, spacing, arrays)
    out = io.BytesIO()
    out.write(struct.pack("<qIIIB", MAGIC, FILE_VERSION, *LIBRARY_VERSION, 1))
    out.write(str(uuid.uuid4()).upper().encode("ascii"))  # 36 characters
    _write_metadata(out, [("creator", "string", b"fluidnexus")])
    out.write(struct.pack("<i", len(arrays)))
    for name, arr in arrays.items():
        _write_grid(out, name, arr, origin, spacing)
    with atomic_file(path) as tmp:
        tmp.write_bytes(out.getvalue())


def _string(text: str | bytes) -> bytes:
    raw = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(raw)) + raw


def _write_metadata(out, items: list[tuple[str, str, bytes]]) -> None:
    """A metadata map: count, then per item its name, type name and value (byte count first)."""
    out.write(struct.pack("<I", len(items)))
    for name, kind, value in items:
        out.write(_string(name) + _string(kind) + _string(value))


def _mask_bytes(bits: np.ndarray) -> bytes:
    """A node mask: bit n in 64-bit little-endian words (bit n of the stream is bit n % 8 of byte n // 8)."""
    return np.packbits(bits.astype(bool), bitorder="little").tobytes()


def _leaves(arr: np.ndarray):
    """Voxel blocks of 8^3 that hold a non-zero value: (origins [L, 3] (i, j, k), values [L, 512, C], active
    [L, 512]), values in leaf order ``(x << 6) + (y << 3) + z``, origins sorted as the tree writes them."""
    vec = arr if arr.ndim == 4 else arr[..., None]
    vol = np.transpose(vec, (2, 1, 0, 3))  # [x, y, z, C]
    pad = [(0, -n % 8) for n in vol.shape[:3]] + [(0, 0)]
    vol = np.pad(vol, pad)
    bx, by, bz = (n // 8 for n in vol.shape[:3])
    blocks = vol.reshape(bx, 8, by, 8, bz, 8, -1).transpose(0, 2, 4, 1, 3, 5, 6).reshape(bx * by * bz, 512, -1)
    active = np.any(blocks != 0, axis=2)
    keep = np.flatnonzero(active.any(axis=1))
    origins = np.stack(np.unravel_index(keep, (bx, by, bz)), axis=1) * 8
    order = np.lexsort(_tree_order_keys(origins))
    values = np.where(active[keep][..., None], blocks[keep], 0)
    return origins[order], values[order], active[keep][order]


def _tree_order_keys(origins: np.ndarray):
    """Sort keys (last = primary) putting leaves in the tree's depth-first order: root children by (x, y, z),
    then children by their bit index inside each internal node."""
    top = origins >> 12
    mid = (origins >> 7) & 31
    low = (origins >> 3) & 15
    mid_index = (mid[:, 0] << 10) + (mid[:, 1] << 5) + mid[:, 2]
    low_index = (low[:, 0] << 8) + (low[:, 1] << 4) + low[:, 2]
    return low_index, mid_index, top[:, 2], top[:, 1], top[:, 0]


def _write_grid(out, name: str, arr: np.ndarray, origin, spacing) -> None:
    channels = 1 if arr.ndim == 3 else 3
    origins, values, active = _leaves(arr)
    out.write(_string(name) + _string(TREE_TYPES[channels]) + _string(""))
    offsets_at = out.tell()
    out.write(struct.pack("<qqq", 0, 0, 0))  # grid, buffers and end positions, filled in below
    grid_pos = out.tell()
    out.write(struct.pack("<I", COMPRESS_ACTIVE_MASK))
    meta = [("class", "string", b"fog volume" if channels == 1 else b"unknown"),
            ("name", "string", name.encode()),
            ("file_voxel_count", "int64", struct.pack("<q", int(active.sum())))]
    if len(origins):
        ijk = [o + np.stack(np.unravel_index(np.flatnonzero(a), (8, 8, 8)), axis=1) for o, a in zip(origins, active)]
        ijk = np.concatenate(ijk)
        meta += [("file_bbox_min", "vec3i", struct.pack("<3i", *ijk.min(0))),
                 ("file_bbox_max", "vec3i", struct.pack("<3i", *ijk.max(0)))]
    _write_metadata(out, meta)
    scale = np.asarray(spacing, np.float64)
    out.write(_string("ScaleTranslateMap"))
    for vec in (np.asarray(origin, np.float64), scale, np.abs(scale), 1 / scale, 1 / scale**2, 0.5 / scale):
        out.write(struct.pack("<3d", *vec))
    _write_topology(out, origins, active, channels)
    block_pos = out.tell()
    for act, vals in zip(active, values):  # leaf buffers, in topology order
        out.write(_mask_bytes(act) + bytes([NO_MASK_OR_INACTIVE_VALS]))
        out.write(np.ascontiguousarray(vals[act], "<f4").tobytes())
    end_pos = out.tell()
    out.seek(offsets_at)
    out.write(struct.pack("<qqq", grid_pos, block_pos, end_pos))
    out.seek(end_pos)


def _write_topology(out, origins: np.ndarray, active: np.ndarray, channels: int) -> None:
    """Buffer count, root (background 0, no tiles), internal nodes with their masks, leaf value masks."""
    out.write(struct.pack("<i", 1))
    out.write(np.zeros(channels, "<f4").tobytes())
    tops = sorted({tuple(o) for o in (origins >> 12) << 12})
    out.write(struct.pack("<II", 0, len(tops)))
    for top in tops:
        in_top = np.all((origins >> 12) << 12 == top, axis=1)
        out.write(struct.pack("<3i", *top))
        mids = np.unique((origins[in_top] >> 7) << 7, axis=0)
        mids = mids[np.argsort(_child_index(mids - np.asarray(top), 7, 5))]
        _write_internal(out, mids - np.asarray(top), 7, 5)
        for mid in mids:
            in_mid = in_top & np.all((origins >> 7) << 7 == mid, axis=1)
            _write_internal(out, origins[in_mid] - mid, 3, 4)
            for act in active[in_mid]:
                out.write(_mask_bytes(act))


def _child_index(local: np.ndarray, child_log2: int, log2: int) -> np.ndarray:
    c = local >> child_log2
    return (c[:, 0] << (2 * log2)) + (c[:, 1] << log2) + c[:, 2]


def _write_internal(out, children_local: np.ndarray, child_log2: int, log2: int) -> None:
    """An internal node's topology: child mask, value mask (no active tile), its tile values (none stored: the
    value mask is empty and every inactive value is the background)."""
    child = np.zeros(1 << (3 * log2), bool)
    child[_child_index(children_local, child_log2, log2)] = True
    out.write(_mask_bytes(child) + _mask_bytes(np.zeros_like(child)) + bytes([NO_MASK_OR_INACTIVE_VALS]))


# ---- reading --------------------------------------------------------------------------------------------------
class _Reader:
    def __init__(self, raw: bytes, path: Path):
        self.raw, self.at, self.path = raw, 0, path

    def take(self, n: int) -> bytes:
        if self.at + n > len(self.raw):
            raise InputError(self.path, None, "truncated VDB file")
        chunk = self.raw[self.at:self.at + n]
        self.at += n
        return chunk

    def unpack(self, fmt: str):
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))

    def string(self) -> str:
        (n,) = self.unpack("<I")
        return self.take(n).decode("utf-8", "replace")

    def mask(self, log2: int) -> np.ndarray:
        return np.unpackbits(np.frombuffer(self.take((1 << (3 * log2)) // 8), np.uint8), bitorder="little") > 0

    def metadata(self) -> dict:
        (count,) = self.unpack("<I")
        out = {}
        for _ in range(count):
            name, kind = self.string(), self.string()
            (n,) = self.unpack("<I")
            out[name] = (kind, self.take(n))
        return out


def read_vdb(path: str | Path) -> dict[str, dict]:
    """Read a file written by :func:`write_vdb` (uncompressed or active-mask compressed float and vec3s grids).

    Returns:
        grid name -> {"scale": [3], "translation": [3] (metres: voxel (i, j, k) at translation + scale * ijk),
        "ijk": [V, 3] int active voxel indices, "values": [V] or [V, 3] float32 their values, "class": str}.

    Raises:
        InputError: the file is missing or not a VDB file this reader understands.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "file not found")
    r = _Reader(path.read_bytes(), path)
    magic, version, _, _, offsets = r.unpack("<qIIIB")
    if magic != MAGIC:
        raise InputError(path, None, "not an OpenVDB file (wrong magic number)")
    if version < 222 or not offsets:
        raise InputError(path, None, f"only VDB files of version >= 222 with grid offsets are read, got {version}")
    r.take(36)
    r.metadata()
    (count,) = r.unpack("<i")
    grids = {}
    for _ in range(count):
        name, kind, _parent = r.string(), r.string(), r.string()
        r.unpack("<qqq")
        (compression,) = r.unpack("<I")
        if compression & ~COMPRESS_ACTIVE_MASK or kind not in TREE_TYPES.values():
            raise InputError(path, name, f"grid type {kind} or compression {compression:#x} is not read here")
        meta = r.metadata()
        if r.string() not in ("ScaleTranslateMap", "UniformScaleTranslateMap"):
            raise InputError(path, name, "only scale-translate transforms are read here")
        translation, scale = r.unpack("<3d"), r.unpack("<3d")
        r.take(4 * 24)
        grids[name] = _read_tree(r, 3 if "vec3s" in kind else 1, compression)
        grids[name].update(scale=np.array(scale), translation=np.array(translation),
                           **{"class": meta.get("class", ("", b""))[1].decode()})
    return grids


def _read_values(r: _Reader, mask: np.ndarray, channels: int, compression: int) -> np.ndarray | None:
    (flag,) = r.unpack("<b")
    if flag not in (NO_MASK_OR_INACTIVE_VALS, NO_MASK_AND_ALL_VALS):
        raise InputError(r.path, None, f"node flag {flag} is not read here")
    count = int(mask.sum()) if compression & COMPRESS_ACTIVE_MASK and flag != NO_MASK_AND_ALL_VALS else len(mask)
    values = np.frombuffer(r.take(4 * channels * count), "<f4").reshape(count, channels)
    return values if count == int(mask.sum()) else values[mask]


def _read_tree(r: _Reader, channels: int, compression: int) -> dict:
    r.unpack("<i")
    r.take(4 * channels)
    tiles, children = r.unpack("<II")
    if tiles:
        raise InputError(r.path, None, "root tiles are not read here")
    leaves = []  # (origin, value mask)
    for _ in range(children):
        top = np.array(r.unpack("<3i"))
        for mid in _read_internal(r, top, 5, 7, channels, compression):
            for origin in _read_internal(r, mid, 4, 3, channels, compression):
                leaves.append((origin, r.mask(3)))
    ijk, values = [], []
    for origin, _ in leaves:
        mask = r.mask(3)
        vals = _read_values(r, mask, channels, compression)
        ijk.append(origin + np.stack(np.unravel_index(np.flatnonzero(mask), (8, 8, 8)), axis=1))
        values.append(vals)
    ijk = np.concatenate(ijk) if ijk else np.zeros((0, 3), int)
    values = np.concatenate(values) if values else np.zeros((0, channels), np.float32)
    return {"ijk": ijk, "values": values[:, 0] if channels == 1 else values}


def _read_internal(r: _Reader, origin: np.ndarray, log2: int, child_log2: int, channels: int,
                   compression: int) -> list[np.ndarray]:
    child, value = r.mask(log2), r.mask(log2)
    if value.any():
        raise InputError(r.path, None, "active tiles are not read here")
    _read_values(r, value, channels, compression)
    index = np.flatnonzero(child)
    local = np.stack([index >> (2 * log2), (index >> log2) & ((1 << log2) - 1), index & ((1 << log2) - 1)], axis=1)
    return list(origin + (local << child_log2))
