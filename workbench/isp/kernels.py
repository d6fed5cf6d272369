"""Compiled per-pixel ISP kernels (numba): the colour products, neutral highlights and the sRGB
curve, each pixel read once.

In numpy each of these is a pass over the whole frame with temporaries; the sRGB curve's power
alone cost ~13 ms of a 640×480 frame. Here the power x^(1/2.4) is split by the float's own
exponent, x = 2^−n·m with m ∈ [1, 2): m^(1/2.4) is a degree-8 polynomial (Chebyshev
interpolant, within 5e-9) and 2^(−n/2.4) a product of four constants chosen by the bits of n,
so the curve is within 4e-8 of the exact one (float32 rounding is 6e-8) with no table and no
branch: the compiler vectorises it (1.6 ms for 921,600 values on one thread, against 3.0 ms for
the table in √x it replaces, whose reads cannot be vectorised). Below the knee the linear
segment 12.92·x is computed exactly.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from numba import njit

SRGB_KNEE = 0.0031308
SRGB_POWER_DEGREE = 8
ENCODE_CHUNK = 2048       # pixels whose colour products are made before they are encoded (in cache)
_CACHE = not getattr(sys, "frozen", False)     # a frozen app has no source beside which to cache
_CONTRACT = {"contract"}  # fused multiply-adds where the CPU has them (no other fast-math liberty)


def _power_polynomial() -> tuple[float, ...]:
    """m^(1/2.4) for m ∈ [1, 2) as a polynomial in t = 2m − 3 ∈ [−1, 1), highest power first."""
    cheb = np.polynomial.chebyshev.chebinterpolate(lambda t: ((t + 3.0) / 2.0) ** (1.0 / 2.4), SRGB_POWER_DEGREE)
    return tuple(float(c) for c in np.polynomial.chebyshev.cheb2poly(cheb)[::-1])


_P8, _P7, _P6, _P5, _P4, _P3, _P2, _P1, _P0 = _power_polynomial()
_OCTAVE_1, _OCTAVE_2, _OCTAVE_4, _OCTAVE_8 = (2.0 ** (-n / 2.4) for n in (1, 2, 4, 8))
"""2^(−n/2.4) for the bits of n: the curve at x ∈ [2^−15, 1) (the knee is 2^−8.3)."""


@njit(cache=_CACHE, nogil=True, fastmath=_CONTRACT, inline="always")
def _encode(v, bits):
    """One float32 value v (its IEEE bits: bits) through the sRGB curve, clipped to [0, 1]; NaN
    stays NaN. Both segments are computed and one is selected, so a loop of these vectorises."""
    n = np.int32(127) - (bits >> np.int32(23))                 # x = 2^−n·m; garbage where unused
    t = np.float64(bits & np.int32(0x7FFFFF)) * (2.0 / 8388608.0) - 1.0
    power = (((((((_P8 * t + _P7) * t + _P6) * t + _P5) * t + _P4) * t + _P3) * t + _P2) * t + _P1) * t + _P0
    octave = ((_OCTAVE_1 if n & 1 else 1.0) * (_OCTAVE_2 if n & 2 else 1.0)) * (
        (_OCTAVE_4 if n & 4 else 1.0) * (_OCTAVE_8 if n & 8 else 1.0))
    y = np.float32(1.055 * power * octave - 0.055)
    y = y if v > np.float32(SRGB_KNEE) else np.float32(12.92) * max(np.float32(0.0), v)
    y = y if v < np.float32(1.0) else np.float32(1.0)
    return v if v != v else y


@njit(cache=_CACHE, nogil=True, fastmath=_CONTRACT)
def _encode_in_place(values):
    """values[i] = sRGB(values[i]) for a flat contiguous float32 array."""
    bits = values.view(np.int32)
    for i in range(values.shape[0]):
        values[i] = _encode(values[i], bits[i])


@njit(cache=_CACHE, nogil=True, fastmath=_CONTRACT)
def srgb_encode_flat(x, scale, out):
    """out[i] = sRGB(scale · x[i]) for flat contiguous float32 arrays."""
    for i in range(x.shape[0]):
        out[i] = x[i] * scale
    _encode_in_place(out)


@njit(cache=_CACHE, nogil=True, fastmath=_CONTRACT, inline="always")
def _neutral_blend(r, g, b, peak, start, span):
    """(r, g, b) blended towards max(r, g, b) by the smoothstep of (peak − start)·span in [0, 1]."""
    t = min(max(np.float32(0.0), (peak - start) * span), np.float32(1.0))   # max(0, NaN) is 0 in numba
    w = t * t * (np.float32(3.0) - np.float32(2.0) * t)
    grey = max(r, max(g, b))
    return r + w * (grey - r), g + w * (grey - g), b + w * (grey - b)


@njit(cache=_CACHE, nogil=True, fastmath=_CONTRACT)
def colour_pixels(linear, to_rgb, highlights, highlight_start, saturated, encode, rgb):
    """Per pixel of linear (N×K, float32): rgb = linear·to_rgb (K×3); with highlights, rgb blends
    towards the neutral of its brightest component by the smoothstep of the brightest sensor
    channel between highlight_start and saturated; with encode, rgb holds the sRGB-encoded values.
    float32 arithmetic without branches, so pixels pipeline (relative error ~1e-7 against
    float64); three channels, the common case, unrolled. Returns max(rgb) before encoding."""
    k_channels = linear.shape[1]
    m = to_rgb.astype(np.float32)
    zero = np.float32(0.0)
    start = np.float32(highlight_start)
    span = np.float32(1.0 / (saturated - highlight_start)) if highlights else zero   # 0: no blend
    peak_out = np.float32(-np.inf)
    for first in range(0, linear.shape[0], ENCODE_CHUNK):
        stop = min(first + ENCODE_CHUNK, linear.shape[0])
        for i in range(first, stop):
            if k_channels == 3:
                c0 = linear[i, 0]
                c1 = linear[i, 1]
                c2 = linear[i, 2]
                r = c0 * m[0, 0] + c1 * m[1, 0] + c2 * m[2, 0]
                g = c0 * m[0, 1] + c1 * m[1, 1] + c2 * m[2, 1]
                b = c0 * m[0, 2] + c1 * m[1, 2] + c2 * m[2, 2]
                peak = max(c0, max(c1, c2))
            else:
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
            r, g, b = _neutral_blend(r, g, b, peak, start, span)
            peak_out = max(peak_out, max(r, max(g, b)))
            rgb[i, 0] = r
            rgb[i, 1] = g
            rgb[i, 2] = b
        if encode:               # a loop of its own over pixels still in cache
            _encode_in_place(rgb[first:stop].reshape(-1))
    return peak_out


@njit(cache=_CACHE, nogil=True)
def normalise_raw(dn, inv_max_dn, raw):
    """raw = clip(dn · inv_max_dn, 0, 1) (H×W, into float32) in one pass; returns how many dn
    were NaN or infinite (the ISP refuses such an image)."""
    zero = np.float32(0.0)
    one = np.float32(1.0)
    non_finite = 0
    for y in range(dn.shape[0]):
        source = dn[y]
        out = raw[y]
        for x in range(dn.shape[1]):
            v = source[x]
            if not abs(v) < np.inf:
                non_finite += 1
            out[x] = min(max(np.float32(v * inv_max_dn), zero), one)
    return non_finite


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
    vertical pair at 2; the last two only with `far`) for the pixel's phase
    p = 2·(y mod 2) + (x mod 2) (demosaic.py builds coef). Beyond the border the mosaic is
    mirrored without repeating the edge (index −1 → 1), which keeps the CFA phase.

    A row's group sums are made first, one contiguous array each, and the coefficients are laid
    out along x for both row phases, so the weighted sum is the same arithmetic at every pixel: a
    loop the compiler vectorises, written out for three channels, a channel at a time for other
    counts. On a 640×480 frame, one thread, against the pixel-by-pixel loop it replaces: Bayer
    bilinear 1.6–1.7 → 0.45 ms, Malvar 2.3–2.4 → 0.7 ms, four channels 2.0 → 1.1 ms. The sums
    and products are added in the same order as pixel by pixel, so the result is the same to
    the bit."""
    h, w = mosaic.shape
    k_channels = out.shape[2]
    groups = 6 if far else 4
    along_x = np.empty((2, k_channels, groups, w), dtype=np.float32)   # coef by row phase, along x
    for py in range(2):
        for k in range(k_channels):
            for j in range(groups):
                for x in range(w):
                    along_x[py, k, j, x] = coef[2 * py + (x & 1), k, j]
    sums = np.zeros((6, w), dtype=np.float32)
    channel = np.empty(w, dtype=np.float32)
    for y in range(first_row, stop_row):
        _group_sums(mosaic, y, far, sums)
        c = along_x[y & 1]
        o = out[y]
        if k_channels == 3:
            _weigh_three(c, sums, far, o)
            continue
        for k in range(k_channels):          # other channel counts: a channel at a time
            channel[:] = 0.0
            for j in range(groups):
                ckj = c[k, j]
                sj = sums[j]
                for x in range(w):
                    channel[x] += ckj[x] * sj[x]
            for x in range(w):
                o[x, k] = channel[x]


@njit(cache=_CACHE, nogil=True, inline="always")
def _group_sums(mosaic, y, far, sums):
    """Row y's neighbour-group sums (6 × W; the last two only with far), mirrored borders."""
    h, w = mosaic.shape
    up = mosaic[_mirror(y - 1, h)]
    row = mosaic[y]
    down = mosaic[_mirror(y + 1, h)]
    for x in range(w):
        sums[0, x] = row[x]
        sums[2, x] = up[x] + down[x]
    for x in range(1, w - 1):
        sums[1, x] = row[x - 1] + row[x + 1]
        sums[3, x] = (up[x - 1] + up[x + 1]) + (down[x - 1] + down[x + 1])
    for x in (0, w - 1):
        xl = _mirror(x - 1, w)
        xr = _mirror(x + 1, w)
        sums[1, x] = row[xl] + row[xr]
        sums[3, x] = (up[xl] + up[xr]) + (down[xl] + down[xr])
    if far:
        up2 = mosaic[_mirror(y - 2, h)]
        down2 = mosaic[_mirror(y + 2, h)]
        for x in range(w):
            sums[5, x] = up2[x] + down2[x]
        for x in range(2, w - 2):
            sums[4, x] = row[x - 2] + row[x + 2]
        for x in (0, 1, w - 2, w - 1):
            sums[4, x] = row[_mirror(x - 2, w)] + row[_mirror(x + 2, w)]


@njit(cache=_CACHE, nogil=True, inline="always")
def _weigh_three(c, sums, far, o):
    """o[x, k] = Σ_j c[k, j, x] · sums[j, x] for three channels (j < 4, or 6 with far), added
    from j = 0 up as the general loop does."""
    zero = np.float32(0.0)
    c0, c1, c2 = c[0], c[1], c[2]
    s0, s1, s2, s3, s4, s5 = sums[0], sums[1], sums[2], sums[3], sums[4], sums[5]
    if far:
        for x in range(o.shape[0]):
            a0, a1, a2, a3, a4, a5 = s0[x], s1[x], s2[x], s3[x], s4[x], s5[x]
            o[x, 0] = zero + c0[0, x] * a0 + c0[1, x] * a1 + c0[2, x] * a2 + c0[3, x] * a3 + c0[4, x] * a4 + c0[5, x] * a5
            o[x, 1] = zero + c1[0, x] * a0 + c1[1, x] * a1 + c1[2, x] * a2 + c1[3, x] * a3 + c1[4, x] * a4 + c1[5, x] * a5
            o[x, 2] = zero + c2[0, x] * a0 + c2[1, x] * a1 + c2[2, x] * a2 + c2[3, x] * a3 + c2[4, x] * a4 + c2[5, x] * a5
    else:
        for x in range(o.shape[0]):
            a0, a1, a2, a3 = s0[x], s1[x], s2[x], s3[x]
            o[x, 0] = zero + c0[0, x] * a0 + c0[1, x] * a1 + c0[2, x] * a2 + c0[3, x] * a3
            o[x, 1] = zero + c1[0, x] * a0 + c1[1, x] * a1 + c1[2, x] * a2 + c1[3, x] * a3
            o[x, 2] = zero + c2[0, x] * a0 + c2[1, x] * a1 + c2[2, x] * a2 + c2[3, x] * a3


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


@njit(cache=_CACHE, nogil=True)
def grey_pixel_sums(ics, lit, gains, target, tolerance):
    """The sums (3,) of the rows of ics (N×3) that are `lit` and nearly grey once corrected: the
    r, g, b chromaticity of ics·gains within `tolerance` of `target` in every component; and how
    many rows those are (a round of the gray-pixels statistic)."""
    sums = np.zeros(3)
    count = 0
    for i in range(ics.shape[0]):
        if not lit[i]:
            continue
        r = ics[i, 0] * gains[0]
        g = ics[i, 1] * gains[1]
        b = ics[i, 2] * gains[2]
        total = r + g + b
        scale = 1.0 / total if total > 0.0 else 1.0
        distance = max(abs(r * scale - target[0]), max(abs(g * scale - target[1]), abs(b * scale - target[2])))
        if distance < tolerance:
            count += 1
            for c in range(3):
                sums[c] += ics[i, c]
    return sums, count


@njit(cache=_CACHE, nogil=True)
def sample_ics(flat, first, stop, step, saturated, to_ics):
    """ics = pixel·to_ics (K×3, float64) of the pixels first…stop − 1 of flat (N×K) whose index is
    a multiple of step and whose every channel is below saturated; returns (ics M×3, their sum
    (3,)). A row block's share of the gray-pixels sample."""
    start = (first + step - 1) // step * step
    out = np.empty((max(0, (stop - start + step - 1) // step), 3))
    sums = np.zeros(3)
    m = 0
    for i in range(start, stop, step):
        if _below(flat, i, saturated):
            for c in range(3):
                out[m, c] = _ics(flat, i, to_ics, c)
                sums[c] += out[m, c]
            m += 1
    return out[:m], sums
