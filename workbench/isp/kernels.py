"""Compiled per-pixel ISP kernels (numba): the colour products, neutral highlights and the sRGB
curve, each pixel read once.

In numpy each of these is a pass over the whole frame with temporaries; the sRGB curve's power
alone cost ~13 ms of a 640×480 frame. Here the curve is a table in s = √x: y(s) = 1.055·s^(1/1.2) −
0.055 is smooth in s, so linear interpolation on 4,096 intervals is within 4e-8 of the exact
curve (float32 rounding is 6e-8); below the knee the linear segment 12.92·x is computed exactly.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from numba import njit

SRGB_KNEE = 0.0031308
SRGB_TABLE_INTERVALS = 4096
ENCODE_CHUNK = 2048       # pixels whose colour products are made before they are encoded (in cache)
_CACHE = not getattr(sys, "frozen", False)     # a frozen app has no source beside which to cache


def _srgb_table() -> np.ndarray:
    """The power segment of the sRGB curve (IEC 61966-2-1), 1.055·x^(1/2.4) − 0.055, at x = s²
    for s on a uniform grid of [0, 1], float32. It is read only above the knee; the node below the
    knee holds the power segment too (the two segments' slopes differ, 12.92 against 12.70, so a
    node from the linear one would bend the interval that holds the knee by ~9e-7)."""
    s = np.linspace(0.0, 1.0, SRGB_TABLE_INTERVALS + 1)
    y = (1.055 * np.power(s * s, 1.0 / 2.4) - 0.055).astype(np.float32)
    y[-1] = 1.0
    y.setflags(write=False)
    return y


SRGB_TABLE = _srgb_table()


@njit(cache=_CACHE, nogil=True, inline="always")
def _encode(value, table):
    """One value through the sRGB curve, clipped to [0, 1] first; NaN stays NaN. float32 arithmetic
    and selects instead of branches, so the compiler can pipeline (and vectorise) it: within 1e-7
    of the exact curve."""
    v = np.float32(value)
    c = min(max(np.float32(0.0), v), np.float32(1.0))   # numba's max(0, NaN) is 0: c indexes the table
    s = np.sqrt(c) * np.float32(SRGB_TABLE_INTERVALS)
    j = min(int(s), SRGB_TABLE_INTERVALS - 1)
    y = table[j] + (s - np.float32(j)) * (table[j + 1] - table[j])
    y = y if c > np.float32(SRGB_KNEE) else np.float32(12.92) * c
    return v if v != v else y


@njit(cache=_CACHE, nogil=True)
def srgb_encode_flat(x, scale, table, out):
    """out[i] = sRGB(scale · x[i]) for flat float32 arrays."""
    for i in range(x.shape[0]):
        out[i] = _encode(x[i] * scale, table)


@njit(cache=_CACHE, nogil=True)
def colour_pixels(linear, to_rgb, highlights, highlight_start, saturated, encode, table, rgb):
    """Per pixel of linear (N×K, float32): rgb = linear·to_rgb (K×3); with highlights, rgb blends
    towards the neutral of its brightest component by the smoothstep of the brightest sensor
    channel between highlight_start and saturated; with encode, rgb holds the sRGB-encoded values
    (the table of srgb_encode_flat). float32 arithmetic without branches, so pixels pipeline
    (relative error ~1e-7 against float64). Returns max(rgb) before encoding."""
    k_channels = linear.shape[1]
    m = to_rgb.astype(np.float32)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    start = np.float32(highlight_start)
    span = np.float32(1.0 / (saturated - highlight_start)) if highlights else zero   # 0: no blend
    peak_out = np.float32(-np.inf)
    for first in range(0, linear.shape[0], ENCODE_CHUNK):
        stop = min(first + ENCODE_CHUNK, linear.shape[0])
        for i in range(first, stop):
            r = zero
            g = zero
            b = zero
            peak = linear[i, 0]
            for k in range(k_channels):
                v = linear[i, k]
                r += v * m[k, 0]
                g += v * m[k, 1]
                b += v * m[k, 2]
                peak = max(peak, v)
            t = min(max(zero, (peak - start) * span), one)       # max(0, NaN) is 0 in numba
            w = t * t * (np.float32(3.0) - np.float32(2.0) * t)
            grey = max(r, max(g, b))
            r += w * (grey - r)
            g += w * (grey - g)
            b += w * (grey - b)
            peak_out = max(peak_out, max(r, max(g, b)))
            rgb[i, 0] = r
            rgb[i, 1] = g
            rgb[i, 2] = b
        if encode:               # a loop of its own over pixels still in cache
            chunk = rgb[first:stop].reshape(-1)
            for j in range(chunk.shape[0]):
                chunk[j] = _encode(chunk[j], table)
    return peak_out


@njit(cache=_CACHE, nogil=True, inline="always")
def _mirror(i, n):
    """Index i of an axis of length n, mirrored without repeating the edge (−1 → 1, n → n − 2)."""
    if i < 0:
        return -i
    if i >= n:
        return 2 * n - 2 - i
    return i


@njit(cache=_CACHE, nogil=True)
def demosaic_2x2(mosaic, coef, far, first_row, stop_row, out):
    """Rows first_row…stop_row − 1 of a linear demosaic of a 2×2 CFA tile (H×W float32 mosaic,
    H, W ≥ 2, or ≥ 3 with `far` → out H×W×K): bilinear and Malvar–He–Cutler (2004).

    Their filters weigh, around a pixel, the centre, the horizontal and vertical neighbours at
    distance 1 (and, for Malvar's 5×5 filters, at distance 2: `far`) and the four diagonal ones;
    on a 2×2 tile each of these groups shares one CFA phase, so every channel is
    coef[p, k] · (centre, horizontal pair, vertical pair, diagonals, horizontal pair at 2,
    vertical pair at 2; the last two only with `far`) for the pixel's phase p = 2·(y mod 2) + (x mod 2) (demosaic.py builds coef).
    Beyond the border the mosaic is mirrored without repeating the edge (index −1 → 1), which
    keeps the CFA phase."""
    h, w = mosaic.shape
    k_channels = out.shape[2]
    zero = np.float32(0.0)
    groups = 6 if far else 4
    for y in range(first_row, stop_row):
        up = mosaic[_mirror(y - 1, h)]
        row = mosaic[y]
        down = mosaic[_mirror(y + 1, h)]
        up2 = mosaic[_mirror(y - 2, h)] if far else row
        down2 = mosaic[_mirror(y + 2, h)] if far else row
        o = out[y]
        py = 2 * (y & 1)
        for x in range(w):
            xl = _mirror(x - 1, w)
            xr = _mirror(x + 1, w)
            across2 = row[_mirror(x - 2, w)] + row[_mirror(x + 2, w)] if far else zero
            along2 = up2[x] + down2[x] if far else zero
            sums = (row[x], row[xl] + row[xr], up[x] + down[x], (up[xl] + up[xr]) + (down[xl] + down[xr]),
                    across2, along2)
            p = py + (x & 1)
            for k in range(k_channels):
                acc = zero
                for j in range(groups):
                    acc += coef[p, k, j] * sums[j]
                o[x, k] = acc


@njit(cache=_CACHE, nogil=True, inline="always")
def _below(flat, i, limit):
    """Every channel of pixel i is below limit (a NaN channel is not)."""
    for k in range(flat.shape[1]):
        if not flat[i, k] < limit:
            return False
    return True


@njit(cache=_CACHE, nogil=True, inline="always")
def _ics(flat, i, to_ics, c):
    """Channel c of pixel i in the internal colour space (float64)."""
    acc = 0.0
    for k in range(flat.shape[1]):
        acc += np.float64(flat[i, k]) * to_ics[k, c]
    return acc


@njit(cache=_CACHE, nogil=True)
def ics_maxima(flat, to_ics, saturated, ics):
    """ics = pixel·to_ics (K×3, float64) for each pixel of flat (N×K) whose every sensor channel is
    below saturated, NaN for the others (out: ics, N×3 float64). Returns the largest value (3,) of
    each ics channel over those pixels (−inf when none) and how many they are."""
    t0 = t1 = t2 = -math.inf
    valid = 0
    for i in range(flat.shape[0]):
        if _below(flat, i, saturated):
            valid += 1
            a, b, c = _ics(flat, i, to_ics, 0), _ics(flat, i, to_ics, 1), _ics(flat, i, to_ics, 2)
            ics[i, 0] = a
            ics[i, 1] = b
            ics[i, 2] = c
            t0 = a if a > t0 else t0
            t1 = b if b > t1 else t1
            t2 = c if c > t2 else t2
        else:
            ics[i, 0] = ics[i, 1] = ics[i, 2] = np.nan
    top = np.array([t0, t1, t2])
    return top, valid


@njit(cache=_CACHE, nogil=True)
def bright_sums(ics, channel, threshold):
    """The sums (3,) of the rows of ics (N×3; NaN rows: left out) whose ics[channel] ≥ threshold,
    and how many rows those are: the white-world statistic's second pass."""
    sums = np.zeros(3)
    selected = 0
    for i in range(ics.shape[0]):
        if ics[i, channel] >= threshold:
            selected += 1
            for c in range(3):
                sums[c] += ics[i, c]
    return sums, selected
