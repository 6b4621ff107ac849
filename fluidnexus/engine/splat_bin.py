"""Tile binning: per-tile lists of Gaussian indices in front-to-back order (not differentiated).

As in 3D Gaussian Splatting (Kerbl et al. 2023, Sec. 6), every Gaussian is listed in each screen tile its
footprint touches. Gaussians are visited in global depth order, so each tile's list comes out sorted by depth
without a per-tile sort. All buffers are int32 torch tensors passed as ndarrays.
"""

import taichi as ti


@ti.kernel
def count_tiles(rect: ti.types.ndarray(), n: ti.i32, tile: ti.i32, tiles_x: ti.i32, counts: ti.types.ndarray()):
    """counts[t + 1] += number of Gaussians whose pixel rectangle touches tile t (counts must start at zero)."""
    for i in range(n):
        for ty in range(rect[i, 2] // tile, rect[i, 3] // tile + 1):
            for tx in range(rect[i, 0] // tile, rect[i, 1] // tile + 1):
                ti.atomic_add(counts[ty * tiles_x + tx + 1], 1)


@ti.kernel
def fill_tiles(order: ti.types.ndarray(), rect: ti.types.ndarray(), n: ti.i32, tile: ti.i32, tiles_x: ti.i32,
               cursor: ti.types.ndarray(), lists: ti.types.ndarray(), first: ti.types.ndarray(),
               slots: ti.types.ndarray()):
    """Append the Gaussians, visited in ``order`` (front to back), to the lists of the tiles they touch.

    Also records where each Gaussian went, so that its per-tile gradients can be summed in a fixed order
    (``splat_raster.gather_gradients``).

    Args:
        order: [n] int32, Gaussian indices sorted by depth. rect: [n, 4] pixel rectangles (first/last column, row).
        cursor: [tiles] int32, in: each tile's list start; used as the write position.
        lists: [entries] int32 out.
        first: [n + 1] int32, in: first[0] = 0; out: the Gaussian order[r] owns slots[first[r]:first[r + 1]].
        slots: [entries] int32 out, the list entries of each Gaussian, its tiles in row-major order.
    """
    ti.loop_config(serialize=True)
    for r in range(n):
        i = order[r]
        s = first[r]
        for ty in range(rect[i, 2] // tile, rect[i, 3] // tile + 1):
            for tx in range(rect[i, 0] // tile, rect[i, 1] // tile + 1):
                t = ty * tiles_x + tx
                lists[cursor[t]] = i
                slots[s] = cursor[t]
                cursor[t] += 1
                s += 1
        first[r + 1] = s
