"""Point-spread functions per field height, wavelength and object distance.

Both PSFs are size×size arrays on the sensor, centred on the chief ray's landing point
(distortion is left to `analysis.distortion`): element [i, j] is the fraction of the energy in the
pixel centred at x = (j − size//2)·spacing, y = (i − size//2)·spacing (µm, sensor axes, +y = the
direction the field rises). They sum to 1 over the grid (energy outside the grid is dropped).

- geometric: rays on a uniform pupil grid binned into pixels.
- diffraction: |FFT of the pupil function|², the pupil phase from the optical path difference of
  traced rays to the reference sphere centred on the chief-ray image point and passing through the
  paraxial exit pupil; pupil coordinates map to exit-ray direction cosines by a fitted affine map.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.fft

from workbench.errors import InvalidValueError
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_z_mm
from workbench.optics.lens.pupil import chief_ray_on_sensor, field_angle_for_height, make_bundle
from workbench.optics.lens.trace import to_plane, trace_rays

_MAX_FFT = 2048
_MAX_PUPIL = 512


def _check_grid(grid_spacing_um: float, size: int):
    if not (math.isfinite(grid_spacing_um) and grid_spacing_um > 0):
        raise InvalidValueError(f"grid_spacing_um={grid_spacing_um}: must be a finite number > 0")
    if not (isinstance(size, (int, np.integer)) and 3 <= size <= 4096):
        raise InvalidValueError(f"size={size}: must be an integer in [3, 4096]")


def _setup(lens, field_height_mm, wavelength_nm, object_distance_m):
    theta = field_angle_for_height(lens, field_height_mm, wavelength_nm, object_distance_m)
    b = make_bundle(lens, theta, object_distance_m, wavelength_nm)
    cx, cy = chief_ray_on_sensor(lens, theta, wavelength_nm, object_distance_m, bundle=b)
    return b, np.array([cx, cy, sensor_z_mm(lens)])


def _source_weights(bundle, d):
    """Relative flux per pupil-grid cell: uniform at infinity; cos³ solid-angle weight otherwise."""
    if math.isinf(bundle.object_distance_mm):
        return np.ones(d.shape[0])
    c = d @ bundle.d0
    return np.clip(c, 0.0, None) ** 3


def psf_geometric(lens: Lens, field_height_mm: float, wavelength_nm: float, object_distance_m: float,
                  grid_spacing_um: float, size: int, n_side: int = 256) -> np.ndarray:
    """Geometric PSF: n_side² rays over the pupil binned on a size×size grid (sums to 1)."""
    _check_grid(grid_spacing_um, size)
    b, q = _setup(lens, field_height_mm, wavelength_nm, object_distance_m)
    u, v, _, _ = b.grid(n_side)
    p0, d0 = b.rays(u, v)
    r = trace_rays(lens, p0, d0, wavelength_nm)
    pts, ok = to_plane(r.points, r.dirs, r.valid, q[2])
    w = _source_weights(b, d0) * ok
    half = size // 2
    j = np.floor((pts[:, 0] - q[0]) * 1e3 / grid_spacing_um + 0.5).astype(np.int64) + half
    i = np.floor((pts[:, 1] - q[1]) * 1e3 / grid_spacing_um + 0.5).astype(np.int64) + half
    inside = ok & (i >= 0) & (i < size) & (j >= 0) & (j < size)
    psf = np.zeros((size, size))
    np.add.at(psf, (i[inside], j[inside]), w[inside])
    total = psf.sum()
    if total <= 0:
        raise InvalidValueError(f"psf_geometric: no ray lands within the {size}×{size} grid of "
                         f"{grid_spacing_um} µm (field height {field_height_mm} mm); enlarge the grid")
    return psf / total


def psf_from_pupil(pupil: np.ndarray, du_mm: float, dv_mm: float, jacobian: np.ndarray,
                   wavelength_nm: float, grid_spacing_um: float, size: int,
                   n_fft: int | None = None) -> np.ndarray:
    """Incoherent PSF from a sampled complex pupil function.

    pupil: (Nv, Nu) complex amplitude on a uniform (u, v) grid of spacing du, dv (mm).
    jacobian: 2×2 d(L, M)/d(u, v) of the exit-ray direction cosines (1/mm).
    The field at image offset r is Σ P exp(i 2π (L x + M y)/λ); its |·|² is box-integrated over
    each output pixel and normalised to sum 1."""
    _check_grid(grid_spacing_um, size)
    lam_mm = wavelength_nm * 1e-6
    nv, nu = pupil.shape
    J = np.asarray(jacobian, dtype=np.float64)
    if abs(np.linalg.det(J)) < 1e-300:
        raise InvalidValueError("psf_from_pupil: singular pupil → direction map")
    dl = min(np.hypot(*J[:, 0]) * du_mm, np.hypot(*J[:, 1]) * dv_mm)
    spacing_mm = grid_spacing_um * 1e-3
    if n_fft is None:
        need = max(2 * max(nu, nv), 4.0 * lam_mm / (dl * spacing_mm))
        n_fft = int(min(_MAX_FFT, 2 ** math.ceil(math.log2(need))))
    n_fft = max(n_fft, nu, nv)
    padded = np.zeros((n_fft, n_fft), np.complex128)
    padded[:nv, :nu] = pupil
    field = scipy.fft.ifft2(padded, workers=2)
    inten = np.fft.fftshift(np.abs(field) ** 2)
    # FFT sample k ↔ pupil frequency f = k/(n_fft·du); image offset r from f = Jᵀ r / λ.
    fft_step_mm = lam_mm / (n_fft * dl)
    ss = int(min(16, max(1, math.ceil(spacing_mm / fft_step_mm))))
    half = size // 2
    sub = (np.arange(ss) + 0.5) / ss - 0.5
    c = (np.arange(size) - half)[:, None] + sub[None, :]
    coords = (c.ravel() * spacing_mm)
    yy, xx = np.meshgrid(coords, coords, indexing="ij")
    fu = (J[0, 0] * xx + J[1, 0] * yy) / lam_mm
    fv = (J[0, 1] * xx + J[1, 1] * yy) / lam_mm
    ku = fu * n_fft * du_mm + n_fft // 2
    kv = fv * n_fft * dv_mm + n_fft // 2
    vals = _bilinear(inten, kv, ku)
    psf = vals.reshape(size, ss, size, ss).sum(axis=(1, 3))
    total = psf.sum()
    if not total > 0:
        raise InvalidValueError("psf_from_pupil: the pupil passes no light")
    return psf / total


def _bilinear(img: np.ndarray, r: np.ndarray, c: np.ndarray) -> np.ndarray:
    n0, n1 = img.shape
    r0 = np.floor(r).astype(np.int64)
    c0 = np.floor(c).astype(np.int64)
    fr, fc = r - r0, c - c0
    out = np.zeros(r.shape)
    for dr, wr in ((0, 1 - fr), (1, fr)):
        for dc, wc in ((0, 1 - fc), (1, fc)):
            rr, cc = r0 + dr, c0 + dc
            ok = (rr >= 0) & (rr < n0) & (cc >= 0) & (cc < n1)
            out += np.where(ok, img[np.clip(rr, 0, n0 - 1), np.clip(cc, 0, n1 - 1)], 0.0) * wr * wc
    return out


def pupil_function(lens: Lens, field_height_mm: float, wavelength_nm: float, object_distance_m: float,
                   n_pupil: int):
    """Sampled pupil of a field: (pupil (n,n) complex, du, dv, jacobian, opd_waves (n,n), valid (n,n))."""
    b, q = _setup(lens, field_height_mm, wavelength_nm, object_distance_m)
    u, v, du, dv = b.grid(n_pupil)
    _, d_in = b.rays(u, v)
    r = b.trace(u, v, wavelength_nm)
    ok = r.valid.copy()
    if ok.sum() < 3:
        raise InvalidValueError(f"pupil_function: fewer than 3 rays pass for field height {field_height_mm} mm")
    par = paraxial(lens, wavelength_nm)
    e = np.array([0.0, 0.0, lens.total_track_mm + par.exit_pupil_mm])
    if not np.isfinite(e).all():
        e = np.array([0.0, 0.0, lens.total_track_mm])
    radius = float(np.linalg.norm(q - e))
    w = r.points - q
    wd = np.einsum("ij,ij->i", w, r.dirs)
    disc = wd * wd - np.einsum("ij,ij->i", w, w) + radius * radius
    ok &= disc >= 0
    s = -wd - np.sqrt(np.where(ok, disc, 0.0))
    opl = r.opl_mm + s
    opd = np.where(ok, opl - opl[ok].mean(), 0.0)
    lam_mm = wavelength_nm * 1e-6
    amp = np.sqrt(_source_weights(b, d_in)) * ok
    design = np.column_stack([u[ok], v[ok], np.ones(ok.sum())])
    coef, *_ = np.linalg.lstsq(design, r.dirs[ok][:, :2], rcond=None)
    jac = coef[:2].T  # [[dL/du, dL/dv], [dM/du, dM/dv]]
    pupil = (amp * np.exp(2j * np.pi * opd / lam_mm)).reshape(n_pupil, n_pupil)
    return pupil, du, dv, jac, (opd / lam_mm).reshape(n_pupil, n_pupil), ok.reshape(n_pupil, n_pupil)


def psf_diffraction(lens: Lens, field_height_mm: float, wavelength_nm: float, object_distance_m: float,
                    grid_spacing_um: float, size: int, n_pupil: int | None = None) -> np.ndarray:
    """Diffraction (FFT) PSF including the traced aberrations; sums to 1 over the grid.
    n_pupil (pupil samples across) defaults to what keeps the FFT window ≥ 2× the output grid,
    capped at 512: for blur of hundreds of waves the pupil phase is undersampled, use psf_geometric."""
    _check_grid(grid_spacing_um, size)
    first = 64 if n_pupil is None else n_pupil
    pupil, du, dv, jac, _, _ = pupil_function(lens, field_height_mm, wavelength_nm, object_distance_m, first)
    if n_pupil is None:
        span = max(np.hypot(*jac[:, 0]) * du, np.hypot(*jac[:, 1]) * dv) * first
        extent_mm = size * grid_spacing_um * 1e-3
        n_pupil = int(np.clip(math.ceil(2.0 * extent_mm * span / (wavelength_nm * 1e-6)), first, _MAX_PUPIL))
        if n_pupil != first:
            pupil, du, dv, jac, _, _ = pupil_function(lens, field_height_mm, wavelength_nm, object_distance_m,
                                                      n_pupil)
    return psf_from_pupil(pupil, du, dv, jac, wavelength_nm, grid_spacing_um, size)


def mtf_from_psf(psf: np.ndarray, grid_spacing_um: float, axis: str = "x") -> tuple[np.ndarray, np.ndarray]:
    """MTF slice along `axis` ('x' or 'y') from a PSF grid: (frequencies in cycles/mm, MTF, 1 at 0)."""
    if axis not in ("x", "y"):
        raise InvalidValueError(f"axis={axis!r}: allowed 'x' or 'y'")
    otf = np.abs(np.fft.fft2(psf))
    otf /= otf[0, 0]
    line = otf[0, :] if axis == "x" else otf[:, 0]
    n = line.size
    freq = np.fft.fftfreq(n, d=grid_spacing_um * 1e-3)
    keep = freq >= 0
    return freq[keep], line[keep]


def diffraction_mtf(freq_cyc_per_mm, wavelength_nm: float, f_number: float) -> np.ndarray:
    """Diffraction-limited MTF of a circular pupil: (2/π)(φ − cosφ sinφ), φ = acos(ν/ν_c), ν_c = 1/(λN)."""
    nu_c = 1.0 / (wavelength_nm * 1e-6 * f_number)
    x = np.clip(np.asarray(freq_cyc_per_mm, dtype=np.float64) / nu_c, 0.0, 1.0)
    phi = np.arccos(x)
    return (2.0 / np.pi) * (phi - np.cos(phi) * np.sin(phi))
