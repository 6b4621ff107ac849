"""LPIPS image distance (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep Features as a Perceptual
Metric"), AlexNet variant, version 0.1, in plain torch with weights loaded from a local folder. Never downloads.

The folder given as ``--lpips-weights DIR`` must hold two files (both plain torch state dicts):

- ``alexnet-owt-7be5be79.pth``: torchvision's ImageNet AlexNet weights
  (https://download.pytorch.org/models/alexnet-owt-7be5be79.pth). Keys used: ``features.{0,3,6,8,10}.weight``
  and ``.bias``; the ``classifier.*`` keys are ignored.
- ``alex.pth``: the LPIPS v0.1 linear heads from the ``lpips`` package (``lpips/weights/v0.1/alex.pth``). Keys
  ``lin{0..4}.model.1.weight``, shapes [1, C, 1, 1] for C = 64, 192, 384, 256, 256.

Distance between images x0, x1 in [0, 1] (Zhang et al. 2018, Eq. 1): map to [-1, 1], subtract the shift and divide
by the scale of the v0.1 scaling layer, take the five ReLU outputs f_l of AlexNet's conv layers, normalise each
over channels, ``f / (||f||_2 + 1e-10)``, and sum over layers the spatial mean of
``w_l . (f0_l - f1_l)^2`` (a 1x1 convolution without bias).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn.functional as F

from .errors import InputError

BACKBONE_FILE = "alexnet-owt-7be5be79.pth"
HEADS_FILE = "alex.pth"
CHANNELS = (64, 192, 384, 256, 256)
# (torchvision key, in channels, kernel, stride, padding) of AlexNet's five conv layers.
CONVS = (("features.0", 3, 11, 4, 2), ("features.3", 64, 5, 1, 2), ("features.6", 192, 3, 1, 1),
         ("features.8", 384, 3, 1, 1), ("features.10", 256, 3, 1, 1))
SHIFT = (-0.030, -0.088, -0.188)
SCALE = (0.458, 0.448, 0.450)
MIN_SIZE = 31
"""Smallest image side for which AlexNet's fifth layer still has one pixel."""


@dataclass(frozen=True)
class LpipsWeights:
    """AlexNet conv weights/biases and the five LPIPS linear heads.

    Attributes:
        conv_weights: five [C_out, C_in, k, k] tensors.
        conv_biases: five [C_out] tensors.
        heads: five [1, C, 1, 1] tensors (non-negative in the published weights).
    """

    conv_weights: tuple[torch.Tensor, ...]
    conv_biases: tuple[torch.Tensor, ...]
    heads: tuple[torch.Tensor, ...]

    def to(self, device=None, dtype=None) -> "LpipsWeights":
        def move(ts):
            return tuple(t.to(device=device, dtype=dtype) for t in ts)
        return LpipsWeights(move(self.conv_weights), move(self.conv_biases), move(self.heads))


def load_weights(folder: str | Path) -> LpipsWeights:
    """Load the two weight files described in the module docstring from ``folder``.

    Raises:
        InputError: the folder or a file is missing or unreadable, or a key is missing or has the wrong shape.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, None, "LPIPS weights folder not found")
    backbone = read_state_dict(folder / BACKBONE_FILE)
    heads = read_state_dict(folder / HEADS_FILE)
    weights, biases = [], []
    for (key, c_in, k, _, _), c_out in zip(CONVS, CHANNELS):
        weights.append(tensor(backbone, folder / BACKBONE_FILE, f"{key}.weight", (c_out, c_in, k, k)))
        biases.append(tensor(backbone, folder / BACKBONE_FILE, f"{key}.bias", (c_out,)))
    lins = tuple(tensor(heads, folder / HEADS_FILE, f"lin{i}.model.1.weight", (1, c, 1, 1))
                 for i, c in enumerate(CHANNELS))
    return LpipsWeights(tuple(weights), tuple(biases), lins)


def read_state_dict(path: Path) -> dict:
    if not path.is_file():
        raise InputError(path, None, "file not found (LPIPS needs alexnet-owt-7be5be79.pth and alex.pth)")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # pickle, zip and torch errors all mean "not a weights file"
        raise InputError(path, None, f"not a readable torch state dict ({err})") from None
    if not isinstance(state, dict):
        raise InputError(path, None, f"expected a state dict, got {type(state).__name__}")
    return state


def tensor(state: dict, path: Path, key: str, shape: tuple[int, ...]) -> torch.Tensor:
    if key not in state:
        raise InputError(path, key, "missing key")
    value = state[key]
    if not isinstance(value, torch.Tensor) or tuple(value.shape) != shape:
        got = tuple(value.shape) if isinstance(value, torch.Tensor) else type(value).__name__
        raise InputError(path, key, f"expected shape {shape}, got {got}")
    return value.detach().float()


def alexnet_features(weights: LpipsWeights, x: torch.Tensor) -> list[torch.Tensor]:
    """The five ReLU outputs relu1..relu5 of AlexNet's feature extractor.

    Args:
        x: [B, 3, H, W] scaled input.

    Returns:
        five [B, C_l, H_l, W_l] tensors, C_l = 64, 192, 384, 256, 256.
    """
    feats = []
    for layer, ((_, _, _, stride, pad), w, b) in enumerate(zip(CONVS, weights.conv_weights, weights.conv_biases)):
        if layer in (1, 2):  # max pooling before conv2 and conv3
            x = F.max_pool2d(x, kernel_size=3, stride=2)
        x = F.relu(F.conv2d(x, w, b, stride=stride, padding=pad))
        feats.append(x)
    return feats


def lpips(weights: LpipsWeights, image0: torch.Tensor, image1: torch.Tensor) -> torch.Tensor:
    """LPIPS distance between two batches of images (0 for identical images, larger is more different).

    Args:
        weights: from :func:`load_weights`, on the images' device and dtype.
        image0, image1: [B, H, W, C] or [H, W, C] images in [0, 1] (docs/conventions.md), C = 1 (gray,
            replicated to RGB) or 3; H, W >= 31.

    Returns:
        [B] distances (a 0-d tensor for unbatched input).

    Raises:
        InputError: images of different shapes, not 1 or 3 channels, or smaller than 31 pixels on a side.
    """
    if image0.shape != image1.shape:
        raise InputError(None, "image", f"LPIPS needs images of one shape, got {tuple(image0.shape)} and "
                                        f"{tuple(image1.shape)}")
    h, w, c = image0.shape[-3:]
    if c not in (1, 3):
        raise InputError(None, "image", f"LPIPS needs 1 or 3 channels, got {c}")
    if min(h, w) < MIN_SIZE:
        raise InputError(None, "image", f"LPIPS needs images of at least {MIN_SIZE}x{MIN_SIZE} pixels, got {h}x{w}")
    feats0, feats1 = (alexnet_features(weights, scale_input(im.reshape(-1, h, w, c))) for im in (image0, image1))
    total = 0
    for f0, f1, head in zip(feats0, feats1, weights.heads):
        f0 = f0 / (f0.norm(dim=1, keepdim=True) + 1e-10)  # unit length over channels
        f1 = f1 / (f1.norm(dim=1, keepdim=True) + 1e-10)
        total = total + F.conv2d((f0 - f1) ** 2, head).mean(dim=(1, 2, 3))  # Zhang et al. 2018, Eq. 1
    return total.reshape(image0.shape[:-3])


def scale_input(images: torch.Tensor) -> torch.Tensor:
    """[B, H, W, C] in [0, 1] -> [B, 3, H, W] network input: [-1, 1], then the v0.1 scaling layer; gray -> RGB."""
    x = (2 * images - 1).permute(0, 3, 1, 2).expand(-1, 3, -1, -1)
    return (x - x.new_tensor(SHIFT)[:, None, None]) / x.new_tensor(SCALE)[:, None, None]
