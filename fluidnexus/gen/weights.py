"""Local weight folders for the learned backends: offline mode, the ``[gen]`` extra, and folder checks.

The learned backends never download. :func:`offline` sets ``HF_HUB_OFFLINE=1`` (and the transformers and
diffusers equivalents) before anything from Hugging Face is imported, and :func:`check_folder` refuses a
missing or incomplete folder with one error that lists everything missing.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError

WEIGHT_SUFFIXES = (".safetensors", ".bin")
GEN_EXTRA = "pip install 'fluidnexus[gen]'"


def offline() -> None:
    """Forbid every Hugging Face download in this process."""
    for key in ("HF_HUB_OFFLINE", "TRANSFORMERS_OFFLINE", "DIFFUSERS_OFFLINE", "HF_DATASETS_OFFLINE"):
        os.environ[key] = "1"


def require_gen(backend: str):
    """Import torch and diffusers for ``backend`` (offline), or raise ImportError naming the ``[gen]`` extra.

    Returns:
        ``(torch, diffusers)`` modules.
    """
    offline()
    try:
        import diffusers
        import torch
        import transformers  # noqa: F401  (the learned backends need it; fail here, not mid-load)
    except ImportError as err:
        raise ImportError(f"the {backend} backend needs the generative extra: {GEN_EXTRA} ({err})") from err
    return torch, diffusers


def _has_weights(folder: Path) -> bool:
    return folder.is_dir() and any(p.suffix in WEIGHT_SUFFIXES for p in folder.iterdir())


def check_folder(root: str | Path | None, layout: dict[str, tuple[str, ...]], what: str, option: str) -> Path:
    """Check that a weights folder holds every file a backend loads.

    Args:
        root: the folder given by the user (None: not given).
        layout: ``{subfolder: required files}``; the special name ``"*weights"`` stands for any
            ``.safetensors``/``.bin`` file in that subfolder ("." is the root itself).
        what: the model's name for messages, e.g. "Zero123".
        option: the command-line option that names the folder, e.g. ``--weights``.
    Returns:
        The folder as a Path.
    Raises:
        InputError: naming the folder and every missing file or subfolder.
    """
    if root is None:
        raise InputError(None, option, f"the {what} backend needs a local weights folder (it never downloads)")
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, option, f"{what} weights folder not found")
    missing = []
    for sub, files in layout.items():
        folder = root / sub
        for name in files:
            if name == "*weights":
                if not _has_weights(folder):
                    missing.append(f"{sub}/*.safetensors (or .bin)")
            elif not (folder / name).is_file():
                missing.append(f"{sub}/{name}" if sub != "." else name)
    if missing:
        raise InputError(root, option, f"incomplete {what} weights folder; missing: {', '.join(missing)}")
    return root


def resolve_device(torch, device: str | None) -> str:
    """``device`` as given, or "cuda" when a GPU is visible and "cpu" otherwise."""
    if device in (None, "auto"):
        return "cuda" if torch.cuda.is_available() else "cpu"
    return device
