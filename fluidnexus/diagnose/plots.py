"""Line plots drawn with OpenCV (the project has no plotting library): observed against simulated over time."""
from __future__ import annotations

import cv2
import numpy as np

COLORS = {"observed": (40, 40, 40), "paper's gas": (200, 90, 30), "gas in ambient air": (30, 160, 220),
          "extended model": (30, 30, 210)}


def line_plot(path, title: str, x: np.ndarray, series: dict, xlabel: str, ylabel: str, marks=()) -> None:
    """Write a PNG of ``series`` (label -> values over ``x``, or over ``x[label]`` when ``x`` is a dict of one x
    array per series); ``marks`` are x positions drawn as dashed lines."""
    W, H, L, R, T, B = 640, 400, 70, 20, 40, 50
    img = np.full((H, W, 3), 255, np.uint8)
    vals = np.concatenate([np.asarray(v, float)[np.isfinite(v)] for v in series.values()] + [np.zeros(0)])
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    if hi - lo < 1e-12:
        lo, hi = lo - 0.5, hi + 0.5
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    xs = {k: np.asarray(x[k] if isinstance(x, dict) else x, float) for k in series}
    x = np.concatenate(list(xs.values()) + [np.zeros(0)])
    x0 = float(np.nanmin(x)) if np.isfinite(x).any() else 0.0
    x1 = float(np.nanmax(x)) if np.isfinite(x).any() else 1.0
    x1 = max(x1, x0 + 1e-9)

    def px(xv, yv):
        return (int(L + (xv - x0) / (x1 - x0) * (W - L - R)), int(H - B - (yv - lo) / (hi - lo) * (H - T - B)))

    cv2.rectangle(img, (L, T), (W - R, H - B), (0, 0, 0), 1)
    for k in range(5):
        yv = lo + (hi - lo) * k / 4
        cv2.putText(img, f"{yv:.3g}", (4, px(x0, yv)[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1)
        xv = x0 + (x1 - x0) * k / 4
        cv2.putText(img, f"{xv:.0f}", (px(xv, lo)[0] - 8, H - B + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1)
    for m in marks:
        for yy in range(T, H - B, 8):
            cv2.line(img, (px(m, lo)[0], yy), (px(m, lo)[0], yy + 4), (150, 150, 150), 1)
    for i, (label, v) in enumerate(series.items()):
        color = COLORS.get(label, (0, 150, 0))
        pts = [px(a, b) for a, b in zip(xs[label], np.asarray(v, float)) if np.isfinite(a) and np.isfinite(b)]
        if len(pts) > 1:
            cv2.polylines(img, [np.array(pts, np.int32)], False, color, 2, cv2.LINE_AA)
        cv2.putText(img, label, (L + 10 + 170 * i, T - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.45, color, 1, cv2.LINE_AA)
    cv2.putText(img, title, (L, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, xlabel, (W // 2 - 30, H - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1)
    cv2.putText(img, ylabel, (4, T - 24 if T > 30 else 12), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1)
    cv2.imwrite(str(path), img)
