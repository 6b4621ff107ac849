"""Depth of the static scene from the views' clean plates: plane-sweep stereo with window aggregation and a
cross-view consistency check (the seeds of the static layer, docs/static-layer.md).

For each view (the reference), candidate depths are swept from the volume's near side far beyond it, uniformly in
inverse depth (image motion between views is linear in inverse depth; Collins 1996). At each depth every pixel of
the reference is lifted to 3D and looked up in the other views (bilinear); its cost against one view is the
squared colour difference averaged over a square window around it (the window makes a smooth texture's depth
distinctive where one pixel agrees with many depths by chance), and its cost at that depth is the mean of its best
half of the other views (a point hidden from some views by an object is still matched by the others). The depth
of least cost wins, placed between candidates by a parabola through the costs around it. A depth is kept only
where it is **consistent**: lifted to 3D and projected into another view, it lands where that view's own depth
map puts the same surface (relative depth within ``consistency``). What no second view confirms (seen by one view
alone, a plain surface, an occlusion boundary) has no depth here.

A view is compared only with its **partners**: the views whose direction from the volume's centre lies within
``max_angle`` of its own. A window's footprint on a surface is alike in two views only when they look at it from
near directions; from views 90 degrees apart (a ring of four cameras) a smooth texture matches best at the wrong
depth, and two such wrong depths agree by chance (on generated rooms, 20-40 % of the depths two views 90 degrees
apart confirm are right, against 47-76 % at 65 degrees and 79-91 % at 45: BENCHMARKS.md, "Stereo partners"). The
bound, 65 degrees, keeps the rigs whose neighbours stand 60-63 degrees apart (ScalarFlow's train01 and train03
either side of a held-out train02, PINF Sphere's five views; BENCHMARKS.md, "Stereo partners at 65 degrees"). A
view without a partner has no depth.

Everything runs at a working size (the longest image side at most ``size`` pixels), so the cost and the window's
reach do not depend on the footage's resolution.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Camera


@dataclass(frozen=True)
class StereoConfig:
    """Plane-sweep settings. The sweep starts at the volume's nearest corner, but no nearer than ``near`` times the
    distance to its centre (a camera close to a loose box), and ends ``far`` half-diagonals beyond its centre (a
    wall several volume sizes away is still swept)."""

    depths: int = 128
    near: float = 0.1
    far: float = 20.0
    window: int = 3  # half-width of the aggregation window, working-size pixels
    size: int = 160  # longest side of the working images
    consistency: float = 0.02  # relative depth agreement between views
    min_confidence: float = 0.5  # plate pixels below this confidence are not compared
    max_angle: float = 65.0  # degrees between two views' directions from the volume's centre, at most, to compare


@dataclass
class DepthMap:
    """One view at the working size: ``camera`` (the view's camera resized), ``depth`` [h, w] camera-space z in
    metres (NaN where no partner confirms it), the view's ``plate`` [h, w, C] and ``confidence`` [h, w], and its
    stereo ``partners`` (indices of the views it was compared with; none: it has no depth)."""

    camera: Camera
    depth: np.ndarray
    plate: np.ndarray
    confidence: np.ndarray
    partners: tuple = ()

    def at(self, uv: np.ndarray, width: int, height: int) -> np.ndarray:
        """[N] the depth at pixels ``uv`` [N, 2] of the full-size image (``width`` x ``height``), nearest working
        pixel; NaN where unconfirmed."""
        scale = np.array([self.camera.width / width, self.camera.height / height])
        px = np.clip(np.floor(np.asarray(uv) * scale).astype(int), 0, [self.camera.width - 1, self.camera.height - 1])
        return self.depth[px[:, 1], px[:, 0]]


def sample(image: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear look-up of ``image`` [H, W, C] at pixel coordinates ``uv`` [..., 2] (pixel centres at +0.5):
    values [..., C] and a bool [...] of the points that fall inside the image."""
    h, w = image.shape[:2]
    shape = uv.shape[:-1]
    flat = uv.reshape(-1, 2)
    rows = -(-len(flat) // _REMAP_WIDTH)
    padded = np.zeros((rows * _REMAP_WIDTH, 2), np.float32)
    padded[:len(flat)] = flat - 0.5
    mx, my = padded[:, 0].reshape(rows, -1), padded[:, 1].reshape(rows, -1)
    out = cv2.remap(np.ascontiguousarray(image, np.float32), mx, my, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    out = out.reshape(rows * _REMAP_WIDTH, -1)[:len(flat)].reshape(shape + (-1,))
    inside = (flat[:, 0] >= 0) & (flat[:, 0] <= w) & (flat[:, 1] >= 0) & (flat[:, 1] <= h)
    return out, inside.reshape(shape)


_REMAP_WIDTH = 4096  # cv2.remap takes maps of at most 32767 on a side: look-ups are laid out in rows of this


def pixel_centres(camera: Camera) -> np.ndarray:
    """[H * W, 2] the camera's pixel centres (u, v), row by row."""
    rows, cols = np.mgrid[0:camera.height, 0:camera.width]
    return np.stack([cols + 0.5, rows + 0.5], axis=-1).reshape(-1, 2)


def sweep_depths(camera: Camera, lo: np.ndarray, hi: np.ndarray, cfg: StereoConfig) -> np.ndarray:
    """[D] candidate depths for ``camera``, uniform in inverse depth from the volume's nearest corner (no nearer
    than ``cfg.near`` of the distance to its centre) to ``cfg.far`` half-diagonals beyond its centre."""
    center, half = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
    dist = float(np.linalg.norm(camera.center - center))
    _, z = camera.project(np.array(list(itertools.product(*zip(lo, hi)))))
    near, far = max(float(z.min()), cfg.near * dist), dist + cfg.far * half
    return 1.0 / np.linspace(1.0 / near, 1.0 / far, cfg.depths)


def partners(cameras, lo: np.ndarray, hi: np.ndarray, cfg: StereoConfig) -> list[tuple]:
    """Per view the indices of the other views whose direction from the volume's centre lies within
    ``cfg.max_angle`` degrees of its own (module docstring)."""
    center = 0.5 * (np.asarray(lo, np.float64) + np.asarray(hi, np.float64))
    directions = np.array([(c.center - center) / np.linalg.norm(c.center - center) for c in cameras])
    near = directions @ directions.T >= np.cos(np.radians(cfg.max_angle))
    return [tuple(j for j in range(len(cameras)) if j != i and near[i, j]) for i in range(len(cameras))]


def _best_half(costs: list[np.ndarray], others: int) -> np.ndarray:
    """The mean of the best half (at least one) of the finite costs per element (inf where none is finite)."""
    costs = np.sort(np.stack(costs), axis=0)
    finite = np.isfinite(costs)
    k = np.minimum(max(1, (others + 1) // 2), finite.sum(axis=0))
    summed = np.cumsum(np.where(finite, costs, 0.0), axis=0)
    return np.where(k > 0, np.take_along_axis(summed, np.maximum(k - 1, 0)[None], 0)[0] / np.maximum(k, 1), np.inf)


def _look_up(camera: Camera, plate: np.ndarray, confidence: np.ndarray, points: np.ndarray, shape: tuple,
             cfg: StereoConfig) -> tuple[np.ndarray, np.ndarray]:
    """(colours [*shape, C], usable [*shape]) of world ``points`` [prod(shape), 3] seen by ``camera``: in its
    image, in front of it, on a plate pixel of enough confidence."""
    px, z = camera.project(points)
    px = px.reshape(shape + (2,))
    value, ok = sample(plate, px)
    conf, _ = sample(confidence[..., None], px)
    return value, ok & (z.reshape(shape) > 0) & (conf[..., 0] >= cfg.min_confidence)


def _matching_costs(ref: int, others, cameras, plates, confidences, depths: np.ndarray,
                    cfg: StereoConfig) -> np.ndarray:
    """[D, h, w] the cost volume of view ``ref`` (module docstring): at each depth, the mean over the best half of
    the views ``others`` of the squared colour difference averaged over the window (inf where a view sees less
    than half the window)."""
    cam = cameras[ref]
    h, w = cam.height, cam.width
    uv = pixel_centres(cam)
    side = 2 * cfg.window + 1
    sure = confidences[ref] >= cfg.min_confidence
    volume = np.full((len(depths), h, w), np.inf, np.float32)
    for d, depth in enumerate(depths):
        points = cam.unproject(uv, depth)
        costs = []
        for j in others:
            value, ok = _look_up(cameras[j], plates[j], confidences[j], points, (h, w), cfg)
            ok &= sure
            square = (((value - plates[ref]) ** 2).sum(axis=-1) * ok).astype(np.float32)
            total = cv2.boxFilter(square, -1, (side, side), normalize=False, borderType=cv2.BORDER_CONSTANT)
            count = cv2.boxFilter(ok.astype(np.float32), -1, (side, side), normalize=False,
                                  borderType=cv2.BORDER_CONSTANT)
            costs.append(np.where(count >= 0.5 * side * side, total / np.maximum(count, 1.0), np.inf))
        volume[d] = _best_half(costs, len(others))
    return volume


def plane_sweep(ref: int, others, cameras, plates, confidences, depths: np.ndarray, cfg: StereoConfig) -> np.ndarray:
    """[h, w] the depth of least cost of each pixel of view ``ref`` against the views ``others`` (module
    docstring), placed between candidates by a parabola through the costs around it (in inverse depth);
    ``cameras``, ``plates`` [h, w, C] and ``confidences`` [h, w] at the working size; NaN where nothing matches at
    any depth (everywhere without ``others``)."""
    cam = cameras[ref]
    if not others:
        return np.full((cam.height, cam.width), np.nan)
    cost = _matching_costs(ref, others, cameras, plates, confidences, depths, cfg)
    best = np.argmin(cost, axis=0)
    last = len(depths) - 1
    prev = np.take_along_axis(cost, np.clip(best - 1, 0, last)[None], 0)[0]
    here = np.take_along_axis(cost, best[None], 0)[0]
    nxt = np.take_along_axis(cost, np.clip(best + 1, 0, last)[None], 0)[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        curve = prev - 2 * here + nxt
        shift = np.where(np.isfinite(curve) & (curve > 0), 0.5 * (prev - nxt) / curve, 0.0)
    position = best + np.clip(np.nan_to_num(shift), -0.5, 0.5)
    inverse = np.interp(position, np.arange(len(depths)), 1.0 / depths)
    depth = np.where(np.isfinite(here), 1.0 / inverse, np.nan)
    return np.where(confidences[ref] >= cfg.min_confidence, depth, np.nan)


def agreeing_views(depths: list[np.ndarray], cameras, pairs: list[tuple], cfg: StereoConfig) -> list[np.ndarray]:
    """Per view [h, w] the number of its partners (``pairs[i]``) whose depth map agrees with its depth (relative
    difference under ``cfg.consistency`` where the lifted point lands in that view)."""
    out = []
    for i, cam in enumerate(cameras):
        h, w = cam.height, cam.width
        points = cam.unproject(pixel_centres(cam), np.nan_to_num(depths[i].ravel(), nan=1.0))
        agree = np.zeros(h * w, int)
        for j in pairs[i]:
            other = cameras[j]
            px, z = other.project(points)
            seen, inside = sample(np.nan_to_num(depths[j], nan=-1.0)[..., None], px.reshape(h, w, 2))
            seen, inside = seen[..., 0].ravel(), inside.ravel()
            # a bilinear look-up across a NaN (stored -1) or a depth edge disagrees, as it should
            agree += inside & (z > 0) & (np.abs(seen - z) < cfg.consistency * np.maximum(z, 1e-12))
        agree[~np.isfinite(depths[i].ravel())] = 0
        out.append(agree.reshape(h, w))
    return out


def _working(cameras, plates, confidences, cfg: StereoConfig) -> tuple[list, list, list]:
    """The views at the working size (longest side at most ``cfg.size``): cameras, plates [h, w, C], confidences."""
    small, small_plates, small_conf = [], [], []
    for cam, plate, conf in zip(cameras, plates, confidences):
        factor = min(1.0, cfg.size / max(cam.width, cam.height))
        s = cam.scaled(factor) if factor < 1.0 else cam
        small.append(s)
        size = (s.width, s.height)
        # what an unsure pixel shows is never read, not even through a resize or a bilinear look-up
        sure = np.where((np.asarray(conf) >= cfg.min_confidence)[..., None], np.asarray(plate, np.float32), 0.0)
        small_plates.append(cv2.resize(sure.astype(np.float32), size, interpolation=cv2.INTER_AREA)
                            .reshape(s.height, s.width, -1))
        small_conf.append(cv2.resize(np.asarray(conf, np.float32), size, interpolation=cv2.INTER_AREA))
    return small, small_plates, small_conf


def depth_maps(cameras, plates, confidences, lo, hi, cfg: StereoConfig = StereoConfig()) -> list[DepthMap]:
    """Confirmed depth maps of every view (module docstring).

    Args:
        cameras: [V] the views' cameras; plates: [V] [H, W, C] in [0, 1]; confidences: [V] [H, W].
        lo, hi: the volume's corners (metres): the sweep's range follows its size.
    Returns:
        [V] :class:`DepthMap` at the working size with its partners; a depth no partner confirms is NaN.
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    small, small_plates, small_conf = _working(cameras, plates, confidences, cfg)
    pairs = partners(small, lo, hi, cfg)
    raw = [plane_sweep(i, pairs[i], small, small_plates, small_conf, sweep_depths(small[i], lo, hi, cfg), cfg)
           for i in range(len(small))]
    agree = agreeing_views(raw, small, pairs, cfg)
    return [DepthMap(cam, np.where(a >= 1, d, np.nan), plate, conf, pair)
            for cam, d, a, plate, conf, pair in zip(small, raw, agree, small_plates, small_conf, pairs)]
