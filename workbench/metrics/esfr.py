"""Spatial frequency response by the slanted-edge method (ISO 12233:2017 e-SFR).

    sfr = edge_sfr(image)                      # a region holding one near-vertical edge
    sfr = edge_sfr(dn, mask=sites, flat=flat)  # one CFA channel's sites on the full grid, flat-fielded
    sfr.frequency_cy_px, sfr.mtf, sfr.mtf50_cy_px, sfr.mtf_at(0.5)
    mtf50_spread(dn, mask=sites, flat=flat)    # MTF50's standard deviation (bootstrap over the rows)

The steps (ISO 12233 §6 and its reference code, sfrmat): the region is divided by a flat-field image
of the same optics (when given) so lens fall-off cannot tilt the edge profile; the edge position in
every row is the centroid of the row's derivative (Hamming-windowed about a first guess); a straight
line is fitted to the positions; every site's signed horizontal distance to that line puts it into
one of 4 bins per pixel, whose means form the supersampled edge-spread function (bins are cos θ apart
normal to the edge, so frequencies are across the edge); its central difference is the line-spread
function, windowed by a Hamming window centred on its peak; |DFT| normalised to 1 at zero frequency,
divided by the central difference's own response sin(2πfΔ)/(2πfΔ), is the SFR. MTF50 is read from a
quadratic fitted to the curve about its first 0.5 crossing (measured_mtf50), not from the crossing
alone, which noise biases low. Frequencies are in
cycles per pixel of the grid the region is on (its Nyquist 0.5), also when `mask` keeps only some
sites (a CFA channel's: every site keeps its own position, so the channel is measured at full
resolution; its own Nyquist is lower, see cfa_plane_nyquist_cy_px).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError

OVERSAMPLE = 4
MIN_ROWS = 16
BOOTSTRAP_DRAWS = 40


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
        """Where the measured MTF falls to 0.5 (measured_mtf50; None if it never does)."""
        return measured_mtf50(self.frequency_cy_px, self.mtf)


def mtf50(frequency_cy_px: np.ndarray, mtf: np.ndarray) -> float | None:
    """The lowest frequency where a curve falls to 0.5, linearly interpolated (None if it never does)."""
    below = np.flatnonzero(np.asarray(mtf) < 0.5)
    if below.size == 0 or below[0] == 0:
        return None
    k = int(below[0])
    f0, f1, m0, m1 = frequency_cy_px[k - 1], frequency_cy_px[k], mtf[k - 1], mtf[k]
    return float(f0 + (m0 - 0.5) * (f1 - f0) / (m0 - m1))


MTF50_FIT_HALF_WIDTH = 0.25      # the quadratic's window: ±25 % of MTF50 (±0.075 cy/px at 0.3, some 40 samples)
MTF50_FIT_PASSES = 3


def measured_mtf50(frequency_cy_px: np.ndarray, mtf: np.ndarray) -> float | None:
    """MTF50 of a measured (noisy) e-SFR: where a quadratic least-squares fit to the curve within
    ±MTF50_FIT_HALF_WIDTH of the first 0.5 crossing reaches 0.5, the window re-centred on that
    (MTF50_FIT_PASSES passes); the first crossing where the fit finds none (None if the curve never
    falls to 0.5). The DFT samples the curve every 1/(ESF length) (0.004 cy/px for a 240-pixel
    region), finer than its noise is correlated, so noise makes it cross 0.5 several times and the
    first crossing alone picks the earliest dip: with the project's noise the raw planes' MTF50 read
    2.4–2.5 % low on average (R and B of slanted_edge_diffraction_f8's 2 µm f/4 variant, 60 draws),
    and the last crossing as much high. The fit is unbiased to first order (a linear function of
    the samples) and halves MTF50's scatter; on noise-free closed-form curves (Gaussian, Airy ×
    pixel) it is within 0.02 % of the exact crossing."""
    f, m = np.asarray(frequency_cy_px, np.float64), np.asarray(mtf, np.float64)
    first = mtf50(f, m)
    if first is None:
        return None
    x0 = first
    for _ in range(MTF50_FIT_PASSES):
        reach = MTF50_FIT_HALF_WIDTH * x0
        near = np.abs(f - x0) <= reach
        if near.sum() < 5:                                  # too few samples for a quadratic's 3 terms
            return first
        c2, c1, c0 = np.polyfit(f[near] - x0, m[near], 2)
        roots = np.roots([c2, c1, c0 - 0.5]) if c2 != 0 else np.array([(0.5 - c0) / c1])
        roots = roots[np.isreal(roots)].real
        roots = roots[np.abs(roots) <= reach]
        if roots.size == 0:                                 # noise swamps the curve here
            return first
        x0 = x0 + float(roots[np.argmin(np.abs(roots))])
    return float(x0)


def cfa_plane_nyquist_cy_px(tile: np.ndarray, channel: int) -> float:
    """Nyquist (cycles per pixel of the full grid, across a near-vertical edge) of one CFA channel's
    sites: 0.5 over the column period of the channel's sites (a Bayer R or B plane 0.25; G, whose
    rows alternate phase, 0.5; every pixel 0.5)."""
    tile = np.asarray(tile)
    phases = np.unique(np.nonzero(tile == channel)[1])
    return 0.5 * phases.size / tile.shape[1]


def _rows_of_sites(img: np.ndarray, mask: np.ndarray | None):
    """(row index, columns, values, valid) of the rows that hold sites: rows × (most sites in a row)
    arrays, a row with fewer sites (RCCC's C in its R rows) padded by repeating its last site
    (valid False there: no derivative, no ESF sample)."""
    if mask is None:
        h, w = img.shape
        return np.arange(h), np.broadcast_to(np.arange(w), (h, w)), img, np.ones((h, w), bool)
    mask = np.asarray(mask, bool)
    if mask.shape != img.shape:
        raise InvalidValueError(f"edge SFR: the site mask is {mask.shape}, the region {img.shape}")
    rows = np.flatnonzero(mask.any(axis=1))
    m = mask[rows]
    counts = m.sum(axis=1)
    n = int(counts.max()) if rows.size else 0
    order = np.argsort(~m, axis=1, kind="stable")[:, :n]          # each row's site columns first, in order
    valid = np.arange(n)[None, :] < counts[:, None]
    last = np.take_along_axis(order, (counts - 1)[:, None], axis=1)
    cols = np.where(valid, order, last)
    return rows, cols, np.take_along_axis(img[rows], cols, axis=1), valid


def _centroids(cols: np.ndarray, values: np.ndarray, centres: np.ndarray | None, half_width: float) -> np.ndarray:
    """Per row, the centroid of the derivative along x between neighbouring sites (signed so the
    edge's step is positive: noise then averages out instead of pulling every centroid to the
    middle), Hamming-windowed about `centres` when given."""
    d = np.diff(values, axis=1)
    if d.sum() < 0:
        d = -d
    x = 0.5 * (cols[:, 1:] + cols[:, :-1])
    if centres is not None:
        d = d * (0.54 + 0.46 * np.cos(np.clip((x - centres[:, None]) / half_width, -1, 1) * np.pi))
    w = d.sum(axis=1)
    if np.any(w <= 0):
        raise InvalidValueError("edge SFR: a row of the region has no edge (a flat row): choose a region "
                                "that the edge crosses in every row")
    return (d * x).sum(axis=1) / w


def _sfr(rows: np.ndarray, cols: np.ndarray, values: np.ndarray, valid: np.ndarray, width: int,
         bins_per_px: int) -> EdgeSFR:
    """e-SFR of the sites (rows[i], cols[i, j]) with values[i, j] where valid[i, j] (module docstring)."""
    half = width / 2
    fit = np.polyfit(rows, _centroids(cols, values, None, half), 1)
    fit = np.polyfit(rows, _centroids(cols, values, np.polyval(fit, rows), half), 1)
    slope = fit[0]                                          # px of x per row
    angle = float(np.degrees(np.arctan(slope)))
    if abs(angle) < 0.5 or abs(angle) > 30:
        raise InvalidValueError(f"edge SFR: the edge leans {angle:.2f}° from vertical; the method needs "
                                "about 1–20° (a slanted edge), not an aligned or diagonal one")
    xs = cols - np.polyval(fit, rows)[:, None]              # signed distance to the line along x (px)
    bins = np.floor(xs[valid] * bins_per_px).astype(np.int64)
    idx = bins - bins.min()
    counts = np.bincount(idx)
    sums = np.bincount(idx, weights=values[valid])
    good = np.flatnonzero(counts > 0)
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
    reach = max(peak, n - 1 - peak)
    k = np.arange(n)
    lsf = lsf * (0.54 + 0.46 * np.cos(np.pi * (k - peak) / max(reach, 1)))
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


def _prepared(image: np.ndarray, mask: np.ndarray | None, flat: np.ndarray | None):
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or img.shape[0] < MIN_ROWS or img.shape[1] < 8:
        raise InvalidValueError(f"edge SFR: the region must be H×W with H ≥ {MIN_ROWS}, W ≥ 8, got {img.shape}")
    if not np.all(np.isfinite(img)):
        raise InvalidValueError("edge SFR: the region holds NaN or Inf")
    if flat is not None:
        flat = np.asarray(flat, dtype=np.float64)
        if flat.shape != img.shape or not np.all(np.isfinite(flat)) or np.any(flat <= 0):
            raise InvalidValueError(f"edge SFR: the flat field must be positive and finite, of the region's "
                                    f"shape {img.shape}, got {flat.shape}")
        img = img / (flat / flat.mean())
    rows, cols, values, valid = _rows_of_sites(img, mask)
    if rows.size < MIN_ROWS or valid.sum(axis=1).min() < 4:
        raise InvalidValueError(f"edge SFR: the region keeps {rows.size} rows of {valid.sum(axis=1).min()} sites "
                                f"or more; it needs ≥ {MIN_ROWS} rows of ≥ 4")
    return rows, cols, values, valid, img.shape[1]


def edge_sfr(image: np.ndarray, bins_per_px: int = OVERSAMPLE, mask: np.ndarray | None = None,
             flat: np.ndarray | None = None) -> EdgeSFR:
    """The e-SFR of a region holding one straight, near-vertical edge (module docstring).

    image: H×W (H ≥ 16) linear-light values; an edge leaning 1–20° from vertical crossing every row.
    A horizontal edge: pass image.T. mask: H×W bool, the sites to use (one CFA channel's; None: all).
    flat: H×W, a flat-field image of the same optics and exposure (a uniform field's, black level
    removed) that the region is divided by; None: no flat-field correction."""
    return _sfr(*_prepared(image, mask, flat), bins_per_px)


def mtf50_spread(image: np.ndarray, mask: np.ndarray | None = None, flat: np.ndarray | None = None,
                 draws: int = BOOTSTRAP_DRAWS, seed: int = 0) -> float | None:
    """Standard deviation of MTF50 (cycles/pixel) over a bootstrap of the region's rows: `draws`
    resamplings of its rows with replacement, each measured as edge_sfr does (edge fit included).
    None when fewer than half the draws reach 0.5."""
    rows, cols, values, valid, width = _prepared(image, mask, flat)
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(draws):
        pick = np.sort(rng.integers(0, rows.size, rows.size))
        try:
            m = _sfr(rows[pick], cols[pick], values[pick], valid[pick], width, OVERSAMPLE).mtf50_cy_px
        except InvalidValueError:
            continue
        if m is not None:
            found.append(m)
    return float(np.std(found, ddof=1)) if len(found) >= max(2, draws // 2) else None
