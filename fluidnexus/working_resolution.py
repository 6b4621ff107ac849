"""The working resolution of a scene's videos: the image scale that synth, refine and recon work at."""
from __future__ import annotations

from .errors import InputError

AUTO_LONG_SIDE = 480  # pixels: ``auto`` shrinks a camera's long side to at most this


def resolve_resolution(text: str, scene) -> float:
    """``--resolution``: a number (the scale of the scene's videos) or ``auto``, the long side of the first view's
    camera at most 480 px (0.25 for 1080 x 1920 captures, 1.0 for the embedded sample)."""
    if text == "auto":
        cam = scene.views[0].camera
        return min(1.0, AUTO_LONG_SIDE / max(cam.width, cam.height))
    try:
        return float(text)
    except ValueError:
        raise InputError(None, "--resolution", f"expected a number or 'auto', got {text!r}") from None
