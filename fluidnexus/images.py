"""Image helpers shared by every stage: colour channels and resizing of [H, W, C] float32 images
(docs/conventions.md, "Images")."""
from __future__ import annotations

import cv2
import numpy as np

LUMA = np.array([0.299, 0.587, 0.114], np.float32)  # the gray of a colour, as fluidnexus.video reads gray footage


def to_channels(image: np.ndarray, channels: int) -> np.ndarray:
    """An [..., 3] colour image or value as [..., channels] (1: luma; 3: as is)."""
    image = np.asarray(image, np.float32)
    if channels == image.shape[-1]:
        return image
    if channels == 1 and image.shape[-1] == 3:
        return (image @ LUMA)[..., None].astype(np.float32)
    if channels == 3 and image.shape[-1] == 1:
        return np.repeat(image, 3, axis=-1)
    raise ValueError(f"cannot convert {image.shape[-1]} channels into {channels}")


def resize_image(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """[H, W, C] resized to ``height x width`` (area averaging to shrink, bilinear to enlarge)."""
    if image.shape[:2] == (height, width):
        return image
    shrink = width <= image.shape[1] and height <= image.shape[0]
    out = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
    return out.reshape(height, width, image.shape[2])
