"""Spatial frequency response by the slanted-edge method (ISO 12233:2017 e-SFR).

    sfr = edge_sfr(image)                      # a region holding one near-vertical edge
    sfr.frequency_cy_px, sfr.mtf, sfr.mtf50_cy_px, sfr.mtf_at(0.5)

The steps (ISO 12233 §6 and its reference code, sfrmat): the edge position in every row is the
centroid of the row's derivative (Hamming-windowed about a first guess); a straight line is fitted
to the positions; every pixel's signed horizontal distance to that line puts it into one of 4 bins
per pixel, whose means form the supersampled edge-spread function (bins are cos θ apart normal
to the edge, so frequencies are across the edge); its central difference is the
line-spread function, windowed by a Hamming window centred on its peak; |DFT| normalised to 1 at
zero frequency, divided by the central difference's own response sin(2πfΔ)/(2πfΔ), is the SFR.
Frequencies are in cycles per pixel of the image given (Nyquist 0.5).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError

OVERSAMPLE = 4
MIN_ROWS = 16


@dataclass(frozen=True)
class EdgeSFR:
    """An edge's SFR: frequency_cy_px and mtf (same length, mtf[0] = 1) and the edge's angle from
    vertical (degrees)."""

    frequency_cy_px: np.ndarray
    mtf: np.ndarray
    edge_angle_deg: float

    def mtf_at(self, frequency_cy_px: float) -> float:
        """MTF at a frequency (linear interpolation), e.g. Nyquist 0.5."""
        return float(np.interp(frequency_cy_px, self.frequency_cy_px, self.mtf))

    @property
    def mtf50_cy_px(self) -> float | None:
        """The lowest frequency where the MTF falls to 0.5 (None if it never does)."""
        below = np.flatnonzero(self.mtf < 0.5)
        if below.size == 0:
            return None
        k = int(below[0])
        f0, f1, m0, m1 = self.frequency_cy_px[k - 1], self.frequency_cy_px[k], self.mtf[k - 1], self.mtf[k]
        return float(f0 + (m0 - 0.5) * (f1 - f0) / (m0 - m1))


def _centroids(image: np.ndarray, window: np.ndarray | None) -> np.ndarray:
    """Per row, the centroid of the derivative along x (signed so the edge's step is positive:
    noise then averages out instead of pulling every centroid to the middle)."""
    d = np.diff(image, axis=1)
    if d.sum() < 0:
        d = -d
    if window is not None:
        d = d * window
    w = d.sum(axis=1)
    if np.any(w <= 0):
        raise InvalidValueError("edge SFR: a row of the region has no edge (a flat row): choose a region "
                                "that the edge crosses in every row")
    x = np.arange(d.shape[1]) + 0.5
    return (d * x).sum(axis=1) / w


def edge_sfr(image: np.ndarray, bins_per_px: int = OVERSAMPLE) -> EdgeSFR:
    """The e-SFR of a region holding one straight, near-vertical edge (module docstring).

    image: H×W (H ≥ 16) linear-light values; an edge leaning 1–20° from vertical crossing every row.
    A horizontal edge: pass image.T."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or img.shape[0] < MIN_ROWS or img.shape[1] < 8:
        raise InvalidValueError(f"edge SFR: the region must be H×W with H ≥ {MIN_ROWS}, W ≥ 8, got {img.shape}")
    if not np.all(np.isfinite(img)):
        raise InvalidValueError("edge SFR: the region holds NaN or Inf")
    h, w = img.shape
    rows = np.arange(h)
    first = _centroids(img, None)
    fit = np.polyfit(rows, first, 1)
    x = np.arange(w - 1) + 0.5
    centres = np.polyval(fit, rows)
    # Hamming window of the derivative about the first line, half-width = the region's half-width
    window = 0.54 + 0.46 * np.cos(np.clip((x[None, :] - centres[:, None]) / (w / 2), -1, 1) * np.pi)
    fit = np.polyfit(rows, _centroids(img, window), 1)
    slope = fit[0]                                          # px of x per row
    angle = float(np.degrees(np.arctan(slope)))
    if abs(angle) < 0.5 or abs(angle) > 30:
        raise InvalidValueError(f"edge SFR: the edge leans {angle:.2f}° from vertical; the method needs "
                                "about 1–20° (a slanted edge), not an aligned or diagonal one")
    # signed distance of each pixel centre to the line, in pixels along x
    xs = np.arange(w)[None, :] + 0.5 - (np.polyval(fit, rows)[:, None] + 0.5)
    bins = np.floor(xs * bins_per_px).astype(np.int64)
    lo = bins.min()
    idx = (bins - lo).ravel()
    counts = np.bincount(idx)
    sums = np.bincount(idx, weights=img.ravel())
    # keep the central span where every bin is populated (the edge is seen over all phases there)
    filled = counts > 0
    good = np.flatnonzero(filled)
    esf = np.interp(np.arange(counts.size), good, sums[good] / counts[good])
    margin = bins_per_px                                    # drop the ragged ends
    esf = esf[margin:-margin]
    lsf = np.zeros_like(esf)
    lsf[1:-1] = 0.5 * (esf[2:] - esf[:-2])
    lsf[0], lsf[-1] = lsf[1], lsf[-2]
    if np.sum(lsf) < 0:
        lsf = -lsf                                          # a falling edge
    peak = int(np.argmax(lsf))
    n = lsf.size
    half = max(peak, n - 1 - peak)
    k = np.arange(n)
    lsf = lsf * (0.54 + 0.46 * np.cos(np.pi * (k - peak) / max(half, 1)))
    spectrum = np.abs(np.fft.rfft(lsf))
    if spectrum[0] <= 0:
        raise InvalidValueError("edge SFR: the edge has no contrast")
    mtf = spectrum / spectrum[0]
    delta_px = math.cos(math.atan(slope)) / bins_per_px      # bin spacing normal to the edge (sfrmat3's delfac)
    freq = np.fft.rfftfreq(n, d=delta_px)                   # cycles per pixel
    arg = 2 * np.pi * freq * delta_px
    correction = np.where(arg > 0, np.sin(arg) / np.where(arg > 0, arg, 1.0), 1.0)
    keep = freq <= min(1.0, 0.5 * bins_per_px * 0.5)        # up to 1 cy/px (twice Nyquist)
    return EdgeSFR(freq[keep], (mtf / correction)[keep], angle)
