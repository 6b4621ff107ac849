"""A model.json (``fluidnexus diagnose`` writes one; ``recon``, ``predict`` and ``interact --model`` read it): the
gas's model and the source's emission window (docs/diagnose.md)."""
from __future__ import annotations

from dataclasses import dataclass

from .atomic import read_json
from .errors import InputError
from .scene import parse_window


@dataclass(frozen=True)
class ModelFile:
    """A model.json: the engine model, and the source's emission window [A, B) in scene frames that diagnose found
    or read (``source.window``; B None: to the end; None: the file records none)."""

    model: object  # engine.ModelConfig (the engine is imported when a command starts it)
    window: tuple[int, int | None] | None


def load_model_file(path, rollout: bool) -> ModelFile | None:
    """The model.json at ``path`` (``fluidnexus diagnose`` writes one), or None without a path.

    ``rollout``: whether the command rolls the model out (predict, interact: the gas in ambient air and the
    entrainment included); recon's fits step the paper's gas alone (docs/simulator.md, "Model structures") and it
    refuses a model with either.
    """
    if path is None:
        return None
    from .engine import ModelConfig  # the engine is imported only where a model file is read

    data = read_json(path, "model file")
    try:
        model = ModelConfig.from_dict(data.get("model", {}))
    except (OSError, ValueError, TypeError, KeyError) as err:
        raise InputError(path, "model", str(err)) from None
    if model.entrainment is not None and not rollout:
        raise InputError(path, "model.entrainment", "recon fits the paper's gas without entrainment, which predict "
                         "and interact roll out: reconstruct without this model and pass it to predict or interact")
    if model.air is not None and not rollout:
        raise InputError(path, "model.structure", "recon fits the paper's gas; this model is the gas in ambient air "
                         "(ambient_air), which predict and interact simulate: reconstruct without it and pass it "
                         "to predict or interact")
    source = data.get("source")
    window = parse_window(source.get("window"), path, "source.window") if isinstance(source, dict) else None
    return ModelFile(model, window)
