"""Front-to-back alpha compositing of the binned 2D Gaussians, with a hand-written backward.

Kerbl et al. 2023, Eq. (3): C = sum_i c_i alpha_i T_i + T_N B with T_i = prod_{j<i} (1 - alpha_j) and
alpha_i = min(0.99, o_i exp(power_i)), power_i = -1/2 d^T Sigma'_i^-1 d, d = pixel centre - projected centre.
As in the 3DGS reference, contributions with alpha < 1/255 are skipped and a pixel stops once its
transmittance would fall below 1e-4. The outputs are the image, alpha = 1 - T_N and the accumulated depth
D = sum_i z_i alpha_i T_i (divide by alpha for the expected depth). The background B is one colour or one colour
per pixel (``bg_stride``, below).

:func:`rasterize` is attached to its backward with ``ti.ad.grad_replaced``/``grad_for``: ``rasterize.grad``
walks each pixel's contributors back to front (3DGS), recovering T_i = T_{i+1} / (1 - alpha_i), so it needs no
per-contributor storage, and adds into the ``.grad`` of the projected Gaussians, opacities and colours.

Work is split by tile, one tile per task, and inside a tile the kernels go through the tile's depth-sorted list
once, updating only the pixels inside each Gaussian's footprint ellipse, row by row (splat order). Each pixel
still sees its Gaussians front to back, so the result equals the per-pixel loop of 3DGS, but the work is the
footprint area instead of the tile area per Gaussian. Per-pixel state lives in the pixel buffers (each tile's
pixels are touched by one task only), so nothing per pixel needs an atomic.

The backward is deterministic (bit-identical reruns on any thread count): each (Gaussian, tile) pair sums its
gradient over the tile's pixels in registers and writes it to its own row of a partial-sum buffer (one row per
tile-list entry); a second kernel then adds each Gaussian's rows in a fixed order (its tiles in the order
``splat_bin.fill_tiles`` listed them). No float atomic adds, so the sum order never depends on scheduling.
"""

import taichi as ti
import torch

from .splat_project import ALPHA_MIN

ALPHA_MAX = 0.99
T_MIN = 1e-4


@ti.func
def tile_bounds(t, tile, tiles_x, width, height):
    """Pixel columns [x0, x1) and rows [y0, y1) of tile t."""
    x0 = (t % tiles_x) * tile
    y0 = (t // tiles_x) * tile
    return x0, ti.min(x0 + tile, width), y0, ti.min(y0 + tile, height)


@ti.func
def splat_power(xy, con, col, row):
    """Exponent of the 2D Gaussian (centre xy, conic con) at the centre of pixel (col, row), and d = pixel - xy."""
    dx = col + 0.5 - xy[0]  # int + literal is the default float type (= real())
    dy = row + 0.5 - xy[1]
    return -0.5 * (con[0] * dx * dx + con[2] * dy * dy) - con[1] * dx * dy, dx, dy


@ti.func
def row_span(xy, con, floor, row, x0, x1):
    """Columns [c0, c1) of ``row``, within [x0, x1), whose pixel centres can reach power >= floor.

    power >= floor is a x^2 + 2 b dy x + c dy^2 + 2 floor <= 0 for x = col + 0.5 - xy[0], dy = row + 0.5 - xy[1]:
    a chord of the footprint ellipse. ``floor`` sits BOUND_SLACK below the alpha = 1/255 level, so rounding at
    the chord ends cannot drop a pixel that passes the alpha test.
    """
    dy = row + 0.5 - xy[1]
    disc = (con[1] * dy) ** 2 - con[0] * (con[2] * dy * dy + 2.0 * floor)
    c0, c1 = x0, x0
    if disc >= 0.0:
        root = ti.sqrt(disc)
        lo = xy[0] - 0.5 + (-con[1] * dy - root) / con[0]
        hi = xy[0] - 0.5 + (-con[1] * dy + root) / con[0]
        c0 = ti.max(x0, ti.cast(ti.ceil(ti.math.clamp(lo, x0 - 1.0, x1 + 1.0)), ti.i32))
        c1 = ti.min(x1, ti.cast(ti.floor(ti.math.clamp(hi, x0 - 1.0, x1 + 1.0)), ti.i32) + 1)
    return c0, c1


@ti.kernel
def composite_forward(g: ti.template(), pix: ti.template(), bg: ti.types.ndarray(), bg_stride: ti.template(),
                      channels: ti.template(),
                      with_depth: ti.template(), tile: ti.i32, width: ti.i32, height: ti.i32, tiles_x: ti.i32,
                      n_tiles: ti.i32,
                      start: ti.types.ndarray(), lists: ti.types.ndarray(), rect: ti.types.ndarray(),
                      power_min: ti.types.ndarray(), t_final: ti.types.ndarray(), last: ti.types.ndarray()):
    """Composite every pixel front to back into ``pix``; record its final transmittance and last contributor.

    Args:
        bg: the background, pixel p channel c at ``bg[p * bg_stride + c]``: bg_stride = 0 for one colour [C],
            bg_stride = C for a per-pixel image [H * W * C] (a compile-time switch).
        with_depth: also composite the depth image (a compile-time switch).
        start: [n_tiles + 1] int32, tile t's entries are lists[start[t]:start[t + 1]].
        lists: [entries] int32 Gaussian indices. rect: [N, 4] int32 footprint pixel rectangles (see
            ``bound_footprints``). power_min: [N] exponent below which alpha < 1/255.
        t_final: [H * W] real out. last: [H * W] int32 out, the list entry of the last contributor
            (start - 1 when none). While compositing, a pixel that stopped early holds -3 - last.
    """
    ti.loop_config(block_dim=1)
    for t in range(n_tiles):
        x0, x1, y0, y1 = tile_bounds(t, tile, tiles_x, width, height)
        for row in range(y0, y1):
            for col in range(x0, x1):
                p = row * width + col
                t_final[p] = 1.0
                last[p] = start[t] - 1
                for c in ti.static(range(channels)):
                    pix.image[p * channels + c] = 0.0
                if ti.static(with_depth):
                    pix.depth[p] = 0.0
        active = (x1 - x0) * (y1 - y0)
        for e in range(start[t], start[t + 1]):
            if active == 0:
                break
            k = lists[e]
            op, z, floor, xy, con = g.opacities[k], g.depth[k], power_min[k], g.xy[k], g.conic[k]
            color = ti.Vector([g.colors[k * channels + c] for c in ti.static(range(channels))])
            for row in range(ti.max(rect[k, 2], y0), ti.min(rect[k, 3] + 1, y1)):
                c0, c1 = row_span(xy, con, floor, row, x0, x1)
                for col in range(c0, c1):
                    p = row * width + col
                    if last[p] >= -1:  # not stopped
                        power, _dx, _dy = splat_power(xy, con, col, row)
                        if power >= floor:
                            alpha = ti.min(ALPHA_MAX, op * ti.exp(power))
                            if alpha >= ALPHA_MIN:
                                trans = t_final[p]
                                next_trans = trans * (1.0 - alpha)
                                if next_trans < T_MIN:
                                    last[p] = -3 - last[p]  # stopped; decoded below
                                    active -= 1
                                else:
                                    w = alpha * trans
                                    for c in ti.static(range(channels)):
                                        pix.image[p * channels + c] += w * color[c]
                                    if ti.static(with_depth):
                                        pix.depth[p] += w * z
                                    t_final[p] = next_trans
                                    last[p] = e
        for row in range(y0, y1):
            for col in range(x0, x1):
                p = row * width + col
                if last[p] < -1:
                    last[p] = -3 - last[p]
                for c in ti.static(range(channels)):
                    pix.image[p * channels + c] += t_final[p] * bg[p * bg_stride + c]
                pix.alpha[p] = 1.0 - t_final[p]


PARTIAL_XY, PARTIAL_CONIC, PARTIAL_OPACITY, PARTIAL_DEPTH, PARTIAL_COLOR = 0, 2, 5, 6, 7  # partial-sum columns


@ti.kernel
def composite_backward(g: ti.template(), pix: ti.template(), bg: ti.types.ndarray(), bg_stride: ti.template(),
                       channels: ti.template(),
                       with_depth: ti.template(), tile: ti.i32, width: ti.i32, height: ti.i32, tiles_x: ti.i32,
                       n_tiles: ti.i32,
                       start: ti.types.ndarray(), lists: ti.types.ndarray(), rect: ti.types.ndarray(),
                       power_min: ti.types.ndarray(), t_final: ti.types.ndarray(), last: ti.types.ndarray(),
                       trans: ti.types.ndarray(), behind: ti.types.ndarray(), partial: ti.types.ndarray()):
    """Adjoint of :func:`composite_forward`, per (Gaussian, tile): dL/d(xy, conic, opacity, depth, colour).

    With S_i = sum_{j>i} c_j alpha_j T_j + T_N B (what lies behind contributor i, B the pixel's background):
    dC/dalpha_i = c_i T_i - S_i / (1 - alpha_i), dA/dalpha_i = T_N / (1 - alpha_i) and
    dD/dalpha_i = z_i T_i - S^D_i / (1 - alpha_i) with S^D the same sum over depths (no background). With the
    upstream gradients g_C, g_A, g_D of the pixel, dL/dalpha_i = T_i (g_C . c_i + g_D z_i) - B_i / (1 - alpha_i)
    where B_i = g_C . S_i - g_A T_N + g_D S^D_i is one running scalar per pixel. Then alpha_i = o_i exp(power_i)
    passes dL/dalpha_i on to o_i and power_i (nothing where alpha is clamped at 0.99).

    Args:
        trans: [H * W] real scratch, T_i while walking back. behind: [H * W] real scratch, B_i.
        partial: [entries, 7 + channels] real out: row e holds the gradient of list entry e's Gaussian from
            the pixels of its tile (columns PARTIAL_XY.., zero for entries behind every pixel's last contributor).
    """
    ti.loop_config(block_dim=1)
    for t in range(n_tiles):
        x0, x1, y0, y1 = tile_bounds(t, tile, tiles_x, width, height)
        tile_last = start[t] - 1  # the deepest entry any pixel of the tile used (3DGS skips the rest too)
        for row in range(y0, y1):
            for col in range(x0, x1):
                p = row * width + col
                tile_last = ti.max(tile_last, last[p])
                trans[p] = t_final[p]
                behind[p] = -pix.alpha.grad[p] * t_final[p]
                for c in ti.static(range(channels)):
                    behind[p] += pix.image.grad[p * channels + c] * t_final[p] * bg[p * bg_stride + c]
        for back in range(tile_last - start[t] + 1):
            e = tile_last - back
            k = lists[e]
            op, z, floor, xy, con = g.opacities[k], g.depth[k], power_min[k], g.xy[k], g.conic[k]
            color = ti.Vector([g.colors[k * channels + c] for c in ti.static(range(channels))])
            grad_xy = ti.Vector.zero(g.xy.dtype, 2)
            grad_con = ti.Vector.zero(g.xy.dtype, 3)
            grad_col = ti.Vector.zero(g.xy.dtype, channels)
            grad_op = 0.0
            grad_z = 0.0
            for row in range(ti.max(rect[k, 2], y0), ti.min(rect[k, 3] + 1, y1)):
                c0, c1 = row_span(xy, con, floor, row, x0, x1)
                for col in range(c0, c1):
                    p = row * width + col
                    if e <= last[p]:
                        power, dx, dy = splat_power(xy, con, col, row)
                        if power >= floor:
                            falloff = ti.exp(power)
                            raw = op * falloff
                            alpha = ti.min(ALPHA_MAX, raw)
                            if alpha >= ALPHA_MIN:
                                inv = 1.0 / (1.0 - alpha)
                                t_i = trans[p] * inv
                                trans[p] = t_i
                                w = alpha * t_i
                                front = 0.0  # dL/d(this contributor's colour and depth) . (colour, depth)
                                for c in ti.static(range(channels)):
                                    grad_c = pix.image.grad[p * channels + c]
                                    grad_col[c] += w * grad_c
                                    front += grad_c * color[c]
                                if ti.static(with_depth):
                                    grad_d = pix.depth.grad[p]
                                    grad_z += w * grad_d
                                    front += grad_d * z
                                grad_alpha = t_i * front - inv * behind[p]
                                behind[p] += w * front
                                if raw < ALPHA_MAX:
                                    grad_op += grad_alpha * falloff
                                    grad_power = grad_alpha * alpha
                                    grad_xy += grad_power * ti.Vector([con[0] * dx + con[1] * dy,
                                                                       con[2] * dy + con[1] * dx])
                                    grad_con += grad_power * ti.Vector([-0.5 * dx * dx, -dx * dy, -0.5 * dy * dy])
            for d in ti.static(range(2)):
                partial[e, PARTIAL_XY + d] = grad_xy[d]
            for d in ti.static(range(3)):
                partial[e, PARTIAL_CONIC + d] = grad_con[d]
            partial[e, PARTIAL_OPACITY] = grad_op
            partial[e, PARTIAL_DEPTH] = grad_z
            for c in ti.static(range(channels)):
                partial[e, PARTIAL_COLOR + c] = grad_col[c]
        for e in range(tile_last + 1, start[t + 1]):  # entries no pixel reached
            for j in ti.static(range(PARTIAL_COLOR + channels)):
                partial[e, j] = 0.0


@ti.kernel
def gather_gradients(g: ti.template(), channels: ti.template(), n: ti.i32, first: ti.types.ndarray(),
                     slots: ti.types.ndarray(), lists: ti.types.ndarray(), partial: ti.types.ndarray()):
    """Add each Gaussian's per-tile partial sums into its ``.grad``s, in the fixed order of its tiles.

    Args:
        first: [n + 1] int32, the Gaussian of depth rank r owns slots[first[r]:first[r + 1]].
        slots: [entries] int32, the tile-list entries of each Gaussian (see ``splat_bin.fill_tiles``).
        lists: [entries] int32, the Gaussian of each entry. partial: see :func:`composite_backward`.
    """
    for r in range(n):
        if first[r + 1] > first[r]:
            acc = ti.Vector.zero(g.xy.dtype, PARTIAL_COLOR + channels)
            for s in range(first[r], first[r + 1]):
                e = slots[s]
                for j in ti.static(range(PARTIAL_COLOR + channels)):
                    acc[j] += partial[e, j]
            k = lists[slots[first[r]]]
            g.xy.grad[k] += ti.Vector([acc[PARTIAL_XY], acc[PARTIAL_XY + 1]])
            g.conic.grad[k] += ti.Vector([acc[PARTIAL_CONIC], acc[PARTIAL_CONIC + 1], acc[PARTIAL_CONIC + 2]])
            g.opacities.grad[k] += acc[PARTIAL_OPACITY]
            g.depth.grad[k] += acc[PARTIAL_DEPTH]
            for c in ti.static(range(channels)):
                g.colors.grad[k * channels + c] += acc[PARTIAL_COLOR + c]


_scratch_cache = {}


def _scratch(t_final, entries: int, columns: int):
    """The backward's scratch, reused between calls: trans and behind [H * W], partial [entries, columns]."""
    key = (t_final.dtype, t_final.device, columns)
    trans, behind, partial = _scratch_cache.get(key, (None, None, None))
    if trans is None or trans.shape[0] < t_final.shape[0]:
        trans = torch.empty(t_final.shape[0], dtype=t_final.dtype, device=t_final.device)
        behind = torch.empty_like(trans)
    if partial is None or partial.shape[0] < entries:
        partial = torch.empty((entries, columns), dtype=t_final.dtype, device=t_final.device)
    _scratch_cache[key] = trans, behind, partial
    return trans, behind, partial


@ti.ad.grad_replaced
def rasterize(g, pix, bg, bg_stride, channels, with_depth, tile, width, height, tiles_x, n_tiles, start, lists,
              rect, power_min, t_final, last, n, first, slots):
    """Composite the binned Gaussians into ``pix``.

    See :func:`composite_forward` for the arguments; ``n``, ``first`` and ``slots`` (the n Gaussians' tile
    entries, see :func:`gather_gradients`) are for the backward.
    """
    composite_forward(g, pix, bg, bg_stride, channels, with_depth, tile, width, height, tiles_x, n_tiles, start,
                      lists, rect, power_min, t_final, last)


@ti.ad.grad_for(rasterize)
def rasterize_grad(g, pix, bg, bg_stride, channels, with_depth, tile, width, height, tiles_x, n_tiles, start, lists,
                   rect, power_min, t_final, last, n, first, slots):
    """Hand-written adjoint of :func:`rasterize`, reading ``pix.*.grad`` and adding into ``g.*.grad``."""
    trans, behind, partial = _scratch(t_final, lists.shape[0], PARTIAL_COLOR + channels)
    composite_backward(g, pix, bg, bg_stride, channels, with_depth, tile, width, height, tiles_x, n_tiles, start,
                       lists, rect, power_min, t_final, last, trans, behind, partial)
    gather_gradients(g, channels, n, first, slots, lists, partial)
