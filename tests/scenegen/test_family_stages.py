"""Every stage on small generated scenes of different kinds (issue 30): the table's own row, as a user runs the
tool (calibrate --from-pinf, background, synth and refine for a single video, recon at the demo's reduced settings,
eval), at the ``tiny`` size (48 x 36 pixels, 12 frames). The held-out camera's render beats both trivial
references of the same run (an all-black image and frame 0 held still) and the source is found near the true one.

The seeds lie outside both halves of the family. Their rows as measured (2026-11-26, 2-core VM, NVS / black /
frame 0 held, dB; source error in source radii):

- 1128, a continuous plume glowing on black, four cameras on an arc: 31.57 / 23.20 / 23.23, 0.7
- 1121, a sideways jet absorbing on white, a ring: 34.61 / 0.03 / 28.13, 0.9
- 1133, a burst (puff) glowing on black, a ring: 29.32 / 24.67 / 24.95, 1.0
- 1128's single video (train01 in, three views synthesised; the nozzle's height stated, scene.json
  source_height, as the table does since 2026-11-28): 27.66 / 23.20 / 23.23, 1.6

Not held here: a textured room (seed 1109, a jet on a wall: 24.42 dB under frame 0 held's 32.47; the static
world from the held-out camera decides it, BENCHMARKS.md "The generated scene family").
"""
import argparse

import pytest

from benchmarks.bench_scene_family import FAST_RECON, one

ROWS = [(1128, "four-view", 1.5), (1121, "four-view", 1.5), (1133, "four-view", 1.5), (1128, "single-view", 2.5)]


@pytest.mark.parametrize("seed, protocol, max_source_radii", ROWS, ids=[f"{s}-{p}" for s, p, _ in ROWS])
def test_every_stage_beats_the_trivial_references(tmp_path, seed, protocol, max_source_radii):
    args = argparse.Namespace(work=tmp_path, size="tiny", plates="estimated", recon_args=FAST_RECON,
                              rescore=False)
    row = one(seed, protocol, args)
    nvs, refs = row["nvs"]["psnr"], row["references"]
    assert nvs > refs["black"]["psnr"] + 1.0, row
    assert nvs > refs["frame0_held"]["psnr"] + 1.0, row
    assert row["source"]["center_error_radii"] <= max_source_radii, row["source"]
