"""A family of generated smoke scenes with a development half and a held-out half (issue 30).

Why here and not in ``fluidnexus``: this is test and benchmark tooling, an instrument that measures the tool from
outside. It must not share the tool's engine, or an error of the engine would be in the footage and in the
reconstruction alike and cancel out; so its smoke comes from its own numpy grid solver (``smoke_solver``), its images
from its own ray marcher (``raymarch``), its cameras from its own pinhole code (``geometry``), and it writes what a
user brings: a PINF capture (info.json + MP4s) that the tool imports with ``calibrate --from-pinf``. (``fluidnexus.gen``
is the tool's novel-view synthesis, not scene generation.) Tests (``tests/scenegen``) and the table
(``benchmarks/bench_scene_family.py``) import it as ``benchmarks.scenes``. docs/scene-family.md describes it.

    from benchmarks.scenes import generate
    info = generate(seed=3, out_dir="/tmp/s3", size="small")   # /tmp/s3/info.json, *.mp4, plates/, truth.json
"""
from .generate import HELD_OUT, INPUTS, generate
from .spec import SIZES, draw
from .splits import DEVELOPMENT_SEEDS, HELD_OUT_SEEDS, HeldOutError, check_seeds, split_of

__all__ = ["generate", "draw", "SIZES", "INPUTS", "HELD_OUT", "DEVELOPMENT_SEEDS", "HELD_OUT_SEEDS",
           "HeldOutError", "check_seeds", "split_of"]
