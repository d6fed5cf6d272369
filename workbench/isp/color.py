"""Colour: the Macbeth/D65 least-squares sensor→XYZ matrix, XYZ→linear sRGB and the sRGB curve.

Scales (the 'swing' convention of ISPParams.normalize): sensor responses are expressed so that a
D65 perfect white diffuser gives 1 in its brightest channel, and XYZ so that the same white has
Y = 1. A camera exposed so that white just fills the swing then renders white as sRGB ≈ (1, 1, 1)
(exact up to the fit residual).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.isp.kernels import srgb_encode_flat
from workbench.spectra import illuminant_spd, macbeth_reflectances, xyz_from_photons
from workbench.units import band_widths_nm, energy_to_photons

# Singular values below this fraction of the largest mean the channels are linearly dependent.
RANK_TOLERANCE = 1e-8


class ColourFitError(ValueError):
    """The sensor's channels cannot support a colour transform (fewer than 3 independent ones)."""


@dataclass(frozen=True)
class ColourFit:
    """A fitted sensor→XYZ transform: xyz = linear @ matrix (matrix K×3).

    condition: condition number of the column-normalised 24×K Macbeth response matrix.
    ridge: the Tikhonov weight used (0 for plain least squares).
    residual_rms: RMS XYZ error of the fit over the patches it was fitted to (Y_white = 1 units).
    notes: human-readable remarks (e.g. that the fit was regularised, and why)."""

    matrix: np.ndarray
    condition: float
    ridge: float
    residual_rms: float
    notes: tuple[str, ...]


def macbeth_responses(qe: np.ndarray, wavelengths_nm: np.ndarray,
                      illuminant: str = "D65") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sensor responses and XYZ of the 24 Macbeth patches and of a perfect white under an illuminant.

    Responses = Σ_λ photons(illuminant × reflectance) · QE_k Δλ. Returns (S 24×K, s_white K,
    X 24×3, x_white 3), in relative units (scale them as needed)."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    qe = np.asarray(qe, dtype=np.float64)
    if qe.ndim != 2 or qe.shape[0] != wl.size:
        raise InvalidValueError(f"qe must be Nλ×K with Nλ = {wl.size} wavelengths, got shape {qe.shape}")
    if not np.all(np.isfinite(qe)) or np.any(qe < 0):
        raise InvalidValueError("qe must be finite and ≥ 0")
    light = energy_to_photons(illuminant_spd(illuminant, wl), wl)
    radiance = macbeth_reflectances(wl) * light                      # 24×Nλ photons (relative)
    weights = qe * band_widths_nm(wl)[:, None]
    return radiance @ weights, light @ weights, xyz_from_photons(radiance, wl), xyz_from_photons(light, wl)


def fit_sensor_to_xyz(qe: np.ndarray, wavelengths_nm: np.ndarray,
                      max_condition: float = 1.0e4, preserve_white: bool = False,
                      leave_out: int | None = None) -> ColourFit:
    """Least-squares K×3 matrix T with S·T ≈ X on the 24 Macbeth patches under D65 (cached per QE).

    leave_out: a patch index (0–23) the fit does not see (a leave-one-out fit, to score that patch
    as a colour the matrix was not trained on); residual_rms is then over the other 23.

    preserve_white: the least-squares solution under the constraint s_white·T = x_white, so the
    D65 white (and every grey) maps exactly onto the neutral axis; the unconstrained fit lets the
    greys drift (a few per cent of red on a typical Bayer sensor).

    Ill-conditioning: channels whose responses are linearly dependent (fewer than 3 singular
    values above RANK_TOLERANCE × the largest; e.g. a mono sensor or two identical channels)
    raise ColourFitError. If the column-normalised response matrix has a condition number above
    max_condition, the fit is Tikhonov-regularised so its effective condition is max_condition,
    and the returned notes say so."""
    qe = np.ascontiguousarray(qe, dtype=np.float64)
    wl = np.ascontiguousarray(wavelengths_nm, dtype=np.float64)
    if leave_out is not None and not 0 <= leave_out < 24:
        raise InvalidValueError(f"leave_out must be a Macbeth patch index 0–23, got {leave_out}")
    return _fit_cached(qe.tobytes(), qe.shape, wl.tobytes(), float(max_condition), bool(preserve_white),
                       None if leave_out is None else int(leave_out))


@lru_cache(maxsize=128)
def _fit_cached(qe_bytes: bytes, qe_shape: tuple[int, int], wl_bytes: bytes,
                max_condition: float, preserve_white: bool, leave_out: int | None = None) -> ColourFit:
    qe = np.frombuffer(qe_bytes, dtype=np.float64).reshape(qe_shape)
    wl = np.frombuffer(wl_bytes, dtype=np.float64)
    S, s_white, X, x_white = macbeth_responses(qe, wl, "D65")
    if leave_out is not None:
        S, X = np.delete(S, leave_out, axis=0), np.delete(X, leave_out, axis=0)
    k = S.shape[1]
    if k < 3:
        raise ColourFitError(f"a colour transform needs at least 3 sensor channels, the sensor has {k}")
    if np.max(s_white) <= 0:
        raise ColourFitError("the sensor does not respond to D65 light (QE is zero on the grid)")
    S = S / np.max(s_white)
    X = X / x_white[1]
    norms = np.linalg.norm(S, axis=0)
    dead = [int(i) for i in np.flatnonzero(norms <= RANK_TOLERANCE * norms.max())]
    if dead:
        raise ColourFitError(f"sensor channel(s) {dead} do not respond to the Macbeth chart")
    A = S / norms
    U, sv, Vt = np.linalg.svd(A, full_matrices=False)
    rank = int(np.sum(sv > RANK_TOLERANCE * sv[0]))
    if rank < 3:
        raise ColourFitError(
            f"the {k} sensor channels give only {rank} independent responses on the Macbeth chart "
            f"(singular values {np.array2string(sv, precision=3)}); a colour transform needs 3 — "
            "identical or proportional channels, or a monochrome sensor")
    condition = float(sv[0] / sv[-1])
    notes: list[str] = []
    ridge = 0.0
    if condition > max_condition:
        c2 = max_condition ** 2
        ridge = float((sv[0] ** 2 - c2 * sv[-1] ** 2) / (c2 - 1.0))
        notes.append(f"colour fit ill-conditioned (condition {condition:.3g} > {max_condition:.3g}); "
                     f"ridge-regularised (λ = {ridge:.3g}) — colours are approximate")
    # Solve in the SVD basis: T_A = V diag(s / (s² + λ)) Uᵀ X (plain least squares when λ = 0).
    T_A = Vt.T @ ((sv / (sv ** 2 + ridge))[:, None] * (U.T @ X))
    if preserve_white:
        # min ‖A·T_A − X‖² (+ λ‖T_A‖²) s.t. a_w·T_A = x_w: T_A += G⁻¹a_wᵀ (x_w − a_w·T_A) / (a_w G⁻¹ a_wᵀ)
        a_w = (s_white / np.max(s_white)) / norms
        g_inv_a = Vt.T @ ((1.0 / (sv ** 2 + ridge)) * (Vt @ a_w))
        T_A = T_A + np.outer(g_inv_a, (x_white / x_white[1]) - a_w @ T_A) / float(a_w @ g_inv_a)
    T = T_A / norms[:, None]
    residual = float(np.sqrt(np.mean((S @ T - X) ** 2)))
    T.setflags(write=False)
    return ColourFit(matrix=T, condition=condition, ridge=ridge, residual_rms=residual, notes=tuple(notes))


@lru_cache(maxsize=1)
def xyz_to_linear_srgb_matrix() -> np.ndarray:
    """3×3 matrix M with linear sRGB = M · XYZ (IEC 61966-2-1, D65 white), from colour-science."""
    import colour
    m = np.array(colour.models.RGB_COLOURSPACE_sRGB.matrix_XYZ_to_RGB, dtype=np.float64)
    m.setflags(write=False)
    return m


@lru_cache(maxsize=1)
def srgb_white_xyz() -> np.ndarray:
    """XYZ (Y = 1) that renders as sRGB (1, 1, 1): the D65 white of the sRGB matrices (read-only)."""
    white = np.linalg.solve(xyz_to_linear_srgb_matrix(), np.ones(3))
    white.setflags(write=False)
    return white


def xyz_to_srgb_linear(xyz: np.ndarray) -> np.ndarray:
    """XYZ (…×3, Y_white = 1) → linear sRGB (…×3, float32, not clipped)."""
    xyz = np.asarray(xyz, dtype=np.float32)
    m = xyz_to_linear_srgb_matrix().T.astype(np.float32)
    return (xyz.reshape(-1, 3) @ m).reshape(xyz.shape)


def srgb_encode(linear: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """The sRGB transfer curve (IEC 61966-2-1) of scale·x, clipped to [0, 1] first, as float32.

    12.92·x for x ≤ 0.0031308, else 1.055·x^(1/2.4) − 0.055; within 1e-7 of
    colour.cctf_encoding(…, 'sRGB'), with 0 ↦ 0 and 1 ↦ 1 exactly, NaN kept (isp.kernels: a
    polynomial in the float's mantissa, one compiled pass)."""
    x = np.ascontiguousarray(linear, dtype=np.float32)
    out = np.empty_like(x)
    srgb_encode_flat(x.reshape(-1), np.float32(scale), out.reshape(-1))
    return out
