"""Fixed-radius neighbour search: a hashed uniform grid (cell size h), counting sort, per-query table.

Built in its own non-differentiated kernels (integer fields only) and reused by every differentiated
kernel of a step (taichi-notes: walking grid cells inside a differentiated kernel breaks ``ti.ad``).

Cells are integer coordinates ``floor(x / h)`` hashed into ``n_buckets`` buckets, so any distribution works
with memory bounded by the capacity. A bucket can hold several cells (hash collisions); each query scans each
distinct bucket of its 27 cells once and accepts candidates by distance, so no pair is missed or counted twice.
The table has a width (neighbours per query, plus one spare slot the branch-free fill writes into); when a query
has as many neighbours as the width or more, the table is reallocated wider and refilled, up to ``max_width``,
beyond which :class:`NeighborOverflow` is raised.
Nothing is ever dropped silently.
"""
import taichi as ti
import torch

from .runtime import real

_P1, _P2, _P3 = 73856093, 19349663, 83492791
_CELL_CLAMP = 1.0e6  # cell coordinates are clamped so far-away (or non-finite) points stay valid integers


def require_ad_stack(width: int) -> None:
    """Make kernels compiled from now on keep autodiff stacks deep enough for ``width`` neighbours.

    A differentiated loop over a dynamic neighbour count keeps its per-iteration locals on an autodiff stack
    whose depth Taichi cannot infer; its fallback depth (32) overflows (a crash, not an error) as soon as a
    particle has more neighbours. Kernels that take a table are recompiled when the table is reallocated,
    so raising the compile setting here covers every differentiated kernel that sees this table.
    """
    cfg = ti.lang.impl.current_cfg()
    need = 2 * int(width) + 8
    if cfg.ad_stack_size < need:
        cfg.ad_stack_size = need


class NeighborOverflow(RuntimeError):
    """A query point has more neighbours than the largest allowed table width."""


def _next_pow2(n: int) -> int:
    p = 1
    while p < n:
        p *= 2
    return p


@ti.func
def _cell_of(x, inv_h):
    c = ti.Vector([0, 0, 0])
    for d in ti.static(range(3)):
        c[d] = ti.cast(ti.floor(ti.math.clamp(x[d] * inv_h, -_CELL_CLAMP, _CELL_CLAMP)), ti.i32)
    return c


@ti.func
def _bucket_of(c, mask):
    return (c[0] * _P1 ^ c[1] * _P2 ^ c[2] * _P3) & mask


@ti.func
def _offset(o):
    """The o-th of the 27 cell offsets (-1..1)^3."""
    return ti.Vector([o // 9 - 1, (o // 3) % 3 - 1, o % 3 - 1])


@ti.func
def _pos(field: ti.template(), row, i):
    """Point i of a positions field that is either [N] or [rows, N] (then row ``row``)."""
    v = ti.Vector([0.0, 0.0, 0.0])
    if ti.static(len(field.shape) == 2):
        v = field[row, i]
    else:
        v = field[i]
    return v


@ti.kernel
def _assign_cells(src: ti.template(), row: int, n: int, inv_h: float, key: ti.template(), count: ti.template(),
                  start: ti.template(), mask: int):
    """Clear the bucket counts and starts, then count the points per bucket (one launch: the loops run in order)."""
    for b in count:
        count[b] = 0
    for b in start:
        start[b] = 0
    for i in range(n):
        b = _bucket_of(_cell_of(_pos(src, row, i), inv_h), mask)
        key[i] = b
        count[b] += 1


@ti.kernel
def _sort_by_bucket(n: int, n_buckets: int, key: ti.template(), count: ti.template(), start: ti.template(),
                    order: ti.template(), src: ti.template(), row: int, sorted_pos: ti.template()):
    """Exclusive prefix sum of the bucket counts, then a stable scatter (serial: deterministic order), then a
    bucket-ordered copy of the positions, so the candidate scan streams through memory."""
    ti.loop_config(serialize=True)
    for b in range(n_buckets):
        start[b + 1] = start[b] + count[b]
    ti.loop_config(serialize=True)
    for i in range(n):
        b = key[i]
        count[b] -= 1
        order[start[b + 1] - count[b] - 1] = i
    for s in range(n):
        sorted_pos[s] = _pos(src, row, order[s])


@ti.kernel
def _fill_table(query: ti.template(), qrow: int, nq: int, inv_h: float, h2: float, exclude_self: int,
                sorted_pos: ti.template(), start: ti.template(), order: ti.template(),
                mask: int, nbr: ti.template(), nbr_count: ti.template(), max_count: ti.template()):
    width = nbr.shape[1]
    max_count[None] = 0
    for i in range(nq):
        xi = _pos(query, qrow, i)
        ci = _cell_of(xi, inv_h)
        buckets = ti.Vector([0] * 27)
        for o in ti.static(range(27)):
            buckets[o] = _bucket_of(ci + _offset(o), mask)
        cnt = 0
        for o in range(27):
            b = buckets[o]
            seen = 0  # two of the 27 cells may share a bucket: scan each bucket once
            for e in range(o):
                if buckets[e] == b:
                    seen = 1
            if seen == 0:
                for s in range(start[b], start[b + 1]):
                    # branch-free: every candidate is written at the next free slot, which only a neighbour
                    # takes (a branch here mispredicts on most candidates: the fill took 1.7x as long)
                    j = order[s]
                    hit = ((xi - sorted_pos[s]).norm_sqr() < h2) & ((exclude_self == 0) | (j != i))
                    nbr[i, ti.min(cnt, width - 1)] = j
                    cnt += ti.cast(hit, ti.i32)
        nbr_count[i] = cnt
        ti.atomic_max(max_count[None], cnt)


@ti.kernel
def _count_sources(nq: int, nbr: ti.template(), count: ti.template(), out: ti.types.ndarray()):
    """out[j + 1] += number of queries listing source j (integer atomics: the counts do not depend on order)."""
    for i in range(nq):
        for k in range(count[i]):
            ti.atomic_add(out[nbr[i, k] + 1], 1)


@ti.kernel
def _fill_sources(nq: int, nbr: ti.template(), count: ti.template(), cursor: ti.types.ndarray(),
                  out: ti.types.ndarray()):
    """Append each query i to the list of every source it lists (in scheduling order; sorted afterwards)."""
    for i in range(nq):
        for k in range(count[i]):
            out[ti.atomic_add(cursor[nbr[i, k]], 1)] = i


@ti.kernel
def _sort_segments(n: int, start: ti.types.ndarray(), items: ti.types.ndarray()):
    """Sort items[start[j]:start[j + 1]] ascending for every j (insertion sort: the lists are short)."""
    for j in range(n):
        for a in range(start[j] + 1, start[j + 1]):
            v = items[a]
            b = a
            while b > start[j] and items[b - 1] > v:
                items[b] = items[b - 1]
                b -= 1
            items[b] = v


class NeighborTable:
    """Neighbours within radius ``h`` of up to ``query_capacity`` points among up to ``source_capacity`` points.

    After :meth:`build`, ``nbr[i, k]`` for ``k < count[i]`` are the source indices j with
    ``|q_i - p_j| < h`` (j != i when ``exclude_self``), in a deterministic order.

    Args:
        source_capacity: most source points.
        query_capacity: most query points (defaults to ``source_capacity``).
        width: initial table width (neighbours per query).
        max_width: the table never grows beyond this; ``max_width`` neighbours or more raise
            :class:`NeighborOverflow`.
    """

    def __init__(self, source_capacity: int, query_capacity: int | None = None, width: int = 48,
                 max_width: int = 4096):
        self.source_capacity = int(source_capacity)
        self.query_capacity = int(query_capacity or source_capacity)
        self.max_width = int(max_width)
        self.n_buckets = _next_pow2(max(2 * self.source_capacity, 64))
        self.key = ti.field(ti.i32, shape=self.source_capacity)
        self.bucket_count = ti.field(ti.i32, shape=self.n_buckets)
        self.bucket_start = ti.field(ti.i32, shape=self.n_buckets + 1)
        self.order = ti.field(ti.i32, shape=self.source_capacity)
        self.sorted_pos = ti.Vector.field(3, real(), shape=self.source_capacity)
        self.count = ti.field(ti.i32, shape=self.query_capacity)
        self.max_count = ti.field(ti.i32, shape=())
        self._allocate(int(width))
        self.n_query = 0

    @property
    def width(self) -> int:
        return self.nbr.shape[1]

    def _allocate(self, width: int) -> None:
        self.nbr = ti.field(ti.i32, shape=(self.query_capacity, width))
        require_ad_stack(width)

    def build(self, src, n_src: int, h: float, query=None, n_query: int | None = None, src_row: int = 0,
              query_row: int = 0) -> None:
        """Fill the table.

        Args:
            src: source positions, a Taichi vec3 field [N] or [rows, N] (then row ``src_row``) [m].
            n_src: active source points.
            h: search radius [m]; also the grid cell size.
            query: query positions (same layouts); ``None`` means the sources themselves, excluding self.
            n_query: active query points (defaults to ``n_src`` for a self table).
        """
        exclude_self = query is None
        if exclude_self:
            query, n_query, query_row = src, n_src, src_row
        if n_src > self.source_capacity or n_query > self.query_capacity:
            raise ValueError(f"neighbour search over capacity: {n_src}/{self.source_capacity} sources, "
                             f"{n_query}/{self.query_capacity} queries")
        mask = self.n_buckets - 1
        _assign_cells(src, src_row, n_src, 1.0 / h, self.key, self.bucket_count, self.bucket_start, mask)
        _sort_by_bucket(n_src, self.n_buckets, self.key, self.bucket_count, self.bucket_start, self.order, src,
                        src_row, self.sorted_pos)
        while True:
            _fill_table(query, query_row, n_query, 1.0 / h, h * h, int(exclude_self), self.sorted_pos,
                        self.bucket_start, self.order, mask, self.nbr, self.count, self.max_count)
            needed = int(self.max_count[None])
            if needed < self.width:  # the fill writes each candidate after the last neighbour: one slot to spare
                break
            if needed >= self.max_width:
                raise NeighborOverflow(f"a query point has {needed} neighbours within h={h} m; the table "
                                       f"allows at most {self.max_width - 1} (raise max_width or check the input)")
            self._allocate(min(self.max_width, ((needed * 5 // 4) + 7) // 8 * 8))  # more than needed
        self.n_query = n_query

    def transpose(self, n_src: int) -> tuple[torch.Tensor, torch.Tensor]:
        """The table read the other way: for each source j, the queries that have j as a neighbour.

        Each list is in increasing query order, so a gather over it sums in a fixed order (a deterministic
        adjoint where the forward scattered nothing and the table is not symmetric).

        Returns:
            (start [n_src + 1] int32, queries [pairs] int32): source j's queries are queries[start[j]:start[j + 1]].
        """
        count = torch.zeros(n_src + 1, dtype=torch.int32)
        _count_sources(self.n_query, self.nbr, self.count, count)
        start = torch.cumsum(count, 0, dtype=torch.int32)  # count[j + 1] holds j's count: start[0] = 0
        queries = torch.empty(max(int(start[-1]), 1), dtype=torch.int32)
        _fill_sources(self.n_query, self.nbr, self.count, start[:-1].clone(), queries)
        _sort_segments(n_src, start, queries)
        return start, queries

    def counts(self):
        """Neighbour counts of the active queries as a numpy int array [n_query]."""
        return self.count.to_numpy()[: self.n_query]

    def lists(self) -> list:
        """Neighbour index lists of the active queries (for tests and housekeeping)."""
        nbr, cnt = self.nbr.to_numpy(), self.count.to_numpy()
        return [nbr[i, : cnt[i]] for i in range(self.n_query)]
