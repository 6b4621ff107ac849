"""The static layer: a set of Gaussians that do not move (backdrop, floor, obstacles), fitted to the views' clean
plates with the project's splat renderer (docs/static-layer.md).

The fit is a small 3D Gaussian splatting optimisation (Kerbl et al. 2023):

- **Initialisation** (seeds of opacity ``initial_opacity``, each as wide as its spacing): for each camera a jittered
  grid of rays through its image, each seeding one Gaussian with its plate's colour at the depth plane-sweep
  stereo finds and one of its partners confirms (``scenery.stereo``: views within 65 degrees of it); the lattice
  nodes of the volume that no view sees through (``scenery.static_hull``: a surface without texture, which the
  stereo cannot place); a ray without a confirmed depth seeds where it meets the floor if that is nearer, else on
  a shell ``shell`` half-diagonals beyond the volume's centre (and beyond every input camera, ``shell_cameras``),
  when its view shows a textured backdrop (which hides the seed from other cameras), and nothing otherwise; a
  **lone** view (over a textured backdrop, without a stereo partner: a single view, a ring's views) also carves
  the hull where its rays seed; a single view over a textured backdrop also seeds the floor it does not see
  (``scenery.view_floor``). A ray or node showing the
  background colour (within ``plain``) seeds nothing: a plain colour has no depth, and the learned
  background colour already shows it (a white backdrop is not filled with white Gaussians). What lies beyond
  every Gaussian is one learned colour, initialised to the scene's known backdrop colour (PINF's
  ``frame_bkg_color``: Game's black sky), else where lone views show a floor to the mean of their pixels off the
  floor, else to the plates' median.
- **Loss** per view: ``0.8 L1 + 0.2 (1 - SSIM)`` (the reconstruction's image loss) weighted by the plate's
  confidence w: the target is ``w plate + (1 - w) render`` and the render's gradient is scaled by w (the render's
  share held fixed), so a pixel of confidence 0 (smoke that never left) pulls nothing and what the plate shows
  there does not matter, not even inside SSIM's windows.
- **Densify and prune** every ``densify_every`` iterations until ``densify_until``: Gaussians whose mean
  screen-space position gradient exceeds ``grad_threshold`` (normalised device units; 3DGS uses 2e-4 over 30k
  iterations, with which a short fit on few views overfits) are cloned
  when small (largest scale under ``percent_dense`` of the volume's size) and split in two when large; Gaussians
  with opacity under ``min_opacity``, larger than ``max_scale`` of the volume's size, or of the background colour
  (within ``plain``: invisible from the training views, a veil from any other; also removed after the last
  iteration) are removed.

Every random choice comes from one generator seeded by ``seed``, so a fit is deterministic (the renderer's
gradients are bit-identical from run to run). The result is saved as ``RUN/static.npz`` (:func:`save_static`) and
read back with :func:`load_static`; :func:`render_static` draws it from any camera.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from .. import engine
from ..atomic import atomic_file
from ..camera import Camera
from ..engine.tensors import torch_dtype
from ..errors import InputError
from ..metrics import image_loss
from ..progress import progress
from ..scene_scale import box_size
from .static_hull import hull_points, in_box
from .stereo import DepthMap, StereoConfig, depth_maps, pixel_centres
from .view_floor import floor_beyond_frame, wall_colour
from .view_objects import object_seeds

STATIC_FILE = "static.npz"
FORMAT = "fluidnexus-static/1"


@dataclass(frozen=True)
class StaticConfig:
    """Settings of a static-layer fit. Lengths are fractions of the volume's size (cube root of its volume)."""

    iterations: int = 1200
    rays: int = 32  # rays per image side per view
    lattice: int = 24  # nodes along the volume's size for the seeds no view sees through (scenery.static_hull)
    inner_tolerance: float = 3.0  # a depth confirmed inside the volume carves the hull's nodes more than this many
    # lattice spacings in front of it (scenery.static_hull)
    hull_views: int = 3  # views that must see a hull node (both where there are two; scenery.static_hull)
    stereo: StereoConfig = StereoConfig()  # the seeds' depths (scenery.stereo)
    shell: float = 2.0  # seeds without a confirmed depth lie this many half-diagonals beyond the volume's centre,
    shell_cameras: float = 1.5  # and at least this many times the farthest input camera's distance from it
    backdrop: float = 0.05  # a view shows a textured backdrop when this share of its pixels has a confirmed depth
    # outside the volume
    plain: float = 0.03  # rays whose colour is within this of the background colour seed nothing
    textured: float = 0.25  # a single view shows a textured backdrop when this share of its sure pixels is not plain
    initial_opacity: float = 0.5
    lr_position: float = 2e-3  # x the volume's size per step
    lr_scale: float = 0.01
    lr_rotation: float = 0.002
    lr_opacity: float = 0.05
    lr_color: float = 0.02
    densify_every: int = 100
    densify_from: int = 100
    densify_until: int = 900
    grad_threshold: float = 6e-4
    percent_dense: float = 0.01
    min_opacity: float = 0.005
    max_scale: float = 0.5
    max_gaussians: int = 10000
    w_l1: float = 0.8
    w_dssim: float = 0.2
    w_seed: float = 1.0  # a single view's objects: the pull of each Gaussian back to its seed (``_seed_prior``)
    seed: int = 0

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class StaticLayer:
    """N static Gaussians (numpy float32): means [N, 3] m, scales [N, 3] m (standard deviations), quats [N, 4]
    (w, x, y, z), opacities [N], colors [N, C]; and ``background`` [C], the colour beyond every Gaussian."""

    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacities: np.ndarray
    colors: np.ndarray
    background: np.ndarray
    info: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.means.shape[0])

    def as_state(self, frame: int):
        """The layer as a ``FrameState`` holding only visual Gaussians (what the exporters write)."""
        from ..state import FrameState

        q = self.quats / np.linalg.norm(self.quats, axis=1, keepdims=True)
        empty = np.zeros((0, 3), np.float32)
        return FrameState(frame, empty, empty, self.means, self.colors, self.scales, q.astype(np.float32),
                          self.opacities)

    def gaussians(self, dtype=torch.float32) -> engine.Gaussians:
        """The layer as a frozen ``engine.Gaussians`` (the renderer's ``static=``)."""
        return engine.Gaussians(*(torch.as_tensor(a, dtype=dtype) for a in
                                  (self.means, self.scales, self.quats, self.opacities, self.colors)))


def inside_volume(layer: StaticLayer) -> StaticLayer:
    """The Gaussians of ``layer`` whose centres lie inside the volume it was fitted in (``info["volume"]``): what
    stands in front of the backdrop, e.g. an obstacle in the flow."""
    lo, hi = (np.asarray(v, np.float32) for v in layer.info["volume"])
    keep = in_box(layer.means, lo, hi)
    return StaticLayer(layer.means[keep], layer.scales[keep], layer.quats[keep], layer.opacities[keep],
                       layer.colors[keep], layer.background, layer.info)


def render_static(layer: StaticLayer, camera: Camera, return_depth: bool = False):
    """The static layer seen by ``camera``, over its background colour: (image [H, W, C], alpha [H, W], depth)."""
    dtype = torch_dtype()
    empty = torch.zeros((0, 3), dtype=dtype)
    channels = layer.colors.shape[1]
    with torch.no_grad():
        return engine.render(camera, empty, empty, torch.zeros((0, 4), dtype=dtype), torch.zeros(0, dtype=dtype),
                             torch.zeros((0, channels), dtype=dtype), torch.as_tensor(layer.background, dtype=dtype),
                             return_depth=return_depth, static=layer.gaussians(dtype))


# ---- initialisation ------------------------------------------------------------------------------------------
def _ray_seeds(index: int, cameras, plates, confidences, depth: DepthMap, fill: np.ndarray, lo: np.ndarray,
               hi: np.ndarray, cfg: StaticConfig, generator: torch.Generator, lone: bool,
               floor=None) -> tuple[np.ndarray, np.ndarray]:
    """One seed per ray of a jittered grid through view ``index``'s image with its plate's colour (``fill`` where
    the plate is unsure, confidence under 0.5), at the ray's stereo depth where a partner confirms it. A ray
    without a confirmed depth seeds at its assumed depth (:func:`assumed_depth`: the floor, else the shell behind
    everything) when the view shows a textured backdrop (``lone``: a view over one that no other view can confirm,
    the only view or one without a stereo partner; or :func:`_sees_backdrop`: a part of the floor or the wall this
    view alone sees shows there, and the wall hides it from other cameras), and nothing otherwise: over a plain
    backdrop nothing would hide a far seed from a camera looking the other way, and such rays are a textureless
    object (whose hull the volume seeds fill) or a plate's error (smoke that sat still). Rays showing the
    background colour (within ``cfg.plain`` of ``fill``) seed nothing."""
    camera, plate, confidence = cameras[index], plates[index], confidences[index]
    h, w = plate.shape[:2]
    cols = (np.arange(cfg.rays) + 0.5) * w / cfg.rays
    rows = (np.arange(cfg.rays) + 0.5) * h / cfg.rays
    uv = np.stack(np.meshgrid(cols, rows), axis=-1).reshape(-1, 2)
    uv = uv + (torch.rand(uv.shape, generator=generator, dtype=torch.float64).numpy() - 0.5) * [w / cfg.rays,
                                                                                               h / cfg.rays]
    z = depth.at(uv, w, h)
    pix = np.clip(uv.astype(int), 0, [w - 1, h - 1])
    confirmed = np.isfinite(z)
    room = lone or _sees_backdrop(depth, lo, hi, cfg)
    z = np.where(confirmed, z, assumed_depth(camera, uv, cameras, lo, hi, cfg, floor if room else None))
    points = camera.unproject(uv, z)
    colors = np.array(plate[pix[:, 1], pix[:, 0]], np.float64).reshape(len(uv), -1)
    colors[confidence[pix[:, 1], pix[:, 0]] < 0.5] = fill
    # a plain colour has no depth (every depth agrees): what shows the background colour is left to it
    content = (np.abs(colors - fill).max(axis=1) > cfg.plain) & (confirmed | room)
    return points[content], colors[content]


def assumed_depth(camera, uv: np.ndarray, cameras, lo: np.ndarray, hi: np.ndarray, cfg: StaticConfig,
                  floor=None) -> np.ndarray:
    """[N] the camera-space depth at which a ray without a confirmed depth seeds: where it meets ``floor`` (when
    given and nearer), else on the shell (:func:`shell_radius` beyond the volume's centre)."""
    center = 0.5 * (lo + hi)
    shell = np.full(len(uv), float(np.linalg.norm(camera.center - center)) + shell_radius(cameras, lo, hi, cfg))
    return shell if floor is None else np.minimum(shell, floor_depth(camera, uv, floor))


def _textured(plate: np.ndarray, confidence: np.ndarray, fill: np.ndarray, cfg: StaticConfig) -> bool:
    """Whether a view's plate shows a textured backdrop: at least ``cfg.textured`` of its sure pixels differ from
    the background colour by more than ``cfg.plain``. On a plain backdrop what differs is an object or a plate's
    error (generated scenes' single-video plates: 0-2.4 % on black and white, 64-93 % in rooms)."""
    sure = np.asarray(plate)[np.asarray(confidence) >= 0.5].reshape(-1, len(fill))
    return len(sure) > 0 and float((np.abs(sure - fill).max(axis=1) > cfg.plain).mean()) >= cfg.textured


def floor_depth(camera, uv: np.ndarray, floor) -> np.ndarray:
    """[N] the camera-space depth at which each pixel's ray meets ``floor`` (``scene.Floor``) from above, inf where
    it does not in front of the camera or the camera is not above the floor."""
    if float((camera.center - np.asarray(floor.point, np.float64)) @ np.asarray(floor.normal, np.float64)) <= 0:
        return np.full(len(uv), np.inf)
    return floor.reach(camera.center, camera.unproject(uv, np.ones(len(uv))) - camera.center)  # rays at depth 1


def shell_radius(cameras, lo: np.ndarray, hi: np.ndarray, cfg: StaticConfig) -> float:
    """How far beyond the volume's centre a ray without a confirmed depth seeds: ``cfg.shell`` half-diagonals, and
    beyond every input camera (``cfg.shell_cameras`` times the farthest one's distance). A backdrop seen past the
    volume stands beyond the cameras; with a ring of cameras closer than the shell, each view's seeds would lie
    between the volume and the cameras opposite, a veil for any camera on the ring (a generated scene's held-out
    static layer: 13.9 dB, under a flat colour's 15.1)."""
    center = 0.5 * (lo + hi)
    farthest = max(float(np.linalg.norm(c.center - center)) for c in cameras)
    return max(cfg.shell * 0.5 * float(np.linalg.norm(hi - lo)), cfg.shell_cameras * farthest)


def _sees_backdrop(depth: DepthMap, lo: np.ndarray, hi: np.ndarray, cfg: StaticConfig) -> bool:
    """Whether the view shows a textured backdrop: at least ``cfg.backdrop`` of its pixels have a confirmed point
    behind the volume (further from the camera than any point of the volume's bounding sphere). A surface that
    runs out of the volume beside it (PINF Game's stairs) is no backdrop: a ray of it without a confirmed depth
    would seed far behind the stairs, a floater for any camera that looks past them."""
    cam = depth.camera
    rows, cols = np.nonzero(np.isfinite(depth.depth))
    if len(rows) == 0:
        return False
    points = cam.unproject(np.stack([cols + 0.5, rows + 0.5], axis=1), depth.depth[rows, cols])
    reach = float(np.linalg.norm(cam.center - 0.5 * (lo + hi))) + 0.5 * float(np.linalg.norm(hi - lo))
    return int((np.linalg.norm(points - cam.center, axis=1) > reach).sum()) >= cfg.backdrop * cam.width * cam.height


def initial_layer(cameras, plates, confidences, lo, hi, cfg: StaticConfig, backdrop=None, floor=None,
                  anchor=None) -> StaticLayer:
    """The seeds of a fit (module docstring), deterministic in ``cfg.seed``; plate pixels with confidence under
    0.5 are not read. The background colour is ``backdrop`` (RGB) when given, else (lone views that show the
    floor) the mean of their mean colours off the floor, else the median colour of the sure pixels of every plate.
    A single view over a plain backdrop with an ``anchor`` seeds its objects' surfaces there (``view_objects``)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    generator = torch.Generator().manual_seed(cfg.seed)
    sure = np.concatenate([p[c >= 0.5] for p, c in zip(plates, confidences)])
    if len(sure) == 0:
        raise InputError(None, "backgrounds", "every plate pixel has confidence under 0.5: nothing to fit")
    background = np.median(sure, axis=0) if backdrop is None else _channels(backdrop, sure.shape[-1])
    depths = depth_maps(cameras, plates, confidences, lo, hi, cfg.stereo)
    # the views over a textured backdrop that no other view can confirm (a single video of a room, a ring's views)
    lone = [not d.partners and _textured(p, c, background, cfg) for d, p, c in zip(depths, plates, confidences)]
    alone = len(cameras) == 1 and lone[0]  # one view of a room
    center, radius, near = 0.5 * (lo + hi), shell_radius(cameras, lo, hi, cfg), 0.5 * float(np.linalg.norm(hi - lo))
    walls = [] if floor is None or backdrop is not None else [
        w for w in (wall_colour(cameras[i], plates[i], confidences[i], floor, center, radius, near)
                    for i in range(len(cameras)) if lone[i]) if w is not None]
    if walls:  # what the lone views show above the floor: the colour of what no view saw
        background = np.mean(walls, axis=0)
    # a single view's floor beyond its frame (``view_floor``)
    beyond = floor_beyond_frame(cameras[0], plates[0], confidences[0], floor, center, radius, near,
                                cfg.rays * cfg.rays) if alone and floor is not None else None
    # a lone view carves the hull where its rays seed: nothing of what it shows stands in front of that
    carving = [DepthMap(d.camera, assumed_depth(d.camera, pixel_centres(d.camera), cameras, lo, hi, cfg, floor)
                        .reshape(d.depth.shape), d.plate, d.confidence) if lonely else d
               for d, lonely in zip(depths, lone)]
    nodes, node_colors = hull_points(carving, lo, hi, background, cfg.lattice, cfg.plain,
                                     inner_tolerance=cfg.inner_tolerance, views_needed=cfg.hull_views)
    node_spacing = box_size(hi - lo) / cfg.lattice
    points, colors = [nodes], [node_colors]
    spacing = [np.full(len(nodes), node_spacing)]
    for index, camera in enumerate(cameras):
        p, c = _ray_seeds(index, cameras, plates, confidences, depths[index], background, lo, hi, cfg, generator,
                          lone[index], floor)
        points.append(p)
        colors.append(c)
        # each seed as wide as its ray's pixel footprint at its depth
        _, z = camera.project(p)
        spacing.append(np.abs(z) * camera.width / cfg.rays / camera.K[0, 0])
    if beyond is not None:
        points.append(beyond[0])
        colors.append(beyond[1])
        spacing.append(beyond[2])
    info = {}
    if len(cameras) == 1 and anchor is not None and not alone:
        up = -cameras[0].R[1] if floor is None else floor.normal  # the image's up where no floor is given
        p, c, s = object_seeds(cameras[0], plates[0], confidences[0], background, anchor, cfg.plain,
                               cfg.max_gaussians // 2, up)
        points.append(p)
        colors.append(c)
        spacing.append(s)
        if len(p):
            info["objects_at"] = [round(float(v), 6) for v in anchor]  # where this view's objects were placed
    means, spacing = np.concatenate(points).reshape(-1, 3), np.concatenate(spacing)
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (len(means), 1))
    colors = np.concatenate(colors).reshape(len(means), plates[0].shape[-1])
    return StaticLayer(means.astype(np.float32), np.tile(0.5 * spacing[:, None], (1, 3)).astype(np.float32),
                       quats.astype(np.float32), np.full(len(means), cfg.initial_opacity, np.float32),
                       colors.astype(np.float32), background.astype(np.float32), info)


def _channels(color, channels: int) -> np.ndarray:
    """An RGB colour as ``channels`` values (its mean for one channel)."""
    color = np.asarray(color, np.float64)
    return np.full(1, color.mean()) if channels == 1 else color


# ---- the optimisation ------------------------------------------------------------------------------------------
class _Params:
    """The optimised tensors: means, log scales, quaternions, opacity logits, colours, and the background colour;
    and, not optimised, where each Gaussian was seeded (``seeds``: its mean, colour, log scale and width then),
    which a clone or a split inherits."""

    def __init__(self, layer: StaticLayer, dtype):
        def leaf(a):
            return torch.as_tensor(np.asarray(a), dtype=dtype).clone().requires_grad_(True)

        op = np.clip(layer.opacities, 1e-4, 1 - 1e-4)
        self.tensors = {"means": leaf(layer.means), "log_scales": leaf(np.log(layer.scales)),
                        "quats": leaf(layer.quats), "logit_opacity": leaf(np.log(op / (1 - op))),
                        "colors": leaf(layer.colors)}
        self.seeds = {k: torch.as_tensor(np.asarray(a), dtype=dtype).clone() for k, a in
                      (("means", layer.means), ("colors", layer.colors), ("log_scales", np.log(layer.scales)),
                       ("widths", 2 * layer.scales.mean(axis=1)))}
        self.background = leaf(layer.background)

    def gaussians(self) -> tuple[torch.Tensor, ...]:
        t = self.tensors
        return (t["means"], t["log_scales"].exp(), t["quats"], torch.sigmoid(t["logit_opacity"]),
                t["colors"].clamp(0.0, 1.0))

    def layer(self, info: dict) -> StaticLayer:
        means, scales, quats, opacities, colors = (x.detach().numpy().astype(np.float32) for x in self.gaussians())
        quats = quats / np.linalg.norm(quats, axis=1, keepdims=True)
        return StaticLayer(means, scales, quats, opacities, colors,
                           self.background.detach().clamp(0, 1).numpy().astype(np.float32), info)


def _optimizer(params: _Params, cfg: StaticConfig, size: float) -> torch.optim.Adam:
    t = params.tensors
    return torch.optim.Adam([{"params": [t["means"]], "lr": cfg.lr_position * size},
                             {"params": [t["log_scales"]], "lr": cfg.lr_scale},
                             {"params": [t["quats"]], "lr": cfg.lr_rotation},
                             {"params": [t["logit_opacity"]], "lr": cfg.lr_opacity},
                             {"params": [t["colors"], params.background], "lr": cfg.lr_color}], eps=1e-15)


def _densify(params: _Params, grad_sum: np.ndarray, seen: np.ndarray, cfg: StaticConfig, size: float,
             generator: torch.Generator) -> _Params:
    """3DGS's adaptive density control: clone small and split large Gaussians with large screen-space gradients,
    then prune faint and oversized ones. Returns new parameters (the optimiser is rebuilt by the caller)."""
    with torch.no_grad():
        t = {k: v.detach().clone() for k, v in params.tensors.items()}
        t.update({f"seed_{k}": v for k, v in params.seeds.items()})
        n = t["means"].shape[0]
        scales = t["log_scales"].exp()
        mean_grad = np.where(seen > 0, grad_sum / np.maximum(seen, 1), 0.0)
        hot = torch.as_tensor(mean_grad > cfg.grad_threshold)
        room = max(0, cfg.max_gaussians - n)
        if int(hot.sum()) > room:  # keep the hottest that fit
            order = np.argsort(-mean_grad)[:room]
            hot = torch.zeros(n, dtype=torch.bool)
            hot[torch.as_tensor(order, dtype=torch.long)] = True
        large = scales.max(dim=1).values > cfg.percent_dense * size
        clone, split = hot & ~large, hot & large
        new = {k: [v] for k, v in t.items()}
        for k, v in t.items():
            new[k].append(v[clone])
        if bool(split.any()):
            # two samples from each split Gaussian, 1.6 times narrower (Kerbl et al. 2023, Sec. 5.2)
            s = scales[split]
            q = torch.nn.functional.normalize(t["quats"][split], dim=1)
            rot = _rotation_matrices(q)
            for _ in range(2):
                offset = torch.randn(s.shape, generator=generator, dtype=s.dtype) * s
                for k, v in t.items():
                    value = v[split]
                    if k in ("means", "seed_means"):  # a split's halves keep their offset from the seed
                        value = value + torch.einsum("nij,nj->ni", rot, offset)
                    elif k == "log_scales":
                        value = value - math.log(1.6)
                    new[k].append(value)
        keep = torch.cat([~split, torch.ones(int(clone.sum()) + 2 * int(split.sum()), dtype=torch.bool)])
        merged = {k: torch.cat(v)[keep] for k, v in new.items()}
        alive = (torch.sigmoid(merged["logit_opacity"]) >= cfg.min_opacity) & \
                (merged["log_scales"].exp().max(dim=1).values <= cfg.max_scale * size) & \
                ~_plain(merged["colors"], params.background, cfg)
        out = object.__new__(_Params)
        out.tensors = {k: v[alive].clone().requires_grad_(True) for k, v in merged.items()
                       if not k.startswith("seed_")}
        out.seeds = {k[len("seed_"):]: v[alive].clone() for k, v in merged.items() if k.startswith("seed_")}
        out.background = params.background.detach().clone().requires_grad_(True)
        return out


def _seed_prior(params: _Params, camera: Camera) -> torch.Tensor:
    """The prior of a single view whose objects over a plain backdrop were seeded (``view_objects``): each
    Gaussian's squared distance from its seed (in colour, in seed widths of position and in log scale), summed and
    divided by the view's pixel count (the image loss's per-pixel scale). One view constrains a Gaussian only as
    far as it shows in that view: the depth and the extent along the rays of every one, and the colour of those
    behind others, are not observed, and Adam's normalised steps move them as far on a vanishing gradient as on a
    real one (a box seen from 54 degrees round drew red and black fringes). With the prior, what the view shows
    moves as the image asks and what it does not show keeps its seed (the assumptions that placed it). Not over a
    textured backdrop: there the floor's and the shell's seeds are better moved (the generated rooms' single
    videos lost 0.3-1.0 dB with it)."""
    t, seeds = params.tensors, params.seeds
    moved = ((t["means"] - seeds["means"]) / seeds["widths"][:, None]).square().sum() + \
        (t["log_scales"] - seeds["log_scales"]).square().sum()
    return (moved + (t["colors"] - seeds["colors"]).square().sum()) / (camera.width * camera.height)


def _plain(colors: torch.Tensor, background: torch.Tensor, cfg: StaticConfig) -> torch.Tensor:
    """[N] bool: Gaussians whose colour is within ``cfg.plain`` of the background colour. Seen against it from the
    training views they show nothing, but from another camera they veil what lies behind them (on Sphere's white
    backdrop, 29 such Gaussians whitened the ball seen by a held-out camera)."""
    return (colors.detach().clamp(0, 1) - background.detach()).abs().max(dim=1).values <= cfg.plain


def _rotation_matrices(q: torch.Tensor) -> torch.Tensor:
    """[N, 3, 3] body-to-world rotations of unit quaternions (w, x, y, z)."""
    w, x, y, z = q.unbind(1)
    return torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], dim=1).reshape(-1, 3, 3)


def _check_inputs(cameras, plates, confidences) -> None:
    if not cameras:
        raise InputError(None, "backgrounds", "the static layer needs at least one view with a plate")
    for camera, plate, conf in zip(cameras, plates, confidences):
        if plate.shape[:2] != (camera.height, camera.width) or conf.shape != plate.shape[:2]:
            raise InputError(None, "backgrounds", f"a plate of {plate.shape[1]}x{plate.shape[0]} px (confidence "
                                                  f"{conf.shape[1]}x{conf.shape[0]}) for a camera of "
                                                  f"{camera.width}x{camera.height}")


def fit_static(cameras, plates, confidences, lo, hi, cfg: StaticConfig = StaticConfig(), backdrop=None,
               floor=None, anchor=None) -> StaticLayer:
    """Fit a static layer to clean plates.

    Args:
        cameras: the views' cameras [V], at the plates' size.
        plates: [V] arrays [H, W, C] in [0, 1]; confidences: [V] arrays [H, W] in [0, 1].
        lo, hi: the scene volume's corners (metres); every length of the fit follows its size.
        cfg: settings; ``cfg.seed`` makes the fit deterministic.
        backdrop: a known colour beyond everything (RGB, scene.json ``backdrop_color``: PINF Game's black sky), or
            None for the plates' median colour; what shows it seeds nothing, and the background colour starts at it.
        floor: the scene's floor (``scene.Floor``; ``world.layer_floor`` says which), where the rays without a
            confirmed depth of a view over a textured backdrop seed when it is nearer than the shell, and where a
            single view also seeds the floor it does not see beyond its frame (``view_floor``).
        anchor: where a single view's objects over a plain backdrop stand (a point, metres; ``view_objects``), or
            None: then they seed nothing.
    Returns:
        The fitted :class:`StaticLayer`; ``info`` holds the final loss, the Gaussian count, the settings and, where
        a single view's objects were seeded at ``anchor``, ``objects_at``.
    """
    _check_inputs(cameras, plates, confidences)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    size = box_size(hi - lo)
    generator = torch.Generator().manual_seed(cfg.seed)
    dtype = torch_dtype()
    targets = [torch.as_tensor(np.asarray(p), dtype=dtype) for p in plates]
    weights = [torch.as_tensor(np.asarray(c), dtype=dtype)[..., None] for c in confidences]
    seeds = initial_layer(cameras, plates, confidences, lo, hi, cfg, backdrop, floor, anchor)
    params = _Params(seeds, dtype)
    opt = _optimizer(params, cfg, size)
    n = params.tensors["means"].shape[0]
    grad_sum, seen = np.zeros(n), np.zeros(n)
    engine.reserve_gaussians(max(cfg.max_gaussians, n) * 2)
    empty3 = torch.zeros((0, 3), dtype=dtype)
    channels = targets[0].shape[-1]
    loss_value = float("nan")
    with progress("static layer", cfg.iterations) as bar:
        for it in range(1, cfg.iterations + 1):
            v = int(torch.randint(len(cameras), (1,), generator=generator))
            camera = cameras[v]
            means, scales, quats, opacities, colors = params.gaussians()
            image, _, _ = engine.render(camera, empty3, empty3, torch.zeros((0, 4), dtype=dtype),
                                        torch.zeros(0, dtype=dtype), torch.zeros((0, channels), dtype=dtype),
                                        params.background, static=engine.Gaussians(means, scales, quats, opacities,
                                                                                   colors))
            w, held = weights[v], image.detach()
            loss = image_loss(w * image + (1 - w) * held, w * targets[v] + (1 - w) * held, cfg.w_l1, cfg.w_dssim)
            loss_value = float(loss.detach())  # the image's: what the record reports
            if "objects_at" in seeds.info:  # a single view's objects over a plain backdrop
                loss = loss + cfg.w_seed * _seed_prior(params, camera)
            opt.zero_grad()
            loss.backward()
            if not math.isfinite(loss_value):
                raise FloatingPointError(f"static layer loss diverged at iteration {it}")
            if it <= cfg.densify_until:
                _accumulate(params, camera, grad_sum, seen)
            opt.step()
            if cfg.densify_from <= it <= cfg.densify_until and it % cfg.densify_every == 0 and it < cfg.iterations:
                params = _densify(params, grad_sum, seen, cfg, size, generator)
                opt = _optimizer(params, cfg, size)
                n = params.tensors["means"].shape[0]
                grad_sum, seen = np.zeros(n), np.zeros(n)
            bar.status(loss=loss_value, gaussians=params.tensors["means"].shape[0])
            bar.advance()
    plain = _plain(params.tensors["colors"], params.background, cfg)  # those that turned plain after the last prune
    params.tensors = {k: v.detach()[~plain] for k, v in params.tensors.items()}
    return params.layer({"loss": loss_value, "gaussians": int(params.tensors["means"].shape[0]),
                         "config": cfg.to_dict(), "volume": [lo.tolist(), hi.tolist()], **seeds.info})


def _accumulate(params: _Params, camera: Camera, grad_sum: np.ndarray, seen: np.ndarray) -> None:
    """Add each Gaussian's screen-space position gradient in normalised device units (3DGS's densify statistic):
    |dL/dx| projected to the image plane, times depth / fx for pixels, times W / 2 for NDC."""
    means = params.tensors["means"]
    if means.grad is None:
        return
    g = means.grad.detach().numpy().astype(np.float64)
    cam = means.detach().numpy().astype(np.float64) @ camera.R.T + camera.t
    g_cam = g @ camera.R.T
    z = cam[:, 2]
    visible = z > 1e-9
    ndc = np.hypot(g_cam[:, 0], g_cam[:, 1]) * np.abs(z) / camera.K[0, 0] * 0.5 * camera.width
    grad_sum[visible] += ndc[visible]
    seen[visible & (np.abs(g).sum(axis=1) > 0)] += 1


# ---- files ---------------------------------------------------------------------------------------------------------
def save_static(run_dir: str | Path, layer: StaticLayer) -> Path:
    """Write ``RUN/static.npz`` atomically; return its path."""
    import json

    dest = Path(run_dir) / STATIC_FILE
    with atomic_file(dest) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, format=np.array(FORMAT), means=layer.means, scales=layer.scales,
                                quats=layer.quats, opacities=layer.opacities, colors=layer.colors,
                                background=layer.background, info=np.array(json.dumps(layer.info)))
    return dest


def load_static(path: str | Path) -> StaticLayer:
    """Read a static layer (``RUN/static.npz``, or the run folder); InputError naming the file when it is not one."""
    import json

    path = Path(path)
    if path.is_dir():
        path = path / STATIC_FILE
    if not path.is_file():
        raise InputError(path, None, "file not found (no static layer: the run's scene had no plates)")
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != FORMAT:
                raise InputError(path, "format", f"expected {FORMAT!r}, got {str(data['format'])!r}")
            arrays = {k: np.asarray(data[k], np.float32) for k in
                      ("means", "scales", "quats", "opacities", "colors", "background")}
            info = json.loads(str(data["info"]))
    except (KeyError, ValueError, OSError) as err:
        raise InputError(path, None, f"not a static layer file ({err})") from None
    n = len(arrays["means"])
    shapes = {"means": (n, 3), "scales": (n, 3), "quats": (n, 4), "opacities": (n,)}
    for key, shape in shapes.items():
        if arrays[key].shape != shape:
            raise InputError(path, key, f"expected shape {shape}, got {arrays[key].shape}")
    if arrays["colors"].ndim != 2 or arrays["colors"].shape[0] != n or \
            arrays["background"].shape != (arrays["colors"].shape[1],):
        raise InputError(path, "colors", "colors must be [N, C] and background [C]")
    return StaticLayer(**arrays, info=info)
