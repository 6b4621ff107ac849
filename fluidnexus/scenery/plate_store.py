"""Scene plates on disk: ``backgrounds/NAME.png`` (16-bit RGB), ``backgrounds/NAME.confidence.png`` (8-bit gray),
``backgrounds/sheet.png`` (the contact sheet) and the ``backgrounds`` record of scene.json (docs/background.md)."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..atomic import atomic_dir, read_json, write_json
from ..errors import InputError
from ..scene import SCENE_FILE, Background, Scene
from .plates import PlateEstimate

FOLDER = "backgrounds"
SHEET = f"{FOLDER}/sheet.png"


def read_image(path: str | Path) -> np.ndarray:
    """An image file (PNG/JPG, 8 or 16 bit, gray or colour; alpha dropped) as [H, W, 3] float32 in [0, 1]."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "file not found")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None or image.dtype not in (np.uint8, np.uint16):
        raise InputError(path, None, "cannot be decoded as an 8- or 16-bit image")
    scale = np.float32(np.iinfo(image.dtype).max)
    if image.ndim == 2:
        image = image[:, :, None]
    if image.shape[2] == 1:
        return np.repeat(image, 3, axis=2).astype(np.float32) / scale
    return cv2.cvtColor(image[:, :, :3], cv2.COLOR_BGR2RGB).astype(np.float32) / scale


def read_plate_file(path: str | Path, width: int, height: int, field: str, owner: str) -> np.ndarray:
    """A user's plate image (:func:`read_image`) that must be ``width x height``, the size of ``owner`` (words for
    the error, e.g. "view 'cam0''s camera"); errors name the file and ``field``."""
    try:
        image = read_image(path)
    except InputError as err:
        raise err.at(prefix=field) from None
    if image.shape[:2] != (height, width):
        raise InputError(path, field, f"is {image.shape[1]}x{image.shape[0]}, but {owner} is {width}x{height}")
    return image


def read_plate(scene: Scene, view: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The plate [H, W, 3] and confidence [H, W] (float32 in [0, 1]) of ``view``; None if it has none."""
    record = scene.backgrounds.get(view)
    if record is None:
        return None
    return read_image(scene.root / record.plate), read_image(scene.root / record.confidence)[..., 0]


def write_backgrounds(scene: Scene, estimates: dict[str, PlateEstimate], sheet: np.ndarray) -> dict[str, Background]:
    """Write every plate, its confidence and the contact sheet into ``backgrounds/`` (the folder appears complete
    or not at all, replacing an earlier one), then record them in scene.json (every other field kept)."""
    records = {}
    with atomic_dir(scene.root / FOLDER) as tmp:
        for name, est in estimates.items():
            _write_png(tmp / f"{name}.png", np.rint(np.clip(est.plate, 0, 1) * 65535).astype(np.uint16))
            _write_png(tmp / f"{name}.confidence.png", np.rint(np.clip(est.confidence, 0, 1) * 255).astype(np.uint8))
            records[name] = Background(name, f"{FOLDER}/{name}.png", f"{FOLDER}/{name}.confidence.png", est.source,
                                       est.summary())
        _write_png(tmp / Path(SHEET).name, np.rint(np.clip(sheet, 0, 1) * 255).astype(np.uint8))
    scene_file = scene.root / SCENE_FILE
    data = read_json(scene_file)
    data["backgrounds"] = {"views": {name: b.to_dict() for name, b in records.items()}}
    write_json(scene_file, data)
    return records


def _write_png(path: Path, image: np.ndarray) -> None:
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if not cv2.imwrite(str(path), image):
        raise RuntimeError(f"OpenCV could not write {path}")
