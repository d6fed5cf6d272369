"""Irradiance → mean photo-electron rate per pixel (ISETCam's signalCurrent + regridOI2ISA).

mean e⁻/s of a pixel = A_pixel · fill factor · Σ_λ E(λ) · QE_k(λ) · Δλ, with E the irradiance
(photons/s/m²/nm) averaged over the pixel's aperture and QE_k the effective QE of the pixel's CFA
channel. The aperture (SensorParams.pixel_aperture) is the full pitch with a microlens: the optical
image's samples, each already the average over its own cell, are averaged over the pixel
(regrid_method), or taken as they are on the pixel grid. A bare photodiode integrates over a centred
square of √FF × pitch instead: see _photodiode_signal_rate.
The optical image and the pixel array are both centred on the optical axis; pixels beyond
the optical image receive no light.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from workbench.compute.pixel_threads import map_row_blocks
from workbench.errors import InvalidValueError
from workbench.optics.types import OpticalImage
from workbench.registry import Registry
from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM, cfa_layout, channel_qe
from workbench.sensor.kernels import project_by_tile
from workbench.sensor.params import PixelResponseParams
from workbench.units import band_widths_nm

REGRID_METHODS: Registry = Registry("sensor.regrid_method", "regrid method")
"""How the optical image is resampled onto the pixels: name → fn(n_src, src_spacing, n_dst,
dst_spacing) -> sparse (n_dst × n_src) 1-D resampling matrix between centred grids."""


def _edges(n: int, spacing: float) -> np.ndarray:
    return (np.arange(n + 1) - n / 2.0) * spacing


@REGRID_METHODS.register("area")
def _area_matrix(n_src: int, s: float, n_dst: int, p: float) -> sp.csr_array:
    """Each pixel averages the (piecewise-constant) irradiance over its square: flux conserving
    for any ratio of sample spacing to pixel pitch."""
    src_edges = _edges(n_src, s)
    lo = _edges(n_dst, p)[:-1]
    hi = lo + p
    j0 = np.clip(np.floor(lo / s + n_src / 2.0).astype(np.int64), 0, n_src - 1)
    span = int(min(np.ceil(p / s) + 2, n_src + 1))     # a pixel can overlap no more than every sample
    rows, cols, vals = [], [], []
    for k in range(span):
        j = j0 + k
        ok = j < n_src
        jj = np.minimum(j, n_src - 1)
        overlap = np.minimum(hi, src_edges[jj + 1]) - np.maximum(lo, src_edges[jj])
        ok &= overlap > 0
        rows.append(np.nonzero(ok)[0])
        cols.append(j[ok])
        vals.append(overlap[ok] / p)
    return sp.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(n_dst, n_src))


@REGRID_METHODS.register("isetcam")
def _isetcam_matrix(n_src: int, s: float, n_dst: int, p: float) -> sp.csr_array:
    """ISETCam's regridOI2ISA: Gaussian pre-blur (kernel ceil(pitch/spacing) samples, σ = kernel/4),
    then bilinear interpolation at the pixel centres."""
    kernel = int(min(np.ceil(p / s - 1e-9), 4 * n_src + 1))   # wider is flat over the whole image
    if kernel > 1:
        half = kernel // 2
        offsets = np.arange(-half, half + 1)
        g = np.exp(-0.5 * (offsets / (kernel / 4.0)) ** 2)
        j = np.arange(n_src)[:, None] + offsets[None, :]
        ok = (j >= 0) & (j < n_src)
        w = np.where(ok, g[None, :], 0.0)
        w /= w.sum(axis=1, keepdims=True)
        blur = sp.csr_array((w[ok], (np.nonzero(ok)[0], j[ok])), shape=(n_src, n_src))
    else:
        blur = sp.eye_array(n_src, format="csr")
    centres = (np.arange(n_dst) - (n_dst - 1) / 2.0) * p
    u = centres / s + (n_src - 1) / 2.0
    inside = (u >= -0.5) & (u <= n_src - 0.5)
    u = np.clip(u, 0.0, n_src - 1.0)
    i0 = np.minimum(np.floor(u).astype(np.int64), max(n_src - 2, 0))
    f = u - i0
    i1 = np.minimum(i0 + 1, n_src - 1)
    r = np.nonzero(inside)[0]
    interp = sp.csr_array((np.concatenate([1 - f[r], f[r]]), (np.concatenate([r, r]),
                           np.concatenate([i0[r], i1[r]]))), shape=(n_dst, n_src))
    return (interp @ blur).tocsr()


@lru_cache(maxsize=16)
def resample_matrix(n_src: int, src_spacing_m: float, n_dst: int, dst_spacing_m: float,
                    method: str = "area") -> sp.csr_array:
    """Sparse (n_dst × n_src) 1-D resampling from a centred grid of samples to centred pixels."""
    m = REGRID_METHODS[method](n_src, src_spacing_m, n_dst, dst_spacing_m).astype(np.float32)
    m.sum_duplicates()
    return m


@lru_cache(maxsize=32)
def _weights_cached(params: PixelResponseParams, wl_key: tuple[float, ...]) -> np.ndarray:
    wl = np.asarray(wl_key)
    w = channel_qe(params, wl) * band_widths_nm(wl)[:, None] * params.pixel_area_m2 * params.fill_factor
    w = w.astype(np.float32)
    w.flags.writeable = False
    return w


def channel_weights(params: PixelResponseParams, wavelengths_nm: np.ndarray) -> np.ndarray:
    """(Nλ, K) float32 weights A·FF·QE_k·Δλ (m²·nm): irradiance @ weights = e⁻/s per channel."""
    return _weights_cached(params.pixel_response,
                           tuple(np.asarray(wavelengths_nm, dtype=np.float64).ravel().tolist()))


def colour_wavelengths_nm(oi: OpticalImage) -> np.ndarray:
    """Wavelengths (nm) at which a SensorImage records its channels' QE for the ISP's colour fit.

    A spectral optical image's own wavelengths; for a render in the sensor's own channels (render
    representation 'sensor', whose bands are channels, not wavelengths) the grid the film was
    made on, SENSOR_SPECTRAL_GRID_NM — otherwise the fit would see three wavelengths and fail."""
    if oi.meta.get("representation") == "sensor":
        return SENSOR_SPECTRAL_GRID_NM
    return np.asarray(oi.wavelengths_nm, dtype=np.float64)


def film_channel_weights(oi: OpticalImage, params: PixelResponseParams) -> np.ndarray:
    """(K, K) weights for an optical image rendered with the sensor's own channels as the film
    (render representation 'sensor'): band k holds the QE_k-weighted mean irradiance, so pixel
    channel k collects A·FF·band_k·∫QE_k dλ."""
    _, names = cfa_layout(params.cfa_pattern)
    integrals = np.asarray(oi.meta.get("channel_integrals_nm", []), dtype=np.float64)
    if integrals.size != len(names) or oi.irradiance_photons.shape[2] != len(names):
        raise InvalidValueError(f"sensor: the optical image was rendered with {integrals.size} sensor channels "
                         f"{oi.meta.get('channel_names')}, this sensor has {len(names)} ({names}); "
                         "render it again with this sensor or use the 'bands' representation")
    return np.diag(params.pixel_area_m2 * params.fill_factor * integrals).astype(np.float32)


_NON_FINITE = ("sensor: the optical image holds NaN/Inf or irradiance too large for float32 "
               "(photons/s/m²/nm); fix the optics stage output")


def _project_by_tile(irr: np.ndarray, weights: np.ndarray, tile: np.ndarray, r0: int, c0: int,
                     rows: int, cols: int) -> np.ndarray:
    """Mean electron rate (e⁻/s) per pixel of the rows×cols window at (r0, c0) of the irradiance:
    Σ_λ E·w[:, channel], clipped at 0 (one compiled pass per row block)."""
    irr = np.ascontiguousarray(irr)
    weights = np.ascontiguousarray(weights, dtype=np.float32)
    tile = np.ascontiguousarray(tile, dtype=np.int64)
    rate = np.empty((rows, cols), dtype=np.float32)
    non_finite = map_row_blocks(lambda _, block: project_by_tile(irr, weights, tile, r0, c0, block.start,
                                                                 block.stop, rate), rows, rows * cols)
    if sum(non_finite):
        raise InvalidValueError(_NON_FINITE)
    return rate


def _photodiode_signal_rate(irr: np.ndarray, spacing_m: float, weights: np.ndarray,
                            params: PixelResponseParams) -> np.ndarray:
    """Mean e⁻/s of pixels that integrate over a centred photodiode square of side a = √FF × pitch.

    The optical image's samples are averages over their cells of side s (charts by exact coverage,
    renders by supersampling), transfer function sinc(s·f) per axis. Each channel's irradiance is
    filtered by sinc(a·f)/sinc(s·f) per axis (finite up to the samples' Nyquist 1/2s; above 1 when
    a < s, e.g. at one sample per pixel), which swaps the cell's box for the photodiode's, then read
    at the pixel centres (shifted by half a sample by the filter's phase when an even number of
    samples spans a pixel). The pixel pitch must be a whole number of samples (scene oversample);
    regrid_method is not used."""
    from workbench.optics.formation.fourier import apply_otf
    pitch_m = params.pixel_pitch_um * 1e-6
    k = pitch_m / spacing_m
    if abs(k - round(k)) > 1e-6 * k or round(k) < 1:
        raise InvalidValueError(f"sensor: pixel_aperture 'photodiode' needs the optical image sampled at the pixel "
                                f"pitch divided by a whole number (scene oversample), got {k:.4g} samples per pixel; "
                                "choose pixel_aperture 'microlens' or a whole scene oversample")
    k = int(round(k))
    h, w = irr.shape[:2]
    rows, cols = params.rows, params.cols
    # a pixel centre's position in samples of the centred optical image; half-integer when k is even
    u_r = k * (np.arange(rows) - (rows - 1) / 2.0) + (h - 1) / 2.0
    u_c = k * (np.arange(cols) - (cols - 1) / 2.0) + (w - 1) / 2.0
    shift = (k - 1) / 2.0 % 1.0
    a_m = params.aperture_width_px * pitch_m

    def transfer(_, fy, fx):
        box = (np.sinc(a_m * fy) / np.sinc(spacing_m * fy)) * (np.sinc(a_m * fx) / np.sinc(spacing_m * fx))
        return box * np.exp(2j * np.pi * shift * spacing_m * (fy + fx)) if shift else box
    planes, _ = apply_otf((irr.reshape(-1, irr.shape[2]) @ weights).reshape(h, w, -1), spacing_m, transfer,
                          pad=k + 2)
    tile, _ = cfa_layout(params.cfa_pattern)
    th, tw = tile.shape
    r_idx, c_idx = np.floor(u_r - shift + 0.5).astype(np.int64), np.floor(u_c - shift + 0.5).astype(np.int64)
    inside_r, inside_c = (r_idx >= 0) & (r_idx < h), (c_idx >= 0) & (c_idx < w)
    rate = np.zeros((rows, cols), dtype=np.float32)
    for i in range(th):
        for j in range(tw):
            rr, cc = np.arange(i, rows, th), np.arange(j, cols, tw)
            rr, cc = rr[inside_r[rr]], cc[inside_c[cc]]
            rate[np.ix_(rr, cc)] = planes[np.ix_(r_idx[rr], c_idx[cc])][..., tile[i, j]]
    if not np.isfinite(rate).all():
        raise InvalidValueError(_NON_FINITE)
    return rate


def irradiance_to_signal_rate(oi: OpticalImage, params: PixelResponseParams, method: str | None = None) -> np.ndarray:
    """Mean photo-electron rate (e⁻/s) of every pixel, rows×cols float32, before any noise.

    Fast path when the optical image is already on the pixel grid (same spacing; same size, or
    larger by an even number of samples so that it crops centred); otherwise the irradiance,
    projected on each channel's QE, is resampled by `method` (REGRID_METHODS; default
    params.regrid_method)."""
    method = method or params.regrid_method
    irr = oi.irradiance_photons
    if irr.ndim != 3 or irr.shape[2] != np.asarray(oi.wavelengths_nm).size:
        raise InvalidValueError(f"sensor: optical image irradiance must be H×W×Nλ with Nλ = "
                         f"{np.asarray(oi.wavelengths_nm).size} wavelengths, got shape {irr.shape}")
    if not (oi.sample_spacing_m > 0 and np.isfinite(oi.sample_spacing_m)):
        raise InvalidValueError(f"sensor: optical image sample_spacing_m must be > 0, got {oi.sample_spacing_m}")
    if irr.dtype != np.float32:
        irr = irr.astype(np.float32)
    weights = (film_channel_weights(oi, params) if oi.meta.get("representation") == "sensor"
               else channel_weights(params, oi.wavelengths_nm))
    if params.pixel_aperture == "photodiode" and params.fill_factor < 1.0:
        return _photodiode_signal_rate(irr, oi.sample_spacing_m, weights, params)
    tile, _ = cfa_layout(params.cfa_pattern)
    rows, cols = params.rows, params.cols
    pitch_m = params.pixel_pitch_um * 1e-6
    h, w = irr.shape[:2]
    same_grid = abs(oi.sample_spacing_m - pitch_m) <= 1e-6 * pitch_m
    if same_grid and h >= rows and w >= cols and (h - rows) % 2 == 0 and (w - cols) % 2 == 0:
        return _project_by_tile(irr, weights, tile, (h - rows) // 2, (w - cols) // 2, rows, cols)
    planes = irr.reshape(-1, irr.shape[2]) @ weights           # (h·w, K) e⁻/s on the OI grid
    r_m = resample_matrix(h, oi.sample_spacing_m, rows, pitch_m, method)
    c_m = resample_matrix(w, oi.sample_spacing_m, cols, pitch_m, method)
    rate = np.empty((rows, cols), dtype=np.float32)
    th, tw = tile.shape
    for k in range(weights.shape[1]):
        plane = planes[:, k].reshape(h, w)
        resampled = (c_m @ (r_m @ plane).T).T
        mask = tile == k
        for i in range(th):
            for j in range(tw):
                if mask[i, j]:
                    rate[i::th, j::tw] = resampled[i::th, j::tw]
    if not np.isfinite(rate).all():
        raise InvalidValueError(_NON_FINITE)
    np.maximum(rate, 0.0, out=rate)                                 # tiny negatives from FFT optics
    return rate
