"""Reconstruction settings: one frozen dataclass, defaults from the authors' release (method notes).

Exception: the iteration counts. The release runs 1000 (frame 0) and 250 (per frame) Adam iterations on a GPU;
on a 2-core CPU that is about an hour for the 120 ScalarFlow frames, so the defaults are 300 / 40 / 20
(init / dynamics / appearance) and ``--init-iters 1000 --dynamics-iters 250`` gives the release's counts.

Lengths are metres. The release works in a x100 scaled space (1 unit = 1 cm); its squared-distance weights are
kept by measuring the simulation term in centimetres (``LENGTH_UNIT``), see docs/reconstruction.md.
The defaults are ScalarFlow's; :func:`config_for_scene` multiplies every setting named in ``LENGTHS`` (and the
loss unit) by the scene's length-scale factor (``fluidnexus.scene_scale``, docs/scale.md).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields

from ..errors import InputError

LENGTH_UNIT = 0.01  # metres per release unit: L_sim = lambda_sim * mean(|(p - p_sim) / LENGTH_UNIT|^2)
# The length settings (metres; defaults at ScalarFlow's scale), multiplied by the scene's length scale.
LENGTHS = ("lr_position", "visual_sigma", "scale0", "visual_spacing", "visual_radius", "init_visual_radius",
           "physical_spacing", "physical_radius", "physical_height", "physical_emit_spacing",
           "physical_emit_radius", "init_visual_height")


@dataclass(frozen=True)
class ReconConfig:
    """Everything that decides a reconstruction's result (saved as RUN/config.json).

    Attributes:
        frames: half-open frame range [start, stop) of the scene's videos; stop None = the last frame.
        resolution: image scale relative to the scene's videos.
        channels: 1 (gray smoke) or 3 (RGB).
        seed: random seed (view order, emitter jitter).
        init_iters: Adam iterations of the frame-0 visual position fit.
        dynamics_iters: stage-1 iterations per frame (optimising p_t).
        appearance_iters: stage-2 iterations per frame (colour, opacity, scale, rotation).
        views_per_iter: views rendered per iteration (the release uses one random view).
        lr_position: stage-1 / init learning rate, metres per step.
        lr_color, lr_opacity, lr_scale, lr_rotation: stage-2 learning rates (Adam, on the raw parameters:
            5x the 3DGS-style 0.01 / 0.05 / 0.005 for colour / opacity / scale, because stage 2 has only
            ``appearance_iters`` steps per frame: +1.5-1.8 dB novel-view PSNR on ScalarFlow, BENCHMARKS.md;
            colour and opacity in logit space, scale in log space).
        w_l1, w_dssim: image loss 0.8 L1 + 0.2 (1 - SSIM).
        lambda_sim: weight of |p_t - p_sim|^2 (in release units, see LENGTH_UNIT).
        lambda_density: weight of mean (rho(p_t)/rho0 - 1)^2.
        lambda_next: weight of the same on the look-ahead Sim(u_t, p_t).
        lambda_visual_incomp: weight of sum max(0, sigma - d_ij)^2 over visual pairs.
        visual_sigma: sigma of that term, metres.
        lambda_color, lambda_scale, lambda_opacity, lambda_rotation: temporal regularisation (paper Eq. 7).
        anisotropy_cap: largest allowed ratio of a Gaussian's largest to smallest scale.
        color0, scale0, opacity0: constant initial appearance of the visual particles (colour and opacity replaced
            by the fitted initial look where ``initial_look`` says so).
        initial_look: ``constant`` (color0 and opacity0 as given), ``fit`` (one colour and one opacity fitted to the
            earliest frame with smoke, ``fit.fit_look``, from color0 / opacity0; the fitted values are saved in
            config.json) or
            ``auto``: fit on footage over a backdrop (a scene with clean plates or a backdrop colour other than
            black), constant on footage over black (the release's constants were tuned on ScalarFlow's glowing
            smoke on black).
        physical_support: ``on``: before each frame's dynamics, physical particles at rest under the visual particles
            that have none within h (``recon/support.py``); ``off``: the paper's gas only; ``auto``: on over a
            backdrop, off on black (the rule of ``initial_look``; measured on PINF's Sphere and the composite
            backdrop scene, not on ScalarFlow, which stays as it was). config.json records the resolved value.
        visual_spacing, visual_radius: visual emitter lattice spacing and disk radius, metres.
        init_visual_radius: radius of the frame-0 visual cylinder, metres.
        physical_spacing: physical initial-lattice spacing, metres.
        physical_radius: radius of the physical cylinder and emitter, metres.
        physical_height: height of the initial physical cylinder (from 2 cm below the source), metres.
        physical_emit_spacing, physical_emit_radius: physical emitter lattice spacing and disk radius, metres.
        init_visual_height: height of the frame-0 visual cylinder above the source, metres.
        stabilization_steps: N_stable steps before frame 0.
        static_iters: iterations of the static-layer fit at the start of a run on a scene with clean plates
            (``scenery.static_layer``, docs/static-layer.md).
        length_scale: the scene's length-scale factor the lengths were derived with (1 on ScalarFlow); it also
            scales the loss unit (``loss_unit``) and the fixed offsets of the initialisation.
        max_loss: a loss above this (or NaN) stops the run (divergence). The visual spacing term is a sum over
            pairs and reaches thousands on a healthy 120-frame run, hence the high default.
    """

    frames: tuple[int, int | None] = (0, None)
    resolution: float = 0.25
    channels: int = 1
    seed: int = 0
    init_iters: int = 300
    dynamics_iters: int = 40
    appearance_iters: int = 20
    views_per_iter: int = 1
    lr_position: float = 1.6e-4
    lr_color: float = 0.05
    lr_opacity: float = 0.25
    lr_scale: float = 0.025
    lr_rotation: float = 0.001
    w_l1: float = 0.8
    w_dssim: float = 0.2
    lambda_sim: float = 0.1
    lambda_density: float = 1.0
    lambda_next: float = 0.1
    lambda_visual_incomp: float = 0.1
    visual_sigma: float = 0.00625
    lambda_color: float = 10.0
    lambda_scale: float = 0.0
    lambda_opacity: float = 8.0
    lambda_rotation: float = 0.1
    anisotropy_cap: float = 4.0
    color0: float = 0.7
    scale0: float = 0.0027
    opacity0: float = 0.1
    visual_spacing: float = 0.00625
    visual_radius: float = 0.025
    init_visual_radius: float = 0.03
    physical_spacing: float = 0.009
    physical_radius: float = 0.10
    physical_height: float = 0.10
    physical_emit_spacing: float = 0.015
    physical_emit_radius: float = 0.09
    init_visual_height: float = 0.05
    stabilization_steps: int = 20
    static_iters: int = 1200
    initial_look: str = "auto"
    physical_support: str = "auto"
    length_scale: float = 1.0
    max_loss: float = 1e6

    def __post_init__(self):
        checks = {
            "resolution": 0 < self.resolution <= 4, "channels": self.channels in (1, 3),
            "views_per_iter": self.views_per_iter >= 1, "anisotropy_cap": self.anisotropy_cap >= 1,
            "init_iters": self.init_iters >= 0, "dynamics_iters": self.dynamics_iters >= 0,
            "appearance_iters": self.appearance_iters >= 0, "stabilization_steps": self.stabilization_steps >= 0,
            "static_iters": self.static_iters >= 0, "initial_look": self.initial_look in ("auto", "fit", "constant"),
            "physical_support": self.physical_support in ("auto", "on", "off"),
            "frames": self.frames[0] >= 0 and (self.frames[1] is None or self.frames[1] > self.frames[0]),
        }
        for name in ("lr_position", "visual_sigma", "scale0", "visual_spacing", "visual_radius",
                     "physical_spacing", "physical_radius", "physical_height", "init_visual_radius",
                     "physical_emit_spacing", "physical_emit_radius", "init_visual_height", "length_scale"):
            checks[name] = getattr(self, name) > 0
        checks["opacity0"] = 0 < self.opacity0 < 1
        checks["color0"] = 0 < self.color0 < 1
        for name, ok in checks.items():
            if not ok:
                raise InputError(None, f"--{name.replace('_', '-')}", f"impossible value {getattr(self, name)!r}")

    @property
    def loss_unit(self) -> float:
        """Metres per loss unit of the squared-length terms (the release's 1 cm at ScalarFlow's scale)."""
        return LENGTH_UNIT * self.length_scale

    def to_dict(self) -> dict:
        d = asdict(self)
        d["frames"] = list(self.frames)
        return d

    @classmethod
    def from_dict(cls, d: dict, path=None) -> "ReconConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise InputError(path, unknown[0], "unknown reconstruction setting")
        d = dict(d)
        if "frames" in d:
            d["frames"] = tuple(d["frames"])
        return cls(**d)


def config_for_scene(scene, values: dict, path=None) -> ReconConfig:
    """The settings for ``scene``: every length in ``LENGTHS`` is its ScalarFlow default times the length-scale
    factor (``values["length_scale"]`` when given, else the scene's); ``values`` (a settings file, the command
    line) win over that."""
    from ..scene_scale import scaled, scene_factor

    factor = float(values["length_scale"]) if values.get("length_scale") is not None else scene_factor(scene)
    defaults = {f.name: f.default for f in fields(ReconConfig)}
    derived = {**scaled({k: defaults[k] for k in LENGTHS}, factor), "length_scale": factor}
    return ReconConfig.from_dict({**derived, **values}, path)


def differing_keys(a: dict, b: dict) -> list[str]:
    """Keys whose values differ between two resolved configs (for refusing a mismatched --resume)."""
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
