"""3D Gaussian Splatting PLY files: one binary little-endian PLY per frame, readable by common splat viewers.

Layout (one ``vertex`` element, every property float32, in this order; the layout the original 3DGS code writes
and that SIBR, SuperSplat, antimatter15/splat and the gsplat/nerfstudio viewers read):

==================  ==========================================================================================
``x y z``           Gaussian centre, metres, in the *viewer frame* (below).
``nx ny nz``        zero (unused normals, kept because the reference layout has them).
``f_dc_0..2``       degree-0 spherical-harmonic coefficient per RGB channel: ``(c - 0.5) / C0``,
                    ``C0 = 0.28209479177387814``; a gray colour (C = 1) is written to all three channels.
``f_rest_0..44``    zero: no view dependence. Written (instead of left out) because SIBR, the reference
                    viewer, reads a fixed degree-3 record of 62 floats.
``opacity``         ``logit(o)`` with ``o`` clamped to ``[1e-6, 1 - 1e-6]`` so that 0 and 1 stay finite.
``scale_0..2``      ``log(s)``, ``s`` the standard deviations in metres (must be > 0).
``rot_0..3``        unit quaternion ``(w, x, y, z)``, scalar first, rotated into the viewer frame.
==================  ==========================================================================================

Viewer frame: our world is +y up (docs/conventions.md); 3DGS scenes come from COLMAP, whose worlds are +y down,
and splat viewers are built for those. The file is therefore written rotated 180 degrees about x:
``(x, y, z) -> (x, -y, -z)``, so the smoke stands upright in those viewers. This is a proper rotation (no mirror)
made only of sign flips, so :func:`read_gaussians_ply` undoes it exactly. The header comments say all of this.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_file
from ..errors import InputError
from ..state import FrameState, validate

SH_C0 = 0.28209479177387814
"""Degree-0 real spherical harmonic, 1 / (2 sqrt(pi)); colour = 0.5 + C0 * f_dc (Kerbl et al. 2023)."""
OPACITY_EPS = 1e-6
"""Opacities are clamped to [OPACITY_EPS, 1 - OPACITY_EPS] before the logit."""
SH_REST = 45
"""Number of f_rest coefficients in the reference layout (3 channels x 15 degree-1..3 harmonics)."""

PROPERTIES = ("x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
              *(f"f_rest_{i}" for i in range(SH_REST)),
              "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
            "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
FRAME_COMMENT = "frame: fluidnexus world (+y up) rotated 180 deg about x, (x, y, z) -> (x, -y, -z): +y down"
SOURCE_FRAME_COMMENT = ("frame: source, the world of the file the scene was imported from (scene.json "
                        "source_frame), its axes and length unit, not rotated for viewers")
CHANNELS_COMMENT = "fluidnexus channels "


def world_to_viewer(positions: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate centres and (w, x, y, z) quaternions by 180 degrees about x.

    Returns ``(x, -y, -z)`` and ``q_x(180) * q = (-x, w, -z, y)``; only sign flips and a permutation, so exact.
    """
    p, q = positions, rotations
    return (np.stack([p[:, 0], -p[:, 1], -p[:, 2]], axis=1),
            np.stack([-q[:, 1], q[:, 0], -q[:, 3], q[:, 2]], axis=1))


def viewer_to_world(positions: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`world_to_viewer`: ``(x, -y, -z)`` and ``q_x(180)^-1 * q = (x, -w, z, -y)``."""
    p, q = positions, rotations
    return (np.stack([p[:, 0], -p[:, 1], -p[:, 2]], axis=1),
            np.stack([q[:, 1], -q[:, 0], q[:, 3], -q[:, 2]], axis=1))


def write_gaussians_ply(path: str | Path, state: FrameState, viewer_frame: bool = True) -> None:
    """Write the visual Gaussians of one frame as a 3DGS PLY file (atomically).

    Args:
        path: the ``.ply`` file to write; its folder is created.
        state: the frame; only its visual Gaussians are written (colours [M, 1] or [M, 3] in [0, 1],
            scales [M, 3] > 0 metres, rotations [M, 4] (w, x, y, z), opacities [M] in [0, 1]).
        viewer_frame: rotate the world into the viewer frame (above). False writes ``state`` as it is: a state
            already converted to the scene's source frame (``export --frame source``); the header says which.

    Raises:
        InputError: inconsistent shapes, non-finite values or a scale <= 0.
    """
    from plyfile import PlyData, PlyElement

    validate(state, path)
    scales = np.asarray(state.visual_scales, dtype=np.float64)
    if np.any(scales <= 0):
        raise InputError(path, "visual_scales", "must be > 0 (the PLY stores log(scale))")
    colors = np.asarray(state.visual_colors, dtype=np.float64)
    opacities = np.clip(np.asarray(state.visual_opacities, dtype=np.float64), OPACITY_EPS, 1 - OPACITY_EPS)
    positions, rotations = (np.asarray(state.visual_positions, dtype=np.float32),
                            np.asarray(state.visual_rotations, dtype=np.float32))
    if viewer_frame:
        positions, rotations = world_to_viewer(positions, rotations)

    vertex = np.zeros(state.num_visual, dtype=[(name, "<f4") for name in PROPERTIES])
    for axis in range(3):
        vertex["xyz"[axis]] = positions[:, axis]
        vertex[f"f_dc_{axis}"] = (colors[:, axis % colors.shape[1]] - 0.5) / SH_C0
        vertex[f"scale_{axis}"] = np.log(scales[:, axis])
    vertex["opacity"] = np.log(opacities) - np.log1p(-opacities)
    for k in range(4):
        vertex[f"rot_{k}"] = rotations[:, k]

    comments = ["fluidnexus 3DGS export: SH degree 0 (f_rest_* are zero), opacity = logit(o) with o clamped to "
                f"[{OPACITY_EPS:g}, 1 - {OPACITY_EPS:g}], scale = log(standard deviation in metres), "
                "rot = quaternion (w, x, y, z)",
                FRAME_COMMENT if viewer_frame else SOURCE_FRAME_COMMENT,
                f"{CHANNELS_COMMENT}{state.channels}",
                f"fluidnexus frame {state.frame}"]
    ply = PlyData([PlyElement.describe(vertex, "vertex")], text=False, byte_order="<", comments=comments)
    with atomic_file(path) as tmp:
        ply.write(str(tmp))


def read_gaussians_ply(path: str | Path) -> dict[str, np.ndarray]:
    """Read a 3DGS PLY file (ours or another tool's) back into world-frame Gaussians.

    Files from other tools are assumed to use the same viewer frame (+y down, as COLMAP-trained scenes do);
    their view-dependent ``f_rest_*`` coefficients are ignored. A file written with ``viewer_frame=False``
    (``export --frame source``, said in its header) is returned in its own frame, unrotated.

    Args:
        path: a PLY file with a ``vertex`` element holding at least x y z, f_dc_0..2, opacity, scale_0..2
            and rot_0..3.

    Returns:
        ``visual_positions`` [M, 3] metres, ``visual_colors`` [M, C] (C = 1 when the file was written from a
        gray state, else 3; not clipped, so a degree-0 colour outside [0, 1] comes back as such),
        ``visual_scales`` [M, 3] metres, ``visual_rotations`` [M, 4] (w, x, y, z) as stored (other tools may
        store unnormalised quaternions), ``visual_opacities`` [M]; all float32.

    Raises:
        InputError: the file is missing, is not a PLY, or lacks the vertex element or one of its properties.
    """
    from plyfile import PlyData

    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "file not found")
    try:
        ply = PlyData.read(str(path))
    except Exception as err:  # plyfile raises PlyParseError, ValueError or struct errors on bad files
        raise InputError(path, None, f"not a readable PLY file ({err})") from None
    if "vertex" not in ply:
        raise InputError(path, "vertex", "missing element")
    vertex = ply["vertex"].data
    for name in REQUIRED:
        if name not in vertex.dtype.names:
            raise InputError(path, f"vertex.{name}", "missing property")

    def column(*names: str) -> np.ndarray:
        return np.stack([np.asarray(vertex[n], dtype=np.float64) for n in names], axis=1)

    channels = 1 if f"{CHANNELS_COMMENT}1" in ply.comments else 3
    positions, rotations = (column("x", "y", "z").astype(np.float32),
                            column("rot_0", "rot_1", "rot_2", "rot_3").astype(np.float32))
    if SOURCE_FRAME_COMMENT not in ply.comments:
        positions, rotations = viewer_to_world(positions, rotations)
    logits = np.asarray(vertex["opacity"], dtype=np.float64)
    return {
        "visual_positions": positions,
        "visual_colors": (0.5 + SH_C0 * column(*(f"f_dc_{i}" for i in range(channels)))).astype(np.float32),
        "visual_scales": np.exp(column("scale_0", "scale_1", "scale_2")).astype(np.float32),
        "visual_rotations": rotations,
        "visual_opacities": (0.5 + 0.5 * np.tanh(0.5 * logits)).astype(np.float32),  # sigmoid, no overflow
    }
