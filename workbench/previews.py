"""PNG previews of every stage: spectral images shown as sRGB, mosaics as grey, channels as RGB."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench import spectra


def spectral_to_srgb(photons: np.ndarray, wavelengths_nm: np.ndarray, percentile: float = 99.0) -> np.ndarray:
    """H×W×Nλ photon image → H×W×3 sRGB in [0,1]; the given luminance percentile maps to white."""
    import colour
    xyz = spectra.xyz_from_photons(photons.reshape(-1, photons.shape[-1]), wavelengths_nm)
    y_ref = np.percentile(xyz[:, 1], percentile) if xyz.size else 0.0
    xyz = xyz / y_ref if y_ref > 0 else np.zeros_like(xyz)
    rgb = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    rgb = np.clip(rgb, 0.0, 1.0)
    return colour.cctf_encoding(rgb, function="sRGB").reshape(*photons.shape[:2], 3)


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
