"""Shift-invariant filtering of spectral images by an OTF, with edge-mirroring padding.

Padding: the image is extended by mirror reflection (numpy 'symmetric'). ISETCam pads with
1e-9·max instead, which darkens a band one PSF wide along every border (light that would come
from outside the field is missing) and, for an HDR frame, still lets bright borders wrap round
in the circular convolution. Mirroring keeps the local mean at the border and stops wrap-round,
so a uniform field stays exactly uniform. Only the light that crosses the border is approximate.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy import fft

from workbench.errors import InvalidValueError


def frequency_grid(shape: tuple[int, int], spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(fy, fx) in cycles/m for an rfft2 of an image of `shape` (rows, cols)."""
    fy = fft.fftfreq(shape[0], d=spacing_m)[:, None]
    fx = fft.rfftfreq(shape[1], d=spacing_m)[None, :]
    return fy, fx


MAX_BLUR_PLANE_SAMPLES = 2 ** 24   # refused above: a padded plane (or kernel grid) for a blur wider than the image


def blur_too_wide(psf_radius_samples: float, what: str, gib: float) -> InvalidValueError:
    """The error for an optical blur too wide to simulate: it names the settings that set it."""
    return InvalidValueError(
        f"optics: the blur is {psf_radius_samples:.3g} samples in radius, {what} (it would take {gib:.3g} GiB a "
        "band): the working f-number N·(1 + m) is very large, or the scene far out of focus. Put scene.distance_m "
        "farther from the focal length (a scene near the focal length has a huge magnification m), focus the lens on "
        "the scene (optics.focus_distance_m) or lower optics.f_number")


def pad_width(shape: tuple[int, int], psf_radius_samples: float) -> int:
    """Padding on each side: a PSF radius, at least 1/8 of the larger image side (ISETCam).
    InvalidValueError (blur_too_wide) for a PSF wider than the image whose padded plane would hold
    more than MAX_BLUR_PLANE_SAMPLES samples: no detail of the scene would survive it, and it would
    take gigabytes (a 24×32 image of a scene 0.1 mm beyond a 50 mm lens's focal length asked 12 GiB)."""
    pad = int(max(math.ceil(max(shape) / 8), math.ceil(psf_radius_samples), 1))
    padded = (shape[0] + 2 * pad) * (shape[1] + 2 * pad)
    if psf_radius_samples > max(shape) and padded > MAX_BLUR_PLANE_SAMPLES:
        raise blur_too_wide(psf_radius_samples, f"wider than the {shape[0]}×{shape[1]} image", padded * 8 / 2 ** 30)
    return pad


def kernel_otf(kernel: np.ndarray, padded_shape: tuple[int, int]) -> np.ndarray:
    """rfft2 of a small centred, odd-sized spatial kernel wrapped onto the padded grid."""
    kr, kc = kernel.shape
    if kr > padded_shape[0] or kc > padded_shape[1]:
        raise InvalidValueError(f"kernel {kernel.shape} is larger than the padded image {padded_shape}")
    grid = np.zeros(padded_shape)
    grid[:kr, :kc] = kernel
    grid = np.roll(grid, (-(kr // 2), -(kc // 2)), axis=(0, 1))
    return fft.rfft2(grid, workers=-1)


def apply_otf(image: np.ndarray, spacing_m: float, otf: Callable[[int, np.ndarray, np.ndarray], np.ndarray],
              pad: int, kernel: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Filter each channel c of an H×W×C image by otf(c, fy, fx) (cycles/m, rfft2 layout),
    times the transfer function of an optional small spatial kernel shared by all channels.

    Returns (filtered float64 image with negative ringing clipped to 0, fraction of samples
    that were clipped). The OTF must be 1 at zero frequency for the filter to conserve light."""
    rows, cols, nch = image.shape
    pad = max(pad, (0 if kernel is None else max(kernel.shape)) // 2 + 1)
    padded_shape = (fft.next_fast_len(rows + 2 * pad, real=True), fft.next_fast_len(cols + 2 * pad, real=True))
    extra_r, extra_c = padded_shape[0] - rows - 2 * pad, padded_shape[1] - cols - 2 * pad
    fy, fx = frequency_grid(padded_shape, spacing_m)
    shared = 1.0 if kernel is None else kernel_otf(kernel, padded_shape)
    out = np.empty(image.shape, dtype=np.float64)
    clipped = 0
    for c in range(nch):
        plane = np.pad(np.asarray(image[..., c], dtype=np.float64),
                       ((pad, pad + extra_r), (pad, pad + extra_c)), mode="symmetric")
        spec = fft.rfft2(plane, workers=-1) * (otf(c, fy, fx) * shared)
        filtered = fft.irfft2(spec, s=padded_shape, workers=-1)[pad:pad + rows, pad:pad + cols]
        neg = filtered < 0
        clipped += int(neg.sum())
        filtered[neg] = 0.0
        out[..., c] = filtered
    return out, clipped / max(out.size, 1)
