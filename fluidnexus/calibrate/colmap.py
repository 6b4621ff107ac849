"""A COLMAP sparse model (``cameras``/``images`` in .bin or .txt), read with pycolmap: one view per image.

Footage for an image named ``cam03.png`` is any file or folder with stem ``cam03`` in the media folder (by default
``<model>/../images`` or ``<model>/../../images``, COLMAP's usual project layout). Models are imported in their
own frame and scale; ``fluidnexus calibrate --images`` produces y-up, optionally metric scenes.
"""
from __future__ import annotations

from pathlib import Path

from ..camera import Camera
from ..errors import InputError
from .assemble import Recording


def default_media_dir(model_dir: Path) -> Path | None:
    for candidate in (model_dir.parent / "images", model_dir.parent.parent / "images"):
        if candidate.is_dir():
            return candidate
    return None


def media_by_stem(folder: Path | None) -> dict[str, Path]:
    if folder is None:
        return {}
    return {p.stem: p for p in sorted(folder.iterdir()) if not p.name.startswith(".")}


def read_colmap(model_dir: str | Path, media_dir: str | Path | None = None) -> dict[str, Recording]:
    """Parse a sparse model folder into recordings."""
    import pycolmap

    model_dir = Path(model_dir)
    if not model_dir.is_dir():
        raise InputError(model_dir, None, "folder not found")
    if not any((model_dir / f"cameras.{ext}").exists() for ext in ("bin", "txt")):
        raise InputError(model_dir, "cameras", "no cameras.bin or cameras.txt: not a COLMAP sparse model")
    try:
        rec = pycolmap.Reconstruction(str(model_dir))
    except Exception as err:  # pycolmap raises plain RuntimeError/ValueError on corrupt files
        raise InputError(model_dir, None, f"cannot read the COLMAP model ({err})") from None
    media = media_by_stem(Path(media_dir) if media_dir else default_media_dir(model_dir))
    recordings = {}
    for image_id in sorted(rec.reg_image_ids()):
        image = rec.image(image_id)
        name = Path(image.name).stem
        try:
            camera = Camera.from_pycolmap(rec.camera(image.camera_id), image.cam_from_world())
        except InputError as err:
            raise err.at(model_dir, f"images[{image.name}]") from None
        recordings[name] = Recording(name, camera, media.get(name))
    if not recordings:
        raise InputError(model_dir, "images", "the model has no registered images")
    return recordings
