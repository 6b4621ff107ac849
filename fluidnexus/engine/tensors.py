"""Copies between Taichi fields and torch tensors / numpy arrays over the active rows only."""

import numpy as np
import taichi as ti
import torch

from .runtime import current


def torch_dtype() -> torch.dtype:
    """The torch dtype of the running Taichi precision."""
    return torch.float64 if current().precision == "f64" else torch.float32


def as_tensor(x, dims: int | None = None) -> torch.Tensor:
    """``x`` (numpy or torch) as a contiguous detached CPU tensor of the running precision, shape [N, dims]."""
    t = torch.as_tensor(np.asarray(x) if not isinstance(x, torch.Tensor) else x.detach())
    t = t.to(device="cpu", dtype=torch_dtype()).contiguous()
    if dims is not None and (t.ndim != 2 or t.shape[1] != dims):
        raise ValueError(f"expected shape [N, {dims}], got {tuple(t.shape)}")
    return t


@ti.kernel
def _load_vec(dst: ti.template(), row: int, src: ti.types.ndarray(), n: int):
    for i in range(n):
        for d in ti.static(range(dst.n)):
            if ti.static(len(dst.shape) == 2):
                dst[row, i][d] = src[i, d]
            else:
                dst[i][d] = src[i, d]


@ti.kernel
def _load_scalar(dst: ti.template(), src: ti.types.ndarray(), n: int):
    for i in range(n):
        dst[i] = src[i, 0]


@ti.kernel
def _store_vec(src: ti.template(), row: int, dst: ti.types.ndarray(), n: int):
    for i in range(n):
        for d in ti.static(range(src.n)):
            if ti.static(len(src.shape) == 2):
                dst[i, d] = src[row, i][d]
            else:
                dst[i, d] = src[i][d]


@ti.kernel
def _store_scalar(src: ti.template(), dst: ti.types.ndarray(), n: int):
    for i in range(n):
        dst[i, 0] = src[i]


def _is_vec(field) -> bool:
    return isinstance(field, ti.MatrixField)


def load(field, values, row: int = 0) -> None:
    """Write ``values`` [n, dims] into the first n entries of ``field`` ([cap] or row ``row`` of [rows, cap])."""
    t = as_tensor(values)
    t = t.reshape(t.shape[0], -1) if t.numel() else t.reshape(t.shape[0] if t.ndim else 0, 1)
    if t.shape[0] > field.shape[-1]:
        raise ValueError(f"{t.shape[0]} rows exceed the capacity {field.shape[-1]}")
    if t.shape[0]:
        if _is_vec(field):
            _load_vec(field, row, t, t.shape[0])
        else:
            _load_scalar(field, t, t.shape[0])


def store(field, n: int, row: int = 0) -> torch.Tensor:
    """The first n entries of ``field`` as a torch tensor [n, dims] of the running precision."""
    out = torch.zeros((n, field.n if _is_vec(field) else 1), dtype=torch_dtype())
    if n:
        if _is_vec(field):
            _store_vec(field, row, out, n)
        else:
            _store_scalar(field, out, n)
    return out
