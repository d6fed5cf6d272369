"""8-bit display copies of images at fixed levels, made where the images are made (off a GUI thread).

A viewer maps a float image to 8 bits every time it draws a new one: pyqtgraph, for one, computes
(x − lo)·(255 / (hi − lo)) in float32, clips it to [0, 255] and truncates — ~2 ms a 640×480 pane on
the window's GUI thread. `display_u8` does the same arithmetic in one compiled pass, so the copy it
makes is the image the viewer would have drawn, pixel for pixel; NaN maps to 0.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
from numba import njit

_CACHE = not getattr(sys, "frozen", False)     # a frozen app has no source beside which to cache


@njit(cache=_CACHE, nogil=True)
def _to_u8(flat, lo, scale, out):
    for i in range(flat.size):
        v = (np.float32(flat[i]) - lo) * scale
        if not v > 0.0:                 # also NaN
            v = np.float32(0.0)
        elif v > 255.0:
            v = np.float32(255.0)
        out[i] = np.uint8(v)


def display_u8(image: np.ndarray, levels: tuple[float, float]) -> np.ndarray:
    """`image` (H×W or H×W×3, any real dtype) as uint8 of the same shape, `levels` = (lo, hi)
    mapped to 0 and 255 as pyqtgraph maps them (float32 arithmetic, clipped, truncated)."""
    lo, hi = float(levels[0]), float(levels[1])
    span = hi - lo if hi != lo else 1.0
    flat = np.ascontiguousarray(image).reshape(-1)
    if flat.dtype.kind not in "fiu":
        raise TypeError(f"display_u8 needs a real-valued image, not {flat.dtype}")
    out = np.empty(flat.size, np.uint8)
    _to_u8(flat, np.float32(lo), np.float32(255.0 / span), out)
    return out.reshape(image.shape)


@dataclass(frozen=True)
class Display8:
    """`u8`: `source` drawn at `levels` (display_u8); a viewer uses it only while it shows that
    very array at those levels."""

    source: np.ndarray
    levels: tuple[float, float]
    u8: np.ndarray

    @classmethod
    def of(cls, source: np.ndarray, levels: tuple[float, float]) -> Display8:
        levels = (float(levels[0]), float(levels[1]))
        return cls(source, levels, display_u8(source, levels))
