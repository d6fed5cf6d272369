"""Synthetic sensors and images for the ISP tests (no dependency on workbench.sensor internals)."""
from __future__ import annotations

import numpy as np

from workbench.isp.color import macbeth_responses
from workbench.sensor.image import SensorImage
from workbench.spectra import DEFAULT_WAVELENGTHS_NM

WL = DEFAULT_WAVELENGTHS_NM

BAYER_TILES = {
    "RGGB": [[0, 1], [1, 2]],
    "BGGR": [[2, 1], [1, 0]],
    "GRBG": [[1, 0], [2, 1]],
    "GBRG": [[1, 2], [0, 1]],
}


def _lobe(wl, mu, s_left, s_right):
    s = np.where(wl < mu, s_left, s_right)
    return np.exp(-0.5 * ((wl - mu) / s) ** 2)


def cie_like_qe(wl=WL) -> np.ndarray:
    """Near-colorimetric QE: the multi-lobe Gaussian fit of the CIE 1931 CMFs (Wyman, Sloan &
    Shirley 2013), clipped at 0, scaled to a peak of 0.6. Columns R(x̄), G(ȳ), B(z̄)."""
    wl = np.asarray(wl, dtype=np.float64)
    x = (1.056 * _lobe(wl, 599.8, 37.9, 31.0) + 0.362 * _lobe(wl, 442.0, 16.0, 26.7)
         - 0.065 * _lobe(wl, 501.1, 20.4, 26.2))
    y = 0.821 * _lobe(wl, 568.8, 46.9, 40.5) + 0.286 * _lobe(wl, 530.9, 16.3, 31.1)
    z = 1.217 * _lobe(wl, 437.0, 11.8, 36.0) + 0.681 * _lobe(wl, 459.0, 26.0, 13.8)
    qe = np.clip(np.stack([x, y, z], axis=1), 0.0, None)
    return 0.6 * qe / qe.max()


def camera_like_qe(wl=WL) -> np.ndarray:
    """A typical (non-colorimetric) RGB camera: single Gaussians at 600, 535, 455 nm."""
    wl = np.asarray(wl, dtype=np.float64)
    return np.stack([0.5 * _lobe(wl, 600, 30, 40), 0.6 * _lobe(wl, 535, 35, 35),
                     0.5 * _lobe(wl, 455, 30, 30)], axis=1)


def mosaic(linear: np.ndarray, tile) -> np.ndarray:
    """Sample an H×W×K image through a CFA tile into an H×W mosaic."""
    tile = np.asarray(tile)
    h, w, _ = linear.shape
    th, tw = tile.shape
    idx = np.tile(tile, (h // th + 1, w // tw + 1))[:h, :w]
    return np.take_along_axis(linear, idx[..., None], axis=2)[..., 0]


def sensor_image(linear: np.ndarray, tile, names, qe, wl=WL, max_dn=255.0, pattern=None) -> SensorImage:
    """A SensorImage whose dn is the CFA sampling of `linear` (in [0, 1] of the swing) × max_dn."""
    dn = (mosaic(np.asarray(linear, dtype=np.float64), tile) * max_dn).astype(np.float32)
    zeros = np.zeros_like(dn)
    return SensorImage(electrons=zeros, volts=zeros, dn=dn, cfa_tile=np.asarray(tile),
                       channel_names=list(names), pattern=pattern or "".join(names),
                       qe=np.asarray(qe, dtype=np.float64), wavelengths_nm=np.asarray(wl),
                       exposure_s=0.01, max_dn=max_dn)


def macbeth_chart(qe, wl=WL, patch_px=12, white_level=1.0):
    """Linear sensor image (4×6 patches of patch_px pixels) of the Macbeth chart under D65.

    Exposure: a D65 perfect white would give white_level in the brightest channel. Returns
    (image H×W×K, reference XYZ 24×3 with a perfect white at Y = white_level)."""
    S, s_white, X, x_white = macbeth_responses(qe, wl, "D65")
    responses = S / s_white.max() * white_level
    xyz_ref = X / x_white[1] * white_level
    k = S.shape[1]
    img = responses.reshape(4, 6, k).repeat(patch_px, axis=0).repeat(patch_px, axis=1)
    return img, xyz_ref


def patch_means(image: np.ndarray, patch_px=12, margin=3) -> np.ndarray:
    """Mean of the centre of each of the 24 patches (24×C), away from demosaic edges."""
    out = []
    for r in range(4):
        for c in range(6):
            block = image[r * patch_px + margin:(r + 1) * patch_px - margin,
                          c * patch_px + margin:(c + 1) * patch_px - margin]
            out.append(block.reshape(-1, image.shape[-1]).mean(axis=0))
    return np.array(out)
