"""``fluidnexus diagnose``: find what the PBF gas model gets wrong on measured footage (docs/diagnose.md).

Modules: :mod:`.observe` (footage and rendered particles to low-resolution images, and the observables a person
reads: centroid, front, width, intensity, tilt), :mod:`.plume` (the PBF plume rollout with the candidate
extensions), :mod:`.search` (base fit, candidate refits, selection test), :mod:`.report` (report.json/md,
plots, model.json), :mod:`.run` (the whole procedure).
"""
from .plume import EXTENSIONS, PlumeParams
from .run import diagnose  # noqa: E402

__all__ = ["EXTENSIONS", "PlumeParams", "diagnose"]
