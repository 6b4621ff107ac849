"""The view-synthesiser interface and its registry (step 1 of the novel-view synthesizer, paper Sec. 3.1).

A synthesiser turns the input view's video into a rough video for another camera of the same scene, frame by
frame. Backends register under a name with the module that holds them, so the registry itself imports nothing
heavy: ``make_synthesizer("zero123", weights=...)`` imports diffusers only then.
"""
from __future__ import annotations

import abc
import importlib
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..scene import Source, Volume

# name -> "module:class" inside fluidnexus.gen
SYNTHESIZERS = {
    "axisym": "axisym:AxisymSynthesizer",
    "zero123": "zero123:Zero123Synthesizer",
}


@dataclass(frozen=True)
class SynthesisInput:
    """What a synthesiser may use: the input view and the scene geometry (never ground truth).

    Attributes:
        video: [T, H, W, C] float32 in [0, 1], the input view's frames.
        camera: the input view's camera (its size matches ``video``).
        source: the smoke inflow disk, if the scene has one.
        volume: the box the smoke occupies, if the scene has one.
    """

    video: np.ndarray
    camera: Camera
    source: Source | None = None
    volume: Volume | None = None


class ViewSynthesizer(abc.ABC):
    """Makes the video of a target camera from :class:`SynthesisInput`."""

    name: str = ""

    @abc.abstractmethod
    def synthesize(self, inp: SynthesisInput, target: Camera) -> np.ndarray:
        """Return the target camera's video, [T, target.height, target.width, C] float32 in [0, 1]."""

    def provenance(self) -> dict:
        """What to record in scene.json about how a video was made (method and settings)."""
        return {"method": self.name}


def _load(table: dict[str, str], name: str, field: str):
    if name not in table:
        raise InputError(None, field, f"unknown method {name!r}; known: {', '.join(sorted(table))}")
    module, cls = table[name].split(":")
    return getattr(importlib.import_module(f"{__package__}.{module}"), cls)


def make_synthesizer(name: str, **options) -> ViewSynthesizer:
    """Build the synthesiser registered as ``name`` with its options (e.g. ``weights=`` for learned ones)."""
    return _load(SYNTHESIZERS, name, "--method")(**options)
