"""The plates' contact sheet: per view a frame of its footage, the plate and the confidence, with a caption."""
from __future__ import annotations

import cv2
import numpy as np

from ..frames import side_by_side
from .plates import CONFIDENT, PlateEstimate

TILE_HEIGHT = 240  # pixels per row of the sheet
CAPTION = 22  # pixels of caption band above each row


def contact_sheet(rows: list[tuple[str, np.ndarray, PlateEstimate]]) -> np.ndarray:
    """[H, W, 3] image: one row ``frame | plate | confidence`` per ``(name, frame, estimate)``, captioned with the
    view, the source and the share of pixels seen (confidence >= 0.5)."""
    out = []
    for name, frame, est in rows:
        h, w = est.plate.shape[:2]
        size = (max(1, round(w * TILE_HEIGHT / h)), TILE_HEIGHT)
        tiles = [cv2.resize(np.ascontiguousarray(im, np.float32), size, interpolation=cv2.INTER_AREA).reshape(
            TILE_HEIGHT, size[0], -1) for im in (frame, est.plate, est.confidence)]
        tiles[2] = np.repeat(tiles[2], 3, axis=2)
        row = side_by_side(*[_framed(tile) for tile in tiles])
        seen = float((est.confidence >= CONFIDENT).mean())
        out.append(_captioned(row, f"{name}: {est.source}, seen {seen:.0%}"))
    width = max(r.shape[1] for r in out)
    out = [np.pad(r, ((0, 4), (0, width - r.shape[1]), (0, 0)), constant_values=1.0) for r in out]
    legend = _captioned(np.ones((0, width, 3), np.float32), "frame | plate | confidence (white = sure)")
    return np.concatenate([legend] + out, axis=0)


def _framed(tile: np.ndarray) -> np.ndarray:
    """A one-pixel grey frame, so a white plate or confidence shows its extent on the white sheet."""
    out = tile.copy()
    out[[0, -1]] = 0.5
    out[:, [0, -1]] = 0.5
    return out


def _captioned(row: np.ndarray, text: str) -> np.ndarray:
    band = np.full((CAPTION, row.shape[1], 3), 255, np.uint8)
    cv2.putText(band, text, (4, CAPTION - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([band.astype(np.float32) / 255, row], axis=0)
