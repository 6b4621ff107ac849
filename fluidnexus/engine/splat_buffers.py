"""Taichi fields of the splat renderer, grown on demand, and the kernels that clear their gradients.

Only the quantities that carry gradients live in Taichi fields (``needs_grad=True``): the per-Gaussian inputs,
their projections and the per-pixel outputs. Bookkeeping (tile lists, per-pixel transmittance) lives in torch
tensors passed to kernels as ndarrays, so its size never forces a recompile. Tensors move in and out of the
fields through ``tensors.load`` / ``tensors.store`` (the engine's one torch bridge).

Capacities grow geometrically (powers of two), so a kernel is re-instantiated for new fields only
O(log N) times per process; ``splat.reserve_gaussians`` sizes them up front for a caller that knows its
count. Fields of an outgrown capacity are not freed (at most about as much memory again).
"""

import taichi as ti

from .runtime import current, real

MIN_GAUSSIANS = 1024
MIN_PIXELS = 64 * 64
MIN_CHANNELS = 3
CAMERA_SLOTS = 24


def _capacity(needed: int, minimum: int) -> int:
    cap = minimum
    while cap < needed:
        cap *= 2
    return cap


@ti.data_oriented
class GaussianFields:
    """Per-Gaussian fields for up to ``cap`` Gaussians with up to ``channels`` colour channels.

    Attributes (all ``needs_grad``):
        means, scales: [cap] 3-vectors, metres. quats: [cap] 4-vectors (w, x, y, z), not normalised.
        opacities: [cap]. colors: [cap * channels] flat, Gaussian g channel c at ``g * C + c``.
        xy: [cap] 2-vectors, projected centre in pixels. conic: [cap] 3-vectors (a, b, c) of the inverse 2D
        covariance [[a, b], [b, c]] in 1/pixel^2. depth: [cap] camera-space z in metres.
    """

    def __init__(self, cap: int, channels: int):
        f = real()
        self.cap, self.channels = cap, channels
        self.means = ti.Vector.field(3, f, shape=cap, needs_grad=True)
        self.scales = ti.Vector.field(3, f, shape=cap, needs_grad=True)
        self.quats = ti.Vector.field(4, f, shape=cap, needs_grad=True)
        self.opacities = ti.field(f, shape=cap, needs_grad=True)
        self.colors = ti.field(f, shape=cap * channels, needs_grad=True)
        self.xy = ti.Vector.field(2, f, shape=cap, needs_grad=True)
        self.conic = ti.Vector.field(3, f, shape=cap, needs_grad=True)
        self.depth = ti.field(f, shape=cap, needs_grad=True)


@ti.data_oriented
class PixelFields:
    """Per-pixel outputs for up to ``cap`` pixels and ``channels`` channels (all ``needs_grad``).

    Attributes:
        image: [cap * channels] flat, pixel p (row-major, p = row * W + col) channel c at ``p * C + c``.
        alpha: [cap] accumulated opacity. depth: [cap] alpha-weighted camera-space z (metres).
    """

    def __init__(self, cap: int, channels: int):
        f = real()
        self.cap, self.channels = cap, channels
        self.image = ti.field(f, shape=cap * channels, needs_grad=True)
        self.alpha = ti.field(f, shape=cap, needs_grad=True)
        self.depth = ti.field(f, shape=cap, needs_grad=True)


class SplatFields:
    """The renderer's fields for the running Taichi configuration; call :meth:`reserve` before each render.

    Attributes:
        camera: [CAMERA_SLOTS] real, the packed camera (see ``splat_project.pack_camera``).
        gauss: :class:`GaussianFields`. pixels: :class:`PixelFields`.
        owner: an id of the render whose forward state the fields hold (for a backward that comes later).
    """

    def __init__(self):
        self.config = current()
        self.camera = ti.field(real(), shape=CAMERA_SLOTS)
        self.channels = MIN_CHANNELS
        self.gauss = GaussianFields(MIN_GAUSSIANS, self.channels)
        self.pixels = PixelFields(MIN_PIXELS, self.channels)
        self.owner = None

    def reserve(self, n: int, n_pixels: int, channels: int) -> None:
        """Grow the fields so that ``n`` Gaussians, ``n_pixels`` pixels and ``channels`` channels fit."""
        if channels > self.channels:
            self.channels = channels
            self.gauss = GaussianFields(self.gauss.cap, channels)
            self.pixels = PixelFields(self.pixels.cap, channels)
            self.owner = None
        if n > self.gauss.cap:
            self.gauss = GaussianFields(_capacity(n, MIN_GAUSSIANS), self.channels)
            self.owner = None
        if n_pixels > self.pixels.cap:
            self.pixels = PixelFields(_capacity(n_pixels, MIN_PIXELS), self.channels)
            self.owner = None


_fields = None


def splat_fields() -> SplatFields:
    """The process's renderer fields, rebuilt when Taichi was restarted with another configuration."""
    global _fields
    if _fields is None or _fields.config is not current():
        _fields = SplatFields()
    return _fields


@ti.kernel
def clear_scalar_grads(dst: ti.template(), n: ti.i32):
    """dst.grad[i] = 0 for i < n."""
    for i in range(n):
        dst.grad[i] = 0.0


@ti.kernel
def clear_gaussian_grads(g: ti.template(), n: ti.i32, channels: ti.i32):
    """Zero the gradients of the first n Gaussians (inputs and projections) before a backward pass."""
    for i in range(n):
        g.means.grad[i] = ti.Vector.zero(g.means.dtype, 3)
        g.scales.grad[i] = ti.Vector.zero(g.scales.dtype, 3)
        g.quats.grad[i] = ti.Vector.zero(g.quats.dtype, 4)
        g.opacities.grad[i] = 0.0
        g.xy.grad[i] = ti.Vector.zero(g.xy.dtype, 2)
        g.conic.grad[i] = ti.Vector.zero(g.conic.dtype, 3)
        g.depth.grad[i] = 0.0
        for c in range(channels):
            g.colors.grad[i * channels + c] = 0.0
