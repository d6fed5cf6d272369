"""PNG previews of every stage: spectral images shown as sRGB, mosaics as grey, channels as RGB."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from workbench import spectra


@lru_cache(maxsize=16)
def _photon_weights(wavelengths_nm: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per band: the weight of a photon rate in Y, and in linear sRGB (Nλ×3) — the photon energy,
    band width, CIE 1931 CMFs and 683 lm/W (spectra.xyz_from_photons) times colour-science's
    XYZ → sRGB matrix, folded into one matrix so a frame takes two matrix products."""
    import colour
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    to_xyz = spectra.xyz_from_photons(np.eye(wl.size), wl)                      # Nλ×3
    to_rgb = to_xyz @ np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB).T
    return to_xyz[:, 1].copy(), to_rgb


def spectral_to_srgb(photons: np.ndarray, wavelengths_nm: np.ndarray, percentile: float = 99.0) -> np.ndarray:
    """H×W×Nλ photon image → H×W×3 sRGB in [0,1] (float32); the given luminance percentile maps
    to white. Equal (within float32 rounding) to XYZ, then colour-science's XYZ_to_RGB (sRGB) and
    sRGB encoding."""
    from workbench.isp.color import srgb_encode
    y_weights, rgb_weights = _photon_weights(tuple(float(w) for w in np.asarray(wavelengths_nm).ravel()))
    flat = photons.reshape(-1, photons.shape[-1])
    if flat.dtype == np.float32:                # no float64 copy of the frame: float32 products
        y_weights, rgb_weights = y_weights.astype(np.float32), rgb_weights.astype(np.float32)
    luminance = flat @ y_weights
    y_ref = float(np.percentile(luminance, percentile)) if luminance.size else 0.0
    if not y_ref > 0:
        return np.zeros((*photons.shape[:2], 3), dtype=np.float32)
    return srgb_encode(flat @ rgb_weights, 1.0 / y_ref).reshape(*photons.shape[:2], 3)


def irradiance_preview(photons: np.ndarray, wavelengths_nm: np.ndarray, meta: dict | None = None) -> np.ndarray:
    """sRGB preview of an optical image or render: colorimetric for spectra; for a render whose
    film was the sensor's own channels (meta['representation'] 'sensor') the channels are shown
    as R, G, B (or R and grey), scaled so the 99th percentile is white."""
    meta = meta or {}
    if meta.get("representation") != "sensor":
        return spectral_to_srgb(photons, wavelengths_nm)
    import colour
    rgb = channels_to_rgb(photons.astype(np.float64), list(meta.get("channel_names") or []))
    ref = np.percentile(rgb, 99.0) if rgb.size else 0.0
    rgb = np.clip(rgb / ref, 0.0, 1.0) if ref > 0 else np.zeros_like(rgb)
    return colour.cctf_encoding(rgb, function="sRGB")


def channels_to_rgb(channels: np.ndarray, names: list[str]) -> np.ndarray:
    """H×W×K linear channels → displayable H×W×3: R,G,B as named; other channels shown grey.
    Channels that already are R, G, B in that order are returned as they are (not copied)."""
    names_u = [n.upper() for n in names]
    if names_u == ["R", "G", "B"]:
        return channels
    if all(c in names_u for c in "RGB"):
        return np.stack([channels[..., names_u.index(c)] for c in "RGB"], axis=-1)
    if channels.shape[-1] == 1:
        return np.repeat(channels, 3, axis=-1)
    # e.g. R + C: red channel in red, clear as grey.
    grey = channels[..., [i for i, n in enumerate(names_u) if n != "R"]].mean(-1)
    red = channels[..., names_u.index("R")] if "R" in names_u else grey
    return np.stack([red, grey, grey], axis=-1)


def png01(image01: np.ndarray):
    """A [0,1] float image (H×W or H×W×3) as an 8-bit PIL image."""
    from PIL import Image
    arr = np.clip(np.nan_to_num(np.asarray(image01, dtype=np.float64)), 0.0, 1.0)
    return Image.fromarray(np.round(arr * 255).astype(np.uint8))


def png_bytes(image) -> bytes:
    """A PIL image encoded as PNG."""
    import io
    buf = io.BytesIO()
    image.save(buf, format="PNG")
    return buf.getvalue()


def save_png(path: str | Path, image01: np.ndarray) -> None:
    """Save a [0,1] float image (H×W or H×W×3) as an 8-bit PNG, atomically."""
    save_image(path, png01(image01))


def save_image(path: str | Path, image) -> None:
    """Save a PIL image as PNG whole or not at all: a killed run leaves the old file or none."""
    from workbench.files import atomic_write_bytes
    atomic_write_bytes(path, png_bytes(image))
