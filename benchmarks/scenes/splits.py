"""The two halves of the generated scene family: the seeds used while designing and the held-out seeds.

The held-out seeds are fixed here, once (2026-11-26, issue 30), before any of them was generated or run. They are
run only to fill the table of ``benchmarks/bench_scene_family.py`` (which refuses them without ``--held-out``),
never while designing or tuning a stage, and never changed afterwards: a change would make the table's held-out
column a development set. docs/scene-family.md says the same.
"""
from __future__ import annotations

# seeds anyone may generate, look at and tune on
DEVELOPMENT_SEEDS: tuple[int, ...] = tuple(range(1, 13))
# run only to fill the table (bench_scene_family.py --split held-out --held-out)
HELD_OUT_SEEDS: tuple[int, ...] = (7301, 7302, 7303, 7304, 7305, 7306, 7307, 7308, 7309, 7310, 7311, 7312)

SPLITS = {"development": DEVELOPMENT_SEEDS, "held-out": HELD_OUT_SEEDS}


class HeldOutError(RuntimeError):
    """A held-out seed was asked for without saying so."""


def split_of(seed: int) -> str:
    """``development``, ``held-out`` or ``other`` (a seed of neither half: tests and experiments)."""
    if seed in HELD_OUT_SEEDS:
        return "held-out"
    return "development" if seed in DEVELOPMENT_SEEDS else "other"


def check_seeds(seeds, held_out: bool) -> None:
    """Refuse any held-out seed unless ``held_out`` is True (the table's ``--held-out``)."""
    bad = [s for s in seeds if s in HELD_OUT_SEEDS]
    if bad and not held_out:
        raise HeldOutError(f"seeds {bad} are held out: they are run only to fill the table, with --held-out "
                           "(docs/scene-family.md)")
