"""The video-refiner interface and its registry (step 2 of the novel-view synthesizer, paper Sec. 3.1, Eq. 2).

A refiner takes a rough video (frame-wise synthesised, so it flickers) and returns a temporally coherent video
of the same size and length that keeps its content. Backends register under a name with the module that holds
them; the registry imports nothing heavy.
"""
from __future__ import annotations

import abc

import numpy as np

from .synthesizer import _load

# name -> "module:class" inside fluidnexus.gen
REFINERS = {
    "temporal": "temporal:TemporalRefiner",
    "cogvideox": "cogvideox:CogVideoXRefiner",
}


class VideoRefiner(abc.ABC):
    """Makes a rough video temporally coherent."""

    name: str = ""
    # True for a learned model that turns a rough render into realistic smoke (the paper's CogVideoX): prediction
    # then renders its rough videos with the constant initial appearance, as the paper does; a non-learned
    # refiner keeps the content it is given, so prediction renders with the reconstructed appearance instead.
    generative: bool = False

    @abc.abstractmethod
    def refine(self, video: np.ndarray) -> np.ndarray:
        """Return the refined video: same shape as ``video`` ([T, H, W, C] float32 in [0, 1])."""

    def provenance(self) -> dict:
        """What to record in scene.json about how a video was refined."""
        return {"method": self.name}


def make_refiner(name: str, **options) -> VideoRefiner:
    """Build the refiner registered as ``name`` with its options (e.g. ``weights=``, ``strength=``)."""
    return _load(REFINERS, name, "--method")(**options)
