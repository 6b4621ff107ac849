"""The engine's one bridge between Taichi fields and torch tensors (simulator and renderer alike).

Copies cover the first n entries of a field (its capacity may be larger; a load may start further on): a vector
field [cap] or one row of a [rows, cap] field holds [n, dims] tensors, a scalar field [cap] (or a row of [rows,
cap]) holds n values, given in any shape with n elements. A field's ``.grad`` is a field too, so the same calls
move gradients.

Every tensor handed to a kernel is detached first: Taichi inspects the ``.grad`` of a tensor that requires grad
(torch then warns about reading the ``.grad`` of a non-leaf, and a leaf gets a zero ``.grad`` allocated).
"""
import numpy as np
import taichi as ti
import torch

from .runtime import current


def torch_dtype() -> torch.dtype:
    """The torch dtype of the running Taichi precision (float64 or float32)."""
    return torch.float64 if current().precision == "f64" else torch.float32


def torch_device() -> torch.device:
    """The torch device whose tensors the running Taichi arch reads in place."""
    return torch.device("cuda" if current().arch == "cuda" else "cpu")


def as_tensor(x, dims: int | None = None) -> torch.Tensor:
    """``x`` (numpy or torch) as a contiguous detached CPU tensor of the running precision, shape [N, dims]."""
    t = torch.as_tensor(np.asarray(x) if not isinstance(x, torch.Tensor) else x.detach())
    t = t.to(device="cpu", dtype=torch_dtype()).contiguous()
    if dims is not None and (t.ndim != 2 or t.shape[1] != dims):
        raise ValueError(f"expected shape [N, {dims}], got {tuple(t.shape)}")
    return t


@ti.kernel
def _load_vec(dst: ti.template(), row: ti.i32, start: ti.i32, src: ti.types.ndarray(), n: ti.i32):
    for i in range(n):
        for d in ti.static(range(dst.n)):
            if ti.static(len(dst.shape) == 2):
                dst[row, start + i][d] = src[i, d]
            else:
                dst[start + i][d] = src[i, d]


@ti.kernel
def _load_scalar(dst: ti.template(), row: ti.i32, start: ti.i32, src: ti.types.ndarray(), n: ti.i32):
    for i in range(n):
        if ti.static(len(dst.shape) == 2):
            dst[row, start + i] = src[i]
        else:
            dst[start + i] = src[i]


@ti.kernel
def _store_vec(src: ti.template(), row: ti.i32, dst: ti.types.ndarray(), n: ti.i32):
    for i in range(n):
        for d in ti.static(range(src.n)):
            if ti.static(len(src.shape) == 2):
                dst[i, d] = src[row, i][d]
            else:
                dst[i, d] = src[i][d]


@ti.kernel
def _store_scalar(src: ti.template(), row: ti.i32, dst: ti.types.ndarray(), n: ti.i32):
    for i in range(n):
        if ti.static(len(src.shape) == 2):
            dst[i] = src[row, i]
        else:
            dst[i] = src[i]


def _dims(field) -> int:
    """Components per entry: n of a vector field, 1 of a scalar field."""
    return field.n if isinstance(field, ti.MatrixField) else 1


def load(field, values, row: int = 0, start: int = 0) -> None:
    """Write ``values`` into the n entries of ``field`` from ``start`` on ([cap], or row ``row`` of [rows, cap]).

    Args:
        field: a Taichi field (or a field's ``.grad``).
        values: numpy or torch (any device; converted to the running precision), [n, dims] for a vector field,
            n values in any shape for a scalar field.
        start: the first entry written (0: the first n entries).
    """
    t = values.detach() if isinstance(values, torch.Tensor) else torch.as_tensor(np.asarray(values))
    t = t.to(dtype=torch_dtype()).contiguous()
    dims = _dims(field)
    if dims > 1 and (t.ndim != 2 or t.shape[1] != dims):
        raise ValueError(f"expected shape [n, {dims}], got {tuple(t.shape)}")
    n = t.numel() // dims
    t = t.reshape(n) if dims == 1 else t
    if start + n > field.shape[-1]:
        raise ValueError(f"{n} rows from row {start} exceed the capacity {field.shape[-1]}")
    if n:
        (_load_vec if dims > 1 else _load_scalar)(field, row, start, t, n)


def store(field, n: int, row: int = 0, out: torch.Tensor | None = None) -> torch.Tensor:
    """The first n entries of ``field`` as a tensor of the running precision.

    Args:
        field: a Taichi field (or a field's ``.grad``), [cap] or [rows, cap] (then row ``row``).
        n: entries to copy.
        out: where to write (contiguous, running precision, n * dims elements, any shape, on the CPU or the
            engine's device); by default a new CPU tensor [n, dims] ([n] for a scalar field).
    Returns:
        ``out``, filled.
    """
    dims = _dims(field)
    if out is None:
        out = torch.empty((n, dims) if dims > 1 else (n,), dtype=torch_dtype())
    if out.numel() != n * dims or not out.is_contiguous():
        raise ValueError(f"out must be contiguous with {n * dims} elements, got {tuple(out.shape)}")
    if n:
        (_store_vec if dims > 1 else _store_scalar)(field, row, out.view(n, dims) if dims > 1 else out.view(n), n)
    return out
