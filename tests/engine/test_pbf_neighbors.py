"""Neighbour search vs scipy cKDTree: random, clustered, table growth, loud overflow."""
import numpy as np
import pytest
from scipy.spatial import cKDTree


def _table_pairs(engine, pts, h, width=48, max_width=4096, queries=None):
    import taichi as ti

    src = ti.Vector.field(3, engine.real(), shape=len(pts) + 3)
    src.from_numpy(np.concatenate([pts, np.zeros((3, 3))]))
    if queries is None:
        t = engine.NeighborTable(len(pts) + 3, width=width, max_width=max_width)
        t.build(src, len(pts), h)
    else:
        q = ti.Vector.field(3, engine.real(), shape=len(queries))
        q.from_numpy(queries)
        t = engine.NeighborTable(len(pts) + 3, len(queries), width=width, max_width=max_width)
        t.build(src, len(pts), h, query=q, n_query=len(queries))
    return {(i, int(j)) for i, lst in enumerate(t.lists()) for j in lst}, t


def _kd_pairs(pts, h, queries=None):
    if queries is None:
        pr = cKDTree(pts).query_pairs(h, output_type="ndarray")
        return {(int(a), int(b)) for a, b in pr} | {(int(b), int(a)) for a, b in pr}
    lists = cKDTree(queries).query_ball_tree(cKDTree(pts), h)
    return {(i, j) for i, lst in enumerate(lists) for j in lst}


@pytest.mark.parametrize("kind", ["random", "clustered", "negative_far"])
def test_neighbors_match_kdtree(ti_engine, kind):
    rng = np.random.default_rng(1)
    if kind == "random":
        pts = rng.uniform(0, 0.1, (800, 3))
    elif kind == "clustered":
        centres = rng.uniform(-0.2, 0.2, (5, 3))
        pts = np.concatenate([c + rng.normal(0, 0.01, (150, 3)) for c in centres])
    else:
        pts = np.concatenate([rng.uniform(-1.0, -0.9, (300, 3)), rng.uniform(50.0, 50.05, (300, 3))])
    got, table = _table_pairs(ti_engine, pts, 0.02)
    assert got == _kd_pairs(pts, 0.02)
    assert np.all(table.counts() == np.bincount([i for i, _ in got], minlength=len(pts)))


def test_query_table_matches_kdtree(ti_engine):
    rng = np.random.default_rng(2)
    pts, q = rng.uniform(0, 0.08, (500, 3)), rng.uniform(-0.01, 0.09, (300, 3))
    got, _ = _table_pairs(ti_engine, pts, 0.02, queries=q)
    assert got == _kd_pairs(pts, 0.02, q)


def test_table_grows_when_width_is_exceeded(ti_engine):
    rng = np.random.default_rng(3)
    pts = rng.normal(0, 0.003, (400, 3))  # nearly everyone within h of everyone
    got, table = _table_pairs(ti_engine, pts, 0.02, width=4)
    assert table.width >= table.counts().max() > 4
    assert got == _kd_pairs(pts, 0.02)


def test_table_overflow_fails_loudly(ti_engine):
    pts = np.random.default_rng(4).normal(0, 0.002, (200, 3))
    with pytest.raises(ti_engine.NeighborOverflow):
        _table_pairs(ti_engine, pts, 0.02, width=4, max_width=16)


def test_a_query_with_exactly_width_neighbours_keeps_them_all(ti_engine):
    """The fill writes every candidate after the last neighbour found: with as many neighbours as the width, the
    last one would be overwritten by later candidates, so the table grows (one slot to spare)."""
    h = 0.02
    near = 0.5 * h * np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0]], float)
    far = 1.5 * h * np.array([[0, -1, 0], [0, 0, -1], [1, 1, 0], [0, 1, 1], [1, 0, 1], [-1, -1, 0]], float) / np.sqrt(
        np.array([1, 1, 2, 2, 2, 2]))[:, None]  # candidates in the 27 cells, none within h of the query
    pts = np.concatenate([near, far]) + 0.1
    q = np.full((1, 3), 0.1)
    got, table = _table_pairs(ti_engine, pts, h, width=4, queries=q)
    assert got == _kd_pairs(pts, h, q) and table.counts()[0] == 4
    assert table.width > 4
