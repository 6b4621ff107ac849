"""``zero123``: frame-wise novel-view diffusion, Zero-1-to-3 (Liu et al. 2023), paper Sec. 3.1 Eq. 1.

The pipeline is written here from diffusers components (diffusers' core has none):

- condition: the CLIP image embedding of the input frame, concatenated with the relative camera pose
  ``[d_polar, sin d_azimuth, cos d_azimuth, d_radius]`` (radians, metres; world up is the polar axis, both
  cameras measured from the scene's centre) and mapped back to the embedding width by the camera projection
  layer; it is the UNet's single cross-attention token;
- the VAE latent of the input frame (its mode, unscaled, as Zero123 was trained) is concatenated with the noisy
  latent along channels (UNet in_channels = 8);
- DDIM (eta = 0), 50 steps, classifier-free guidance 3.0 against a zero condition and zero image latent;
- frames are padded to a square (black), resized to 256 x 256, and the result is resized back and cropped.

Weights folder (the layout of the public diffusers conversions of Zero123 / Zero123-XL)::

    unet/            config.json + diffusion_pytorch_model.safetensors   (UNet2DConditionModel, 8 in-channels)
    vae/             config.json + diffusion_pytorch_model.safetensors   (AutoencoderKL)
    image_encoder/   config.json + model.safetensors                     (CLIPVisionModelWithProjection)
    cc_projection/   config.json + diffusion_pytorch_model.safetensors   (CameraProjection: Linear(E + 4, E))
    scheduler/       scheduler_config.json                               (read into a DDIMScheduler)
    feature_extractor/preprocessor_config.json  (optional: CLIP image_mean / image_std)
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..errors import InputError
from ..progress import progress
from .synthesizer import SynthesisInput, ViewSynthesizer
from .weights import check_folder, require_gen, resolve_device

LAYOUT = {
    "unet": ("config.json", "*weights"),
    "vae": ("config.json", "*weights"),
    "image_encoder": ("config.json", "*weights"),
    "cc_projection": ("config.json", "*weights"),
    "scheduler": ("scheduler_config.json",),
}
CLIP_MEAN = (0.48145466, 0.4578275, 0.40821073)
CLIP_STD = (0.26862954, 0.26130258, 0.27577711)


@dataclass(frozen=True)
class Zero123Config:
    """Settings of the Zero123 synthesiser.

    Attributes:
        steps: DDIM steps. guidance: classifier-free guidance scale. resolution: square model size, pixels.
        seed: noise seed (frame t uses seed + t). device: torch device (None: a GPU when there is one).
    """

    steps: int = 50
    guidance: float = 3.0
    resolution: int = 256
    seed: int = 0
    device: str | None = None


def spherical(camera: Camera, centre: np.ndarray) -> tuple[float, float, float]:
    """(polar, azimuth, radius) of the camera centre around ``centre``: polar from world +y, azimuth
    ``atan2(x, z)`` in the horizontal plane, radians and metres."""
    d = camera.center - centre
    radius = float(np.linalg.norm(d))
    return math.acos(np.clip(d[1] / radius, -1, 1)), math.atan2(d[0], d[2]), radius


def relative_pose(source: Camera, target: Camera, centre: np.ndarray) -> list[float]:
    """Zero123's pose condition ``[d_polar, sin d_azimuth, cos d_azimuth, d_radius]`` from source to target."""
    p0, a0, r0 = spherical(source, centre)
    p1, a1, r1 = spherical(target, centre)
    return [p1 - p0, math.sin(a1 - a0), math.cos(a1 - a0), r1 - r0]


def _centre(inp: SynthesisInput) -> np.ndarray:
    if inp.volume is not None:
        return inp.volume.center
    if inp.source is not None:
        return np.asarray(inp.source.center, np.float64)
    raise InputError(None, "volume", "zero123 needs the scene's volume (or source) as the orbit centre")


def camera_projection_class():
    """The ``CameraProjection`` model class (defined lazily: it subclasses diffusers' ModelMixin)."""
    from diffusers import ConfigMixin, ModelMixin
    from diffusers.configuration_utils import register_to_config
    from torch import nn

    class CameraProjection(ModelMixin, ConfigMixin):
        """Linear map of [CLIP image embedding, 4 pose numbers] back to the embedding width."""

        @register_to_config
        def __init__(self, in_channel: int = 772, out_channel: int = 768):
            super().__init__()
            self.projection = nn.Linear(in_channel, out_channel)

        def forward(self, x):
            return self.projection(x)

    return CameraProjection


def pad_square(frame: np.ndarray) -> tuple[np.ndarray, tuple[int, int]]:
    """Centre [H, W, C] in a black square; returns the square and the (y0, x0) offset of the frame."""
    h, w = frame.shape[:2]
    side = max(h, w)
    y0, x0 = (side - h) // 2, (side - w) // 2
    out = np.zeros((side, side, frame.shape[2]), np.float32)
    out[y0:y0 + h, x0:x0 + w] = frame
    return out, (y0, x0)


class Zero123Pipeline:
    """Zero123 inference from diffusers components (module docstring), one frame at a time."""

    def __init__(self, weights: str | Path | None, config: Zero123Config = Zero123Config()):
        root = check_folder(weights, LAYOUT, "Zero123", "--weights")
        torch, diffusers = require_gen("zero123")
        from transformers import CLIPVisionModelWithProjection

        self.torch, self.config = torch, config
        self.device = resolve_device(torch, config.device)
        self.dtype = torch.float16 if self.device.startswith("cuda") else torch.float32
        load = {"dtype": self.dtype, "local_files_only": True}
        self.unet = diffusers.UNet2DConditionModel.from_pretrained(root / "unet", **load).to(self.device).eval()
        self.vae = diffusers.AutoencoderKL.from_pretrained(root / "vae", **load).to(self.device).eval()
        self.encoder = CLIPVisionModelWithProjection.from_pretrained(root / "image_encoder", **load)
        self.encoder = self.encoder.to(self.device).eval()
        self.projection = camera_projection_class().from_pretrained(root / "cc_projection", **load)
        self.projection = self.projection.to(self.device).eval()
        self.scheduler = diffusers.DDIMScheduler.from_pretrained(root / "scheduler", local_files_only=True)
        self.mean, self.std = self._clip_stats(root / "feature_extractor" / "preprocessor_config.json")
        self.vae_factor = 2 ** (len(self.vae.config.block_out_channels) - 1)

    @staticmethod
    def _clip_stats(path: Path):
        if not path.is_file():
            return CLIP_MEAN, CLIP_STD
        data = json.loads(path.read_text())
        return tuple(data.get("image_mean", CLIP_MEAN)), tuple(data.get("image_std", CLIP_STD))

    def _condition(self, image, pose: list[float]):
        """[1, 1, E] cross-attention token from a [1, 3, R, R] image in [0, 1] and the pose."""
        torch, F = self.torch, self.torch.nn.functional
        size = self.encoder.config.image_size
        clip_in = F.interpolate(image, size=(size, size), mode="bicubic", align_corners=False, antialias=True)
        mean = torch.tensor(self.mean, device=self.device, dtype=self.dtype).view(1, 3, 1, 1)
        std = torch.tensor(self.std, device=self.device, dtype=self.dtype).view(1, 3, 1, 1)
        embed = self.encoder((clip_in - mean) / std).image_embeds  # [1, E]
        pose_t = torch.tensor([pose], device=self.device, dtype=self.dtype)
        return self.projection(torch.cat([embed, pose_t], dim=-1))[:, None, :]

    def __call__(self, image: np.ndarray, pose: list[float], seed: int) -> np.ndarray:
        """One novel view: [R, R, 3] in [0, 1] and a pose condition -> [R, R, 3] in [0, 1]."""
        torch, c = self.torch, self.config
        with torch.no_grad():
            x = torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1)[None].to(self.device, self.dtype)
            cond = self._condition(x, pose)
            image_latent = self.vae.encode(x * 2 - 1).latent_dist.mode()
            cond_all = torch.cat([torch.zeros_like(cond), cond])
            latent_all = torch.cat([torch.zeros_like(image_latent), image_latent])
            generator = torch.Generator("cpu").manual_seed(seed)
            shape = (1, self.unet.config.out_channels, image.shape[0] // self.vae_factor,
                     image.shape[1] // self.vae_factor)
            latents = torch.randn(shape, generator=generator).to(self.device, self.dtype)
            self.scheduler.set_timesteps(c.steps, device=self.device)
            latents = latents * self.scheduler.init_noise_sigma
            for t in self.scheduler.timesteps:
                model_in = torch.cat([self.scheduler.scale_model_input(latents, t)] * 2)
                model_in = torch.cat([model_in, latent_all], dim=1)
                uncond, cond_pred = self.unet(model_in, t, encoder_hidden_states=cond_all).sample.chunk(2)
                noise = uncond + c.guidance * (cond_pred - uncond)
                latents = self.scheduler.step(noise, t, latents, eta=0.0).prev_sample
            decoded = self.vae.decode(latents / self.vae.config.scaling_factor).sample
        return ((decoded[0].float().permute(1, 2, 0).cpu().numpy() + 1) / 2).clip(0, 1)


class Zero123Synthesizer(ViewSynthesizer):
    """The ``zero123`` backend: square padding, resize to the model size, Zero123, resize back, crop."""

    name = "zero123"

    def __init__(self, weights: str | Path | None = None, config: Zero123Config = Zero123Config()):
        self.weights, self.config = weights, config
        self.pipeline = Zero123Pipeline(weights, config)

    def provenance(self) -> dict:
        c = self.config
        return {"method": self.name, "weights": str(self.weights), "steps": c.steps, "guidance": c.guidance,
                "resolution": c.resolution, "seed": c.seed, "scheduler": "DDIM"}

    def synthesize(self, inp: SynthesisInput, target: Camera) -> np.ndarray:
        import cv2

        pose = relative_pose(inp.camera, target, _centre(inp))
        res, frames = self.config.resolution, inp.video.shape[0]
        channels = inp.video.shape[-1]
        out = np.empty((frames, target.height, target.width, channels), np.float32)
        with progress("zero123 frames", frames) as bar:
            for t, frame in enumerate(inp.video):
                rgb = frame if channels == 3 else np.repeat(frame, 3, axis=-1)
                square, _ = pad_square(rgb.astype(np.float32))
                small = cv2.resize(square, (res, res), interpolation=cv2.INTER_AREA)
                novel = self.pipeline(small, pose, self.config.seed + t)
                out[t] = self._crop_back(novel, target, channels)
                bar.advance()
        return out

    @staticmethod
    def _crop_back(novel: np.ndarray, target: Camera, channels: int) -> np.ndarray:
        """Resize the square result to the target's padded square and crop the target frame out of it."""
        import cv2

        side = max(target.height, target.width)
        big = cv2.resize(novel, (side, side), interpolation=cv2.INTER_LINEAR)
        y0, x0 = (side - target.height) // 2, (side - target.width) // 2
        crop = big[y0:y0 + target.height, x0:x0 + target.width]
        return crop.mean(axis=-1, keepdims=True) if channels == 1 else crop
