"""ParticleSet against a plain numpy model of the same rows: appends, removals, overwrites, in order."""
import numpy as np


def test_rows_follow_a_numpy_model_through_adds_removals_and_overwrites(ti_engine):
    parts = ti_engine.VisualParticles(40, channels=3)
    model = {name: np.zeros((0, w)) for name, w in parts.widths.items()}
    defaults = {"color": 0.7, "scale": 0.0027, "rotation": (1.0, 0.0, 0.0, 0.0), "opacity": 0.1}
    rng = np.random.default_rng(0)

    def add(count, **given):
        rows = parts.add(**given)
        assert rows == slice(len(model["position"]), len(model["position"]) + count)
        for name, w in parts.widths.items():
            value = given[name] if name in given else np.broadcast_to(defaults[name], (count, w))
            model[name] = np.concatenate([model[name], np.asarray(value, float).reshape(count, w)])

    def check():
        assert parts.n == len(model["position"])
        for name, w in parts.widths.items():
            got = parts.get(name)
            assert got.shape == ((parts.n, w) if w > 1 else (parts.n,))
            np.testing.assert_array_equal(got.reshape(parts.n, w), model[name])
            beyond = parts.fields[name].to_numpy()[parts.n:]
            assert not beyond.any(), name  # rows past the active count hold zeros

    add(7, position=rng.normal(size=(7, 3)))
    check()
    add(5, position=rng.normal(size=(5, 3)), opacity=rng.uniform(size=5), color=rng.uniform(size=(5, 3)))
    check()
    positions = model["position"].copy()
    positions[[1, 8]] = np.nan  # non-finite rows are removed like any other
    parts.set("position", positions)
    model["position"] = positions
    mask = np.isfinite(positions).all(axis=1) & (rng.uniform(size=12) > 0.3)
    assert parts.keep(mask) == 12 - int(mask.sum())
    model = {name: values[mask] for name, values in model.items()}
    check()
    add(3, position=rng.normal(size=(3, 3)), scale=rng.uniform(size=(3, 3)))
    check()
    assert parts.keep(np.ones(parts.n, bool)) == 0
    check()
    assert parts.keep(np.zeros(parts.n, bool)) == len(model["position"])
    model = {name: values[:0] for name, values in model.items()}
    check()
