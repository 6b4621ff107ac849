"""``cogvideox``: video SDEdit refinement with diffusers' ``CogVideoXVideoToVideoPipeline`` (paper Eq. 2).

The rough video is letterboxed to the model's size (720 x 480 for CogVideoX-5B), refined at SDEdit strength
lambda (the pipeline starts ``int(steps * lambda)`` steps from the end), and cropped and resized back.

Long videos (paper Sec. 3.1, "long video generation"): the first ``window`` (49) frames are refined as is.
Every later window starts with the last ``prefix`` (S = 9) frames of the output so far and extends it by
``window - S`` new rough frames. The prefix frames are encoded once (9 frames = 3 latent frames of the causal
VAE) and re-inserted into the latents after every denoising step, noised to the level of the next step and
clean after the last one, so the new frames are denoised in agreement with frames already produced. The
FluidNexus release used real target-view frames as the first prefix; this tool never has them.

Weights: a diffusers-format folder (``model_index.json``, ``transformer/``, ``vae/``, ``text_encoder/``,
``tokenizer/``, ``scheduler/``), loaded offline; an optional LoRA folder as written by diffusers'
``save_lora_weights`` (``pytorch_lora_weights.safetensors``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..progress import progress
from .refiner import VideoRefiner
from .weights import check_folder, require_gen, resolve_device

LAYOUT = {
    ".": ("model_index.json",),
    "transformer": ("config.json", "*weights"),
    "vae": ("config.json", "*weights"),
    "text_encoder": ("config.json", "*weights"),
    "tokenizer": ("tokenizer_config.json",),
    "scheduler": ("scheduler_config.json",),
}
LORA_LAYOUT = {".": ("pytorch_lora_weights.safetensors",)}
DEFAULT_PROMPT = "A plume of white smoke rises and swirls against a black background."


@dataclass(frozen=True)
class CogVideoXConfig:
    """Settings of the CogVideoX refiner.

    Attributes:
        strength: SDEdit strength lambda in [0, 1] (paper: 0.5 for novel views, 0.75 for predicted frames).
        steps: denoising steps of the full schedule.
        guidance: classifier-free guidance scale.
        size: (width, height) the model runs at; the video is letterboxed into it.
        window: frames per window (T' = 49; must be 4 k + 1 for the causal VAE).
        prefix: clean frames carried into each later window (S = 9, 4 k + 1).
        prompt: the text prompt (ignored when ``prompt_embeds`` is given).
        max_text_length: tokens of the prompt (226 for CogVideoX).
        prompt_embeds: path of a torch-saved tensor [1, L, D] of precomputed prompt embeddings.
        seed: random seed of the noise.
        device: torch device (None: a GPU when there is one).
        offload: sequential CPU offload of the sub-models (small GPUs).
    """

    strength: float = 0.5
    steps: int = 50
    guidance: float = 6.0
    size: tuple[int, int] = (720, 480)
    window: int = 49
    prefix: int = 9
    prompt: str = DEFAULT_PROMPT
    max_text_length: int = 226
    prompt_embeds: str | None = None
    seed: int = 0
    device: str | None = None
    offload: bool = False


def letterbox_box(width: int, height: int, size: tuple[int, int]) -> tuple[int, int, int, int]:
    """(x0, y0, w, h) of a ``width x height`` frame scaled to fit inside ``size`` (W, H), centred."""
    scale = min(size[0] / width, size[1] / height)
    w, h = max(1, round(width * scale)), max(1, round(height * scale))
    return (size[0] - w) // 2, (size[1] - h) // 2, w, h


def letterbox(video: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """[T, H, W, C] -> [T, size[1], size[0], 3]: fit, centre, pad with black; gray becomes RGB."""
    import cv2

    x0, y0, w, h = letterbox_box(video.shape[2], video.shape[1], size)
    out = np.zeros((video.shape[0], size[1], size[0], 3), np.float32)
    for t, frame in enumerate(video):
        resized = cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA).reshape(h, w, -1)
        out[t, y0:y0 + h, x0:x0 + w] = resized if resized.shape[-1] == 3 else np.repeat(resized, 3, -1)
    return out


def unletterbox(video: np.ndarray, width: int, height: int, channels: int) -> np.ndarray:
    """Inverse of :func:`letterbox`: crop the box and resize back to ``width x height`` with ``channels``."""
    import cv2

    size = (video.shape[2], video.shape[1])
    x0, y0, w, h = letterbox_box(width, height, size)
    out = np.empty((video.shape[0], height, width, channels), np.float32)
    for t, frame in enumerate(video):
        crop = cv2.resize(np.ascontiguousarray(frame[y0:y0 + h, x0:x0 + w]), (width, height),
                          interpolation=cv2.INTER_LINEAR)
        out[t] = crop.mean(axis=-1, keepdims=True) if channels == 1 else crop
    return np.clip(out, 0.0, 1.0)


def window_starts(frames: int, window: int, prefix: int) -> list[int]:
    """First frame of every window: 0, then each window begins ``prefix`` frames before the previous end."""
    starts, end = [0], window
    while end < frames:
        starts.append(end - prefix)
        end += window - prefix
    return starts


def load_pipeline(weights: str | Path, lora: str | Path | None = None, device: str | None = None,
                  offload: bool = False):
    """Load ``CogVideoXVideoToVideoPipeline`` from a local folder (offline), with an optional fused LoRA.

    Raises:
        InputError: a missing or incomplete folder (every missing file named).
        ImportError: the ``[gen]`` extra is not installed.
    """
    root = check_folder(weights, LAYOUT, "CogVideoX", "--weights")
    lora_root = check_folder(lora, LORA_LAYOUT, "CogVideoX LoRA", "--lora") if lora is not None else None
    torch, diffusers = require_gen("cogvideox")
    device = resolve_device(torch, device)
    dtype = torch.bfloat16 if device.startswith("cuda") else torch.float32
    pipe = diffusers.CogVideoXVideoToVideoPipeline.from_pretrained(root, dtype=dtype, local_files_only=True)
    if lora_root is not None:
        pipe.load_lora_weights(lora_root, adapter_name="refiner")
        pipe.fuse_lora(lora_scale=1.0)
    if offload:
        if not device.startswith("cuda"):
            raise InputError(None, "--offload", "CPU offload needs a CUDA GPU")
        pipe.enable_model_cpu_offload()
        pipe.vae.enable_tiling()
    else:
        pipe.to(device)
    pipe.set_progress_bar_config(disable=True)
    return pipe, device


class CogVideoXRefiner(VideoRefiner):
    """The ``cogvideox`` backend (module docstring)."""

    name = "cogvideox"
    generative = True

    def __init__(self, weights: str | Path | None = None, lora: str | Path | None = None,
                 config: CogVideoXConfig = CogVideoXConfig()):
        if not 0.0 <= config.strength <= 1.0:
            raise InputError(None, "--strength", f"must be in [0, 1], got {config.strength}")
        for name, value in (("window", config.window), ("prefix", config.prefix)):
            if value < 1 or (value - 1) % 4:
                raise InputError(None, name, f"must be 4 k + 1 frames (the VAE's causal grouping), got {value}")
        if config.prefix >= config.window:
            raise InputError(None, "prefix", f"must be shorter than the window ({config.window}), got {config.prefix}")
        self.config, self.weights, self.lora = config, weights, lora
        self.pipe, self.device = load_pipeline(weights, lora, config.device, config.offload)
        self.windows: list[dict] = []  # per window of the last call: prefix latents and final latents

    def provenance(self) -> dict:
        c = self.config
        lora = None if self.lora is None else str(self.lora)
        return {"method": self.name, "weights": str(self.weights), "lora": lora,
                "strength": c.strength, "steps": c.steps, "guidance": c.guidance, "size": list(c.size),
                "window": c.window, "prefix": c.prefix, "seed": c.seed,
                "prompt": None if c.prompt_embeds else c.prompt, "prompt_embeds": c.prompt_embeds}

    def refine(self, video: np.ndarray) -> np.ndarray:
        c = self.config
        if int(c.steps * c.strength) == 0:  # SDEdit with no denoising step leaves the video as it is
            return np.asarray(video, np.float32).copy()
        frames, height, width, channels = video.shape
        boxed = letterbox(np.asarray(video, np.float32), c.size)
        starts = window_starts(frames, c.window, c.prefix)
        out = np.empty_like(boxed)
        self.windows = []
        with progress("cogvideox windows", len(starts)) as bar:
            for k, start in enumerate(starts):
                chunk = boxed[start:start + c.window]
                if k > 0:
                    chunk = np.concatenate([out[start:start + c.prefix], chunk[c.prefix:]])
                valid = len(chunk)
                if valid < c.window:  # pad the last window by repeating its last frame
                    chunk = np.concatenate([chunk, np.repeat(chunk[-1:], c.window - valid, 0)])
                refined = self._window(chunk, chunk[:c.prefix] if k > 0 else None)
                keep = 0 if k == 0 else c.prefix
                out[start + keep:start + valid] = refined[keep:valid]
                bar.advance()
        return unletterbox(out, width, height, channels)

    def _prompt_kwargs(self, torch) -> dict:
        c = self.config
        if c.prompt_embeds is None:
            return {"prompt": c.prompt}
        path = Path(c.prompt_embeds)
        if not path.is_file():
            raise InputError(path, "--prompt-embeds", "file not found")
        embeds = torch.load(path, map_location="cpu", weights_only=True)
        if embeds.ndim != 3:
            raise InputError(path, "--prompt-embeds", f"expected a [1, L, D] tensor, got shape {tuple(embeds.shape)}")
        dtype = self.pipe.transformer.dtype
        return {"prompt_embeds": embeds.to(self.device, dtype),
                "negative_prompt_embeds": torch.zeros_like(embeds).to(self.device, dtype)}

    def _window(self, chunk: np.ndarray, prefix: np.ndarray | None) -> np.ndarray:
        """Refine one [window, H, W, 3] chunk; with ``prefix`` re-insert its latents at every step."""
        torch, _ = require_gen("cogvideox")
        c, pipe = self.config, self.pipe
        generator = torch.Generator("cpu").manual_seed(c.seed)
        height, width = c.size[1], c.size[0]
        record = {"prefix": None if prefix is None else self._encode(prefix, height, width), "final": None}
        callback = self._reinsert(record, generator)
        result = pipe(video=chunk[None], height=height, width=width, num_inference_steps=c.steps,
                      strength=c.strength, guidance_scale=c.guidance, generator=generator, output_type="np",
                      max_sequence_length=c.max_text_length, callback_on_step_end=callback,
                      callback_on_step_end_tensor_inputs=["latents"], **self._prompt_kwargs(torch))
        self.windows.append(record)
        return np.asarray(result.frames[0], np.float32)[:len(chunk)]

    def _encode(self, frames: np.ndarray, height: int, width: int):
        """Clean latents [1, F_lat, C, h, w] of frames in [0, 1], scaled as the pipeline scales them."""
        torch, _ = require_gen("cogvideox")
        pipe = self.pipe
        video = pipe.video_processor.preprocess_video(frames[None], height=height, width=width)
        video = video.to(self.device, pipe.vae.dtype)
        with torch.no_grad():
            latents = pipe.vae.encode(video).latent_dist.mode()
        return (pipe.vae_scaling_factor_image * latents).permute(0, 2, 1, 3, 4)

    def _reinsert(self, record: dict, generator):
        """A step-end callback that overwrites the first latent frames with ``record["prefix"]`` noised to the
        next step's level (clean after the last step) and keeps the latents in ``record["final"]``."""
        torch, _ = require_gen("cogvideox")
        prefix = record["prefix"]
        noise = None if prefix is None else torch.randn(prefix.shape, generator=generator).to(prefix)

        def callback(pipe, i, t, cb):
            latents = cb["latents"]
            if prefix is not None:
                latents = latents.clone()
                count, timesteps = prefix.shape[1], pipe.scheduler.timesteps
                index = int((timesteps == t).nonzero()[0, 0])
                if index + 1 < len(timesteps):
                    noisy = pipe.scheduler.add_noise(prefix, noise, timesteps[index + 1:index + 2])
                    latents[:, :count] = noisy.to(latents.dtype)
                else:
                    latents[:, :count] = prefix.to(latents.dtype)
            record["final"] = latents
            return {"latents": latents}

        return callback
