"""ISO 12233-style slanted-edge MTF: edge spread → line spread → MTF, and MTF50.

Steps (after ISO 12233 / sfrmat): per-row edge centroids from the row derivative, a straight
line fitted through them, every sample projected onto the edge normal, the projections
binned at 1/oversample sample into the edge-spread function (ESF), its central difference as
the line-spread function (LSF), an optional Hamming window, |FFT|, normalised at DC. The
MTF is divided by the responses of the binning (sinc fΔ) and of the central difference
(sin 2πfΔ / 2πfΔ), Δ = 1/oversample, so a perfect edge measures 1 up to Nyquist.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError


@dataclass
class EdgeMTF:
    """frequency_cyc_per_sample along the edge normal, mtf (1 at DC), mtf50 (cycles/sample),
    edge angle from the sample columns (degrees), and the ESF/LSF on the oversampled grid."""

    frequency_cyc_per_sample: np.ndarray
    mtf: np.ndarray
    mtf50_cyc_per_sample: float
    edge_angle_deg: float
    esf: np.ndarray
    lsf: np.ndarray

    def frequency_cyc_per_mm(self, spacing_m: float) -> np.ndarray:
        return self.frequency_cyc_per_sample / (spacing_m * 1e3)


def mtf50(frequency: np.ndarray, mtf: np.ndarray) -> float:
    """First frequency at which the MTF falls to 0.5 (linear interpolation); nan if it never does."""
    below = np.nonzero(mtf < 0.5)[0]
    if below.size == 0 or below[0] == 0:
        return float("nan")
    i = below[0]
    f0, f1, m0, m1 = frequency[i - 1], frequency[i], mtf[i - 1], mtf[i]
    return float(f0 + (m0 - 0.5) * (f1 - f0) / (m0 - m1))


def _edge_line(img: np.ndarray) -> tuple[float, float]:
    """Fit column = a + b·row through the per-row centroids of |d/dx|."""
    deriv = np.abs(np.diff(img, axis=1))
    weight = deriv.sum(axis=1)
    ok = weight > 1e-12 * max(float(weight.max()), 1e-300)
    if ok.sum() < 2:
        raise InvalidValueError("slanted-edge MTF: no edge found (the image is flat)")
    cols = np.arange(deriv.shape[1]) + 0.5
    centroid = (deriv[ok] * cols).sum(axis=1) / weight[ok]
    rows = np.nonzero(ok)[0].astype(np.float64)
    b, a = np.polyfit(rows, centroid, 1)
    return float(a), float(b)


def slanted_edge_mtf(image: np.ndarray, oversample: int = 4, window: bool = True) -> EdgeMTF:
    """MTF of a 2-D image (H×W, or H×W×C summed over C) containing one straight edge.

    The edge may be near-vertical or near-horizontal (then the image is transposed); it must
    be tilted by 1–30° from the sample grid so that the rows cover every sub-sample phase."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img.sum(axis=2)
    if img.ndim != 2 or min(img.shape) < 8:
        raise InvalidValueError(f"slanted-edge MTF needs a 2-D image of at least 8×8 samples, got {image.shape}")
    if not np.all(np.isfinite(img)):
        raise InvalidValueError("slanted-edge MTF: the image has NaN/Inf")
    if oversample < 1:
        raise InvalidValueError(f"oversample must be ≥ 1, got {oversample}")
    if np.abs(np.diff(img, axis=0)).sum() > np.abs(np.diff(img, axis=1)).sum():
        img = img.T
    a, b = _edge_line(img)
    angle = float(np.degrees(np.arctan(b)))
    if not 1.0 <= abs(angle) <= 30.0:
        raise InvalidValueError(f"slanted-edge MTF: the edge is {angle:.2f}° from the grid; 1–30° is needed")
    rows, cols = img.shape
    cos_t = np.cos(np.arctan(b))
    jj, ii = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows, dtype=np.float64))
    dist = (jj - (a + b * ii)) * cos_t                       # signed normal distance, samples
    # keep only the distances every row reaches, so the ESF ends are not one-sided
    half = min(dist[:, 0].max() * -1, dist[:, -1].min())
    keep = np.abs(dist) <= half
    idx = np.floor(dist[keep] * oversample).astype(np.int64)
    idx -= idx.min()
    counts = np.bincount(idx)
    sums = np.bincount(idx, weights=img[keep])
    have = counts > 0
    pos = np.arange(counts.size)
    esf = np.interp(pos, pos[have], sums[have] / counts[have])
    lsf = np.zeros_like(esf)
    lsf[1:-1] = (esf[2:] - esf[:-2]) / 2.0
    if window:
        centre = float((np.abs(lsf) * pos).sum() / max(np.abs(lsf).sum(), 1e-300))
        half_width = max(centre, lsf.size - 1 - centre)
        lsf = lsf * (0.54 + 0.46 * np.cos(np.pi * np.clip((pos - centre) / half_width, -1, 1)))
    spec = np.abs(np.fft.rfft(lsf))
    if spec[0] <= 0:
        raise InvalidValueError("slanted-edge MTF: the edge has no contrast")
    delta = 1.0 / oversample
    freq = np.fft.rfftfreq(lsf.size, d=delta)
    corr = np.sinc(freq * delta) * np.sinc(2 * freq * delta)
    mtf = spec / spec[0] / np.where(corr > 0.1, corr, 1.0)
    upto = freq <= 1.0
    return EdgeMTF(freq[upto], mtf[upto], mtf50(freq[upto], mtf[upto]), angle, esf, lsf)
