"""``axisym``: a non-learned view synthesiser for rising plumes (docs/novel-views.md has the derivation).

Model. A buoyant plume rising from a source is close to axisymmetric about a vertical axis through the source,
and background-subtracted smoke footage is optically thin: a pixel is proportional to the line integral of
density along its ray. For a density ``f(y, r)`` (height y, distance r from the axis) every horizontal view
sees the same Abel projection ``A(y, s) = 2 int_s^inf f(y, r) r dr / sqrt(r^2 - s^2)`` of the signed
distance s between its ray and the axis; a ray with unit direction d sees ``A / |d_h|`` (d_h its horizontal
part: a tilted ray crosses each horizontal slice over a longer path). So a target pixel takes the value of
the input pixel whose ray passes the axis at the same height and signed distance, times ``|d_h,in| / |d_h|``.

Four refinements over a warp about one fixed axis:

- the axis follows the plume: per frame and per image row, the intensity centroid of the input row, lifted
  onto the vertical plane through the source that faces the input camera, smoothed over height and time and
  pulled towards the source where a row holds little smoke;
- perspective of both cameras: every target ray is intersected with the (bent) axis by a fixed-point
  iteration on the height of closest approach, and the matching point is projected through the input camera;
- the input row splits into its part symmetric about the axis and its antisymmetric part. An asymmetry that is
  a lateral displacement of mass (angular mode m = 1 of the density) projects as ``cos(da)`` times itself in a
  view turned by ``da`` about the axis, and its unseen sine part has no preferred sign, so the antisymmetric
  part is carried over with gain ``cos(da)``;
- fine detail of unknown depth z moves to ``s cos(da) + z sin(da)``: with a depth spread ``depth_spread_m``
  inside the plume, the expected target image is blurred by ``depth_spread_m |sin(da)|`` (the least-squares
  estimate; no detail is invented).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from ..camera import Camera
from ..errors import InputError
from .synthesizer import SynthesisInput, ViewSynthesizer


@dataclass(frozen=True)
class AxisymConfig:
    """Settings of the axisymmetric synthesiser.

    Attributes:
        axis_sigma_m: Gaussian smoothing of the axis offset along height, metres (ScalarFlow's scale; ``synth``
            applies :meth:`scaled` with the scene's length scale, as to ``depth_spread_m``).
        axis_sigma_frames: Gaussian smoothing of the axis offset along time, frames.
        axis_prior: weight of the source position in the axis fit, in units of a row's summed intensity
            (a row holding much less smoke than this stays near the vertical through the source).
        follow_axis: estimate the axis from the input (False: the fixed vertical through the source).
        antisymmetric_gain: "cos" carries the asymmetric part with gain cos(da); "keep" copies it unchanged
            (a plain warp); "drop" keeps the symmetric part only.
        path_factor: scale by |d_h,in| / |d_h,target| (different ray tilts cross the slices over different paths).
        iterations: fixed-point iterations for the closest approach of a target ray to the bent axis.
        depth_spread_m: spread (standard deviation) of the unknown depth of fine detail inside the plume,
            metres. A detail at lateral offset s and depth z moves to ``s cos(da) + z sin(da)`` in the target
            view, so its expected image is blurred by ``depth_spread_m |sin(da)|`` (0: no blur).
    """

    axis_sigma_m: float = 0.03
    axis_sigma_frames: float = 2.0
    axis_prior: float = 1.0
    follow_axis: bool = True
    antisymmetric_gain: str = "cos"
    path_factor: bool = True
    iterations: int = 3
    depth_spread_m: float = 0.02

    def scaled(self, factor: float) -> "AxisymConfig":
        """The settings for a scene ``factor`` times ScalarFlow's size (``fluidnexus.scene_scale``): the two
        lengths, ``axis_sigma_m`` and ``depth_spread_m``, are multiplied by it."""
        return replace(self, axis_sigma_m=self.axis_sigma_m * factor, depth_spread_m=self.depth_spread_m * factor)


# ---- geometry -------------------------------------------------------------------------------------------
def pixel_rays(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Rays through the pixel centres of ``camera``.

    Returns:
        origin [3] (the camera centre, world metres) and unit directions [H, W, 3] (world).
    """
    u, v = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    pix = np.stack([u, v, np.ones_like(u)], axis=-1)
    d = pix @ np.linalg.inv(camera.K).T @ camera.R  # R^T K^-1 [u, v, 1], row-vector form
    return camera.center, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _unit2(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _perp2(v: np.ndarray) -> np.ndarray:
    """Horizontal (x, z) vector turned so that cross2(v, perp(v)) = |v|^2 (cross2(p, q) = p_x q_z - p_z q_x)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _cross2(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    return p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]


def _anchor(inp: SynthesisInput) -> np.ndarray:
    """(x, y, z) of the plume's foot: the source centre, else the volume's bottom centre."""
    if inp.source is not None:
        return np.asarray(inp.source.center, np.float64)
    if inp.volume is not None:
        return inp.volume.bottom_center
    raise InputError(None, "source", "axisym needs the scene's source (or volume) to place the plume axis")


@dataclass(frozen=True)
class PlumeAxis:
    """A vertical-ish axis per frame: horizontal position (x, z) as a function of height.

    Attributes:
        heights: [R] increasing heights, metres.
        xz: [T, R, 2] axis position at each height and frame, metres.
    """

    heights: np.ndarray
    xz: np.ndarray

    def at(self, frame: int, y: np.ndarray) -> np.ndarray:
        """[..., 2] axis position at heights ``y`` [...] (clamped to the covered range)."""
        out = np.empty(y.shape + (2,))
        for k in range(2):
            out[..., k] = np.interp(y, self.heights, self.xz[frame, :, k])
        return out

    @classmethod
    def fixed(cls, point: np.ndarray, frames: int) -> "PlumeAxis":
        """The vertical line through ``point`` (x, y, z) for ``frames`` frames."""
        xz = np.broadcast_to(np.asarray(point, np.float64)[[0, 2]], (frames, 2, 2)).copy()
        return cls(np.array([-1e3, 1e3]), xz)


def _gaussian_smooth(x: np.ndarray, sigma: float, axis: int) -> np.ndarray:
    """Gaussian filter along one axis with edge replication (sigma in samples; 0 = unchanged)."""
    if sigma <= 0:
        return x
    radius = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    k /= k.sum()
    x = np.moveaxis(x, axis, -1)
    pad = np.concatenate([np.repeat(x[..., :1], radius, -1), x, np.repeat(x[..., -1:], radius, -1)], -1)
    out = sum(k[i] * pad[..., i:i + x.shape[-1]] for i in range(2 * radius + 1))
    return np.moveaxis(out, -1, axis)


def estimate_axis(inp: SynthesisInput, config: AxisymConfig = AxisymConfig()) -> PlumeAxis:
    """Fit the plume axis per frame and height from the input view (module docstring, first refinement).

    Each input row's intensity centroid column is lifted onto the vertical plane through the anchor that
    faces the input camera; its lateral offset from the anchor is smoothed with weights = row intensity and a
    prior of weight ``axis_prior`` at zero offset.

    Returns:
        The :class:`PlumeAxis` (one height per input row).
    """
    anchor = _anchor(inp)
    video = inp.video.mean(axis=-1)  # [T, H, W]
    frames, h, w = video.shape
    if not config.follow_axis:
        return PlumeAxis.fixed(anchor, frames)
    cam = inp.camera
    facing = _unit2(anchor[[0, 2]] - cam.center[[0, 2]])
    lateral = _perp2(facing)
    mass = video.sum(axis=-1)  # [T, H]
    cols = np.arange(w) + 0.5
    centroid = (video * cols).sum(axis=-1) / np.maximum(mass, 1e-12)
    # lift (centroid, row) onto the plane through the anchor with horizontal normal `facing`
    origin, rays = pixel_rays(cam)
    plane = (anchor - origin)[[0, 2]] @ facing  # horizontal distance from the camera to the plane
    pix = np.stack([centroid, np.broadcast_to(np.arange(h) + 0.5, centroid.shape), np.ones_like(centroid)], -1)
    d = pix @ np.linalg.inv(cam.K).T @ cam.R  # [T, H, 3] ray directions through the centroids
    points = origin + (plane / np.maximum(d[..., [0, 2]] @ facing, 1e-12))[..., None] * d
    offset = (points[..., [0, 2]] - anchor[[0, 2]]) @ lateral  # [T, H] metres
    # height of each row where the column under the anchor meets the plane
    column = rays[:, int(np.clip(cam.project(anchor[None])[0][0, 0], 0, w - 1))]
    row_y = origin[1] + column[:, 1] * plane / np.maximum(column[:, [0, 2]] @ facing, 1e-12)
    row_step = float(np.abs(np.diff(row_y)).mean()) if h > 1 else 1.0
    sig_rows = config.axis_sigma_m / max(row_step, 1e-9)
    num = _gaussian_smooth(_gaussian_smooth(mass * offset, sig_rows, 1), config.axis_sigma_frames, 0)
    den = _gaussian_smooth(_gaussian_smooth(mass, sig_rows, 1), config.axis_sigma_frames, 0)
    smooth = num / (den + config.axis_prior)
    order = np.argsort(row_y)
    xz = anchor[[0, 2]] + smooth[:, order, None] * lateral
    return PlumeAxis(row_y[order], xz)


def warp_maps(axis: PlumeAxis, frame: int, source: Camera, target: Camera, iterations: int = 3):
    """Where each target pixel reads the source view, under the axisymmetric model.

    Args:
        axis: the plume axis; ``frame`` selects its frame.
        source, target: the input and the target cameras.
        iterations: fixed-point iterations for the height of closest approach to the axis.
    Returns:
        ``(uv, uv_mirror, gain, cos_da)``: [H, W, 2] source pixel coordinates of the matching point and of its
        mirror image about the axis, [H, W] the path factor |d_h,src| / |d_h,tgt|, and [H, W] the cosine of
        the azimuth between the two viewing directions.
    """
    origin, d = pixel_rays(target)
    dh = d[..., [0, 2]]
    dh2 = np.maximum((dh ** 2).sum(-1), 1e-12)
    y = np.full(d.shape[:2], float(np.median(axis.heights)) if len(axis.heights) > 2 else origin[1])
    a = axis.at(frame, y)
    for _ in range(iterations):  # closest approach of the ray to the vertical through a(y)
        t = ((a - origin[[0, 2]]) * dh).sum(-1) / dh2
        y = origin[1] + t * d[..., 1]
        a = axis.at(frame, y)
    t = ((a - origin[[0, 2]]) * dh).sum(-1) / dh2
    closest = origin[[0, 2]] + t[..., None] * dh
    s = _cross2(_unit2(dh), closest - a)  # signed distance of the ray from the axis
    facing = _unit2(a - source.center[[0, 2]])
    side = _perp2(facing)

    def to_source(sign):
        q_xz = a + sign * s[..., None] * side
        q = np.stack([q_xz[..., 0], y, q_xz[..., 1]], -1)
        uv, _ = source.project(q.reshape(-1, 3))
        return uv.reshape(q.shape[:2] + (2,)), q

    uv, q = to_source(1.0)
    uv_m, _ = to_source(-1.0)
    dq = _unit2(q - source.center)
    gain = np.linalg.norm(dq[..., [0, 2]], axis=-1) / np.sqrt(dh2)
    cos_da = (facing * _unit2(dh)).sum(-1)
    return uv, uv_m, gain, cos_da


def _sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear sample of [H, W, C] at continuous pixel coordinates [h, w, 2]; outside the image is 0."""
    import cv2

    maps = (uv - 0.5).astype(np.float32)
    out = cv2.remap(image, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=0)
    return out.reshape(uv.shape[:2] + (image.shape[-1],))


def render_axisym(inp: SynthesisInput, target: Camera, axis: PlumeAxis,
                  config: AxisymConfig = AxisymConfig()) -> np.ndarray:
    """The target camera's video under the axisymmetric model.

    Returns:
        [T, target.height, target.width, C] float32 in [0, 1].
    """
    frames = inp.video.shape[0]
    out = np.empty((frames, target.height, target.width, inp.video.shape[-1]), np.float32)
    gains = {"cos": None, "keep": 1.0, "drop": 0.0}
    if config.antisymmetric_gain not in gains:
        raise InputError(None, "antisymmetric_gain", f"must be one of {sorted(gains)}")
    sigma_px = detail_blur_px(inp.camera, target, _anchor(inp), config.depth_spread_m)
    static = None if config.follow_axis else warp_maps(axis, 0, inp.camera, target, config.iterations)
    for k in range(frames):
        uv, uv_m, gain, cos_da = static or warp_maps(axis, k, inp.camera, target, config.iterations)
        frame = np.ascontiguousarray(inp.video[k], np.float32)
        direct, mirror = _sample(frame, uv), _sample(frame, uv_m)
        anti_gain = gains[config.antisymmetric_gain]
        anti_gain = np.maximum(cos_da, 0.0)[..., None] if anti_gain is None else anti_gain
        value = 0.5 * (direct + mirror) + anti_gain * 0.5 * (direct - mirror)
        if config.path_factor:
            value = value * gain[..., None]
        out[k] = np.clip(_blur(value, sigma_px), 0.0, 1.0)
    return out


def detail_blur_px(source: Camera, target: Camera, anchor: np.ndarray, depth_spread_m: float) -> float:
    """Gaussian sigma in target pixels for details of unknown depth (see ``AxisymConfig.depth_spread_m``)."""
    a, b = (_unit2(anchor[[0, 2]] - c.center[[0, 2]]) for c in (source, target))
    sin_da = abs(float(_cross2(a, b)))
    distance = float(np.linalg.norm(anchor - target.center))
    return depth_spread_m * sin_da * float(target.K[0, 0]) / distance


def _blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    import cv2

    if sigma_px < 0.3:
        return image
    return cv2.GaussianBlur(image, (0, 0), sigma_px).reshape(image.shape)


class AxisymSynthesizer(ViewSynthesizer):
    """The ``axisym`` backend: :func:`estimate_axis` once, then :func:`render_axisym` per target camera."""

    name = "axisym"

    def __init__(self, config: AxisymConfig = AxisymConfig()):
        self.config = config
        self._axis: tuple[SynthesisInput, PlumeAxis] | None = None  # the last input and its fitted axis

    def synthesize(self, inp: SynthesisInput, target: Camera) -> np.ndarray:
        if self._axis is None or self._axis[0] is not inp:
            self._axis = (inp, estimate_axis(inp, self.config))
        return render_axisym(inp, target, self._axis[1], self.config)

    def provenance(self) -> dict:
        return {"method": self.name, **asdict(self.config)}
