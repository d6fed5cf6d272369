"""Matrix products over many pixels, in blocks.

A product of an (N×K) pixel array with a small matrix is cheap, but one big call lets OpenBLAS
wake its worker threads, which stalls for milliseconds on a busy machine with few cores. Blocks
of BLOCK_PIXELS rows stay in cache and run on the calling thread."""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError

BLOCK_PIXELS = 16384


def pixels_matmul(pixels: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """(N×K) float32 pixels @ (K×M) matrix → (N×M) float32."""
    flat = np.ascontiguousarray(pixels, dtype=np.float32)
    m = np.ascontiguousarray(matrix, dtype=np.float32)
    if flat.ndim != 2 or m.ndim != 2 or flat.shape[1] != m.shape[0]:
        raise InvalidValueError(f"pixels_matmul: shapes {flat.shape} and {m.shape} do not chain")
    out = np.empty((flat.shape[0], m.shape[1]), dtype=np.float32)
    for start in range(0, flat.shape[0], BLOCK_PIXELS):
        np.matmul(flat[start:start + BLOCK_PIXELS], m, out=out[start:start + BLOCK_PIXELS])
    return out


def pixels_sum(pixels: np.ndarray) -> np.ndarray:
    """Column sums (K,) float64 of (N×K) pixels; float32 products per block, float64 across blocks."""
    flat = np.ascontiguousarray(pixels, dtype=np.float32)
    ones = np.ones(min(BLOCK_PIXELS, flat.shape[0]), dtype=np.float32)
    total = np.zeros(flat.shape[1], dtype=np.float64)
    for start in range(0, flat.shape[0], BLOCK_PIXELS):
        block = flat[start:start + BLOCK_PIXELS]
        total += ones[:block.shape[0]] @ block
    return total
