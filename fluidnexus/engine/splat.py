"""Differentiable 3D Gaussian splatting (Kerbl et al. 2023) on Taichi, behind one torch function.

:func:`render` projects the Gaussians (``splat_project``), bins them into screen tiles in depth order
(``splat_bin``) and composites each pixel front to back (``splat_raster``). It is a
``torch.autograd.Function``: the forward runs the Taichi kernels and the backward runs their ``ti.ad`` adjoints
(the hand-written ``rasterize.grad`` then the automatic ``project_gaussians.grad``), so an image loss
back-propagates through torch into whatever produced the Gaussians (for instance the simulator's bridge).

The Gaussians are composited over a background: one colour, or one image per camera (a clean plate). A second,
static set of Gaussians (``static=``) joins the smoke in the same depth sort, so static objects hide the smoke
behind them and the smoke in front of them hides them.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import torch

from .splat_bin import count_tiles, fill_tiles
from .splat_buffers import clear_gaussian_grads, clear_scalar_grads, splat_fields
from .splat_gaussians import Gaussians
from .splat_project import DEFAULT_NEAR, bound_footprints, pack_camera, project_gaussians
from .splat_raster import rasterize
from .tensors import load, store, torch_device, torch_dtype

DEFAULT_TILE = 16

_tokens = itertools.count()


@dataclass
class _Frame:
    """What one forward leaves for its backward: the image layout, tile lists and per-pixel state.

    ``first`` and ``slots`` list each Gaussian's tile entries (``splat_bin.fill_tiles``) for the backward.
    ``background`` is the flat, detached background the kernels read: [C] when ``background_stride`` is 0 (one
    colour), [H * W * C] when it is C (one colour per pixel).
    """

    token: int
    n: int
    channels: int
    with_depth: bool
    width: int
    height: int
    tile: int
    tiles_x: int
    n_tiles: int
    camera_packed: torch.Tensor
    background: torch.Tensor
    background_stride: int
    start: torch.Tensor
    lists: torch.Tensor
    rect: torch.Tensor
    power_min: torch.Tensor
    t_final: torch.Tensor
    last: torch.Tensor
    first: torch.Tensor
    slots: torch.Tensor

    def raster_args(self, fields):
        return (fields.gauss, fields.pixels, self.background, self.background_stride, self.channels,
                self.with_depth, self.tile, self.width, self.height, self.tiles_x, self.n_tiles, self.start,
                self.lists, self.rect, self.power_min, self.t_final, self.last, self.n, self.first, self.slots)


def _rows(t: torch.Tensor) -> torch.Tensor:
    """``t`` with at least one row (kernels get n separately), contiguous, for passing as an ndarray."""
    if t.shape[0] == 0:
        t = torch.zeros((1,) + tuple(t.shape[1:]), dtype=t.dtype, device=t.device)
    return t.contiguous()


def _load_inputs(fields, frame: _Frame, means, scales, quats, opacities, colors) -> None:
    """Copy the Gaussians and the camera into the Taichi fields and project the Gaussians."""
    g = fields.gauss
    for field, values in ((g.means, means), (g.scales, scales), (g.quats, quats), (g.opacities, opacities),
                          (g.colors, colors), (fields.camera, frame.camera_packed)):
        load(field, values)
    project_gaussians(g, fields.camera, frame.n)
    fields.owner = frame.token


def _bin(fields, frame: _Frame) -> None:
    """Cull, bound and sort the projected Gaussians into per-tile lists (fills frame.start/lists/power_min)."""
    n, dev = frame.n, frame.camera_packed.device
    rect = torch.empty((max(n, 1), 4), dtype=torch.int32, device=dev)
    power_min = torch.empty(max(n, 1), dtype=frame.camera_packed.dtype, device=dev)
    key = torch.empty(max(n, 1), dtype=frame.camera_packed.dtype, device=dev)
    bound_footprints(fields.gauss, fields.camera, n, rect, power_min, key)
    order = torch.argsort(key[:n], stable=True).to(torch.int32)
    counts = torch.zeros(frame.n_tiles + 1, dtype=torch.int32, device=dev)
    count_tiles(rect, n, frame.tile, frame.tiles_x, counts)
    start = torch.cumsum(counts, 0, dtype=torch.int32)
    entries = max(int(start[-1]), 1)
    lists = torch.empty(entries, dtype=torch.int32, device=dev)
    slots = torch.empty(entries, dtype=torch.int32, device=dev)
    first = torch.zeros(n + 1, dtype=torch.int32, device=dev)
    fill_tiles(_rows(order), rect, n, frame.tile, frame.tiles_x, start[:-1].clone(), lists, first, slots)
    frame.start, frame.lists, frame.rect, frame.power_min = start, lists, rect, power_min
    frame.first, frame.slots = first, slots


def prepare_frame(camera, means, scales, quats, opacities, colors, background, near: float, tile: int,
                  with_depth: bool):
    """Everything before compositing: load the inputs into the fields, project, cull and bin.

    Tensors must already be in the engine's dtype and device; ``background`` is [C] (one colour) or [H, W, C]
    (one per pixel). Returns the fields and the :class:`_Frame`, whose ``raster_args(fields)`` are the arguments
    of ``splat_raster.rasterize``.
    """
    n, channels = means.shape[0], colors.shape[1]
    width, height = camera.width, camera.height
    tiles_x, tiles_y = -(-width // tile), -(-height // tile)
    dtype, dev = means.dtype, means.device
    frame = _Frame(next(_tokens), n, channels, with_depth, width, height, tile, tiles_x, tiles_x * tiles_y,
                   torch.as_tensor(pack_camera(camera, near), dtype=dtype, device=dev),
                   background=background.detach().reshape(-1).contiguous(),
                   background_stride=channels if background.dim() == 3 else 0,
                   start=None, lists=None, rect=None, power_min=None,
                   t_final=torch.empty(width * height, dtype=dtype, device=dev),
                   last=torch.empty(width * height, dtype=torch.int32, device=dev), first=None, slots=None)
    fields = splat_fields()
    fields.reserve(n, width * height, channels)
    _load_inputs(fields, frame, means, scales, quats, opacities, colors)
    _bin(fields, frame)
    return fields, frame


class _RenderFunction(torch.autograd.Function):
    """Taichi forward and ``ti.ad`` backward of :func:`render` (camera, near, tile, with_depth are constants).

    The depth output is empty when with_depth is False (the kernels then skip it).
    """

    @staticmethod
    def forward(ctx, means, scales, quats, opacities, colors, background, camera, near, tile, with_depth):
        fields, frame = prepare_frame(camera, means, scales, quats, opacities, colors, background, near, tile,
                                      with_depth)
        rasterize(*frame.raster_args(fields))
        pix, width, height, channels = fields.pixels, frame.width, frame.height, frame.channels
        dtype, dev = means.dtype, means.device
        image = torch.empty((height, width, channels), dtype=dtype, device=dev)
        alpha = torch.empty((height, width), dtype=dtype, device=dev)
        depth = torch.empty((height, width) if with_depth else (0,), dtype=dtype, device=dev)
        store(pix.image, width * height * channels, out=image)
        store(pix.alpha, width * height, out=alpha)
        if with_depth:
            store(pix.depth, width * height, out=depth)
        ctx.frame = frame
        ctx.save_for_backward(means, scales, quats, opacities, colors, background)
        ctx.set_materialize_grads(False)
        return image, alpha, depth

    @staticmethod
    def backward(ctx, grad_image, grad_alpha, grad_depth):
        frame = ctx.frame
        means, scales, quats, opacities, colors, background = ctx.saved_tensors
        fields = splat_fields()
        fields.reserve(frame.n, frame.width * frame.height, frame.channels)
        if fields.owner != frame.token:  # another render ran in between: restore this one's projection
            _load_inputs(fields, frame, means, scales, quats, opacities, colors)
        g, pix, n, n_pix = fields.gauss, fields.pixels, frame.n, frame.width * frame.height
        clear_gaussian_grads(g, n, frame.channels)
        outputs = [(pix.image, grad_image, n_pix * frame.channels), (pix.alpha, grad_alpha, n_pix)]
        if frame.with_depth:
            outputs.append((pix.depth, grad_depth, n_pix))
        for field, grad, size in outputs:
            if grad is None:  # that output does not reach the loss
                clear_scalar_grads(field, size)
            else:
                load(field.grad, grad)
        rasterize.grad(*frame.raster_args(fields))
        project_gaussians.grad(g, fields.camera, n)
        grads = [store(field.grad, count, out=torch.empty(like.shape, dtype=like.dtype, device=like.device))
                 for field, like, count in ((g.means, means, n), (g.scales, scales, n), (g.quats, quats, n),
                                            (g.opacities, opacities, n), (g.colors, colors, n * frame.channels))]
        grad_background = None
        if ctx.needs_input_grad[5] and grad_image is not None:
            # C = ... + T_N B (Kerbl et al. 2023, Eq. 3 with a background B): dL/dB(p) = T_N(p) dL/dC(p) for a
            # per-pixel B, and dL/dB = sum_p T_N(p) dL/dC(p) for one colour.
            grad_flat = grad_image.reshape(-1, frame.channels)
            if frame.background_stride:
                grad_background = (frame.t_final[:, None] * grad_flat).reshape(background.shape)
            else:
                grad_background = frame.t_final @ grad_flat
        return (*grads, grad_background, None, None, None, None)


def reserve_gaussians(n: int) -> None:
    """Size the renderer for up to ``n`` Gaussians now.

    The renderer's fields otherwise grow by doubling as the splat count grows, and each doubling re-instantiates
    the render kernels for the new fields (20-30 s on a 2-core CPU). A caller that knows its largest count, such
    as a reconstruction whose visual particles accumulate frame by frame, compiles them once instead.
    """
    splat_fields().reserve(int(n), 0, 1)


def render(camera, means: torch.Tensor, scales: torch.Tensor, quats: torch.Tensor, opacities: torch.Tensor,
           colors: torch.Tensor, background: torch.Tensor | None = None, return_depth: bool = False,
           near: float = DEFAULT_NEAR, tile: int = DEFAULT_TILE, static: Gaussians | None = None):
    """Render 3D Gaussians seen by ``camera`` over a background; differentiable in every tensor argument.

    Each pixel is C = sum_i c_i alpha_i T_i + T_N B(pixel) (Kerbl et al. 2023, Eq. 3, with a background B that
    may vary per pixel). Tensors are converted to the running Taichi precision and device
    (``fluidnexus.engine.init``); outputs come back in that dtype on the means' device.

    Args:
        camera: a :class:`fluidnexus.camera.Camera` (OpenCV axes; pixel (col, row) is sampled at its centre).
        means: [N, 3] centres, world metres.
        scales: [N, 3] standard deviations along the Gaussian's body axes, metres (not log).
        quats: [N, 4] rotations (w, x, y, z), body to world; normalised inside, must be non-zero.
        opacities: [N] peak opacities in [0, 1].
        colors: [N, C] colours, C = 1 (grayscale) or 3 (RGB) or any C >= 1.
        background: what lies behind every Gaussian: [C] one colour, or [H, W, C] one per pixel (this camera's
            clean plate); default black.
        return_depth: also return the accumulated depth.
        near: near plane in metres; Gaussians with camera z <= near are culled.
        tile: tile edge in pixels.
        static: a second set of Gaussians (backdrop, obstacles) with the same C, depth sorted together with the
            smoke in one composite. Its tensors get gradients when they require grad and stay frozen otherwise.
            Size the renderer for both sets together (``reserve_gaussians(N + len(static))``).
    Returns:
        image [H, W, C]; alpha [H, W] = 1 - T_N, the matte of everything drawn (smoke and static), so the
        background's weight is 1 - alpha; and depth [H, W] (sum of alpha-weighted camera-space z in metres over
        both sets; divide by alpha for the expected depth) or None.
    """
    smoke = Gaussians(means, scales, quats, opacities, colors)
    smoke.check()
    channels = colors.shape[1]
    if static is not None:
        static.check("static")
        if static.colors.shape[1] != channels:
            raise ValueError(f"static.colors has {static.colors.shape[1]} channels, the smoke's colors {channels}")
    out_device = means.device
    dtype, dev = torch_dtype(), torch_device()
    if background is None:
        background = torch.zeros(channels, dtype=dtype, device=dev)
    if tuple(background.shape) not in ((channels,), (camera.height, camera.width, channels)):
        raise ValueError(f"background must have shape ({channels},) or (H, W, C) = "
                         f"({camera.height}, {camera.width}, {channels}), got {tuple(background.shape)}")
    gaussians = smoke.to(dtype, dev)
    if static is not None:
        gaussians = gaussians.union(static.to(dtype, dev))
    background = background.to(device=dev, dtype=dtype)
    image, alpha, depth = _RenderFunction.apply(*gaussians.tensors(), background, camera, float(near), int(tile),
                                                bool(return_depth))
    image, alpha = image.to(out_device), alpha.to(out_device)
    return image, alpha, (depth.to(out_device) if return_depth else None)
