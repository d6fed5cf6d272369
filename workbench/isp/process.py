"""The ISP: SensorImage → raw, linear and sRGB images (anchor: ISETCam ipCompute).

raw → (demosaic) linear sensor channels → (Macbeth/D65 matrix) XYZ → (illuminant correction)
→ linear sRGB → (normalisation, clip) → sRGB transfer curve.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from workbench.compute.pixel_threads import map_row_blocks
from workbench.errors import InvalidValueError
from workbench.isp import kernels
from workbench.isp.blocked import pixels_matmul
from workbench.isp.color import (
    ColourFit,
    ColourFitError,
    fit_sensor_to_xyz,
    srgb_encode,
    srgb_white_xyz,
    xyz_to_linear_srgb_matrix,
)
from workbench.isp.demosaic import demosaic
from workbench.isp.illuminant import illuminant_gains
from workbench.isp.params import ISPParams
from workbench.sensor.image import SensorImage

# SensorImage.meta key of the black level (dn) that the ISP subtracts ("zero level" in ISETCam).
BLACK_LEVEL_KEY = "black_level_dn"
# A sensor channel at or above this fraction of full scale is saturated: its pixel's colour is
# not the scene's (left out of white balance statistics; 'neutral' highlights start here).
SATURATED_FRACTION = 0.98
HIGHLIGHT_START = 0.90        # 'neutral' highlights blend from here to SATURATED_FRACTION
# Channels that can stand for luminance in a grey rendering, in order of preference.
GREY_CHANNELS = ("C", "W", "M", "Y", "G")


@dataclass
class ISPResult:
    """The three image representations of one exposure (all float32, no NaN/Inf).

    raw: H×W mosaic as recorded, dn / max_dn clipped to [0, 1] (black level included).
    linear: H×W×K demosaiced sensor channels in [0, 1], in channel_names order, black level
        removed ((dn − black) / (max_dn − black)); no colour transform.
    srgb: H×W×3 sRGB-encoded values in [0, 1] (the full pipeline).
    xyz (made when first read): H×W×3 CIE XYZ after illuminant correction, before normalisation
        and clipping (Y = 1 for a D65 white that fills the swing), or None when no colour
        transform was applied.
    to_xyz: the K×3 matrix linear → xyz (illuminant gains included), or None.
    colour_fit: the sensor→XYZ fit used (or None); gains: the illuminant-correction gains (or None).
    notes: why something was not done as asked (fallbacks, grey renderings, regularised fits)."""

    raw: np.ndarray
    linear: np.ndarray
    srgb: np.ndarray
    channel_names: list[str]
    to_xyz: np.ndarray | None = None
    colour_fit: ColourFit | None = None
    gains: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)

    @cached_property
    def xyz(self) -> np.ndarray | None:
        return None if self.to_xyz is None else linear_to_xyz(self.linear, self.to_xyz)


def _validate(image: SensorImage) -> float:
    """Check what the ISP relies on but the pixels' values (see _raw); return the black level in dn."""
    dn = np.asarray(image.dn)
    if dn.ndim != 2 or min(dn.shape) < 1:
        raise InvalidValueError(f"ISP: SensorImage.dn must be H×W with H, W ≥ 1, got shape {dn.shape}")
    if not (np.isfinite(image.max_dn) and image.max_dn > 0):
        raise InvalidValueError(f"ISP: SensorImage.max_dn must be a positive number, got {image.max_dn}")
    k = len(image.channel_names)
    qe = np.asarray(image.qe)
    if k == 0 or qe.ndim != 2 or qe.shape[1] != k or qe.shape[0] != np.asarray(image.wavelengths_nm).size:
        raise InvalidValueError(f"ISP: SensorImage.qe must be Nλ×K with K = {k} channels "
                         f"{image.channel_names} and Nλ = len(wavelengths_nm); got shape {qe.shape}")
    black = float(image.meta.get(BLACK_LEVEL_KEY, 0.0))
    if not 0.0 <= black < image.max_dn:
        raise InvalidValueError(f"ISP: SensorImage.meta['{BLACK_LEVEL_KEY}'] = {black} must lie in "
                         f"[0, max_dn = {image.max_dn})")
    return black


def _raw(image: SensorImage) -> np.ndarray:
    """dn / max_dn clipped to [0, 1] (float32), one compiled pass that also refuses NaN and Inf."""
    dn = np.asarray(image.dn)
    if dn.dtype not in (np.float32, np.float64):
        dn = dn.astype(np.float32)
    raw = np.empty(dn.shape, dtype=np.float32)
    if kernels.normalise_raw(dn, dn.dtype.type(1.0 / image.max_dn), raw):
        raise InvalidValueError("ISP: SensorImage.dn contains NaN or Inf")
    return raw


def raw_to_linear(raw: np.ndarray, cfa_tile: np.ndarray, channel_names: list[str],
                  method: str = "bilinear", black_level: float = 0.0) -> tuple[np.ndarray, list[str]]:
    """Demosaic a [0, 1] mosaic into H×W×K sensor channels in [0, 1]; returns (linear, notes).

    black_level (raw units, [0, 1)) is subtracted and the rest rescaled to [0, 1] first.
    Every DEMOSAIC_METHODS entry keeps values within the range of its input."""
    if black_level:
        if not 0.0 <= black_level < 1.0:
            raise InvalidValueError(f"black_level must lie in [0, 1) of the raw scale, got {black_level}")
        raw = np.clip((raw - np.float32(black_level)) * np.float32(1.0 / (1.0 - black_level)), 0.0, 1.0)
    return demosaic(raw, cfa_tile, channel_names, method)


def linear_to_xyz(linear: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """H×W×K sensor channels → H×W×3 with a K×3 matrix (xyz = linear @ matrix), float32.

    The matrix is normally ColourFit.matrix (sensor → XYZ); any K×3 channel transform works."""
    h, w, k = linear.shape
    if matrix.shape != (k, 3):
        raise InvalidValueError(f"colour matrix must be {k}×3 for {k} channels, got {matrix.shape}")
    return pixels_matmul(linear.reshape(-1, k), matrix).reshape(h, w, 3)


def _scale(peak: float, normalize: str, notes: list[str]) -> float:
    """The factor applied before encoding: 1 for 'swing', 1/max for 'max'."""
    if normalize == "swing":
        return 1.0
    if normalize == "max":
        if not peak > 0:
            notes.append("normalize='max': the image is black; left unscaled")
            return 1.0
        return 1.0 / peak
    raise InvalidValueError(f"normalize '{normalize}' is unknown; allowed: 'swing', 'max'")


def colour_transform(linear: np.ndarray, to_rgb: np.ndarray, neutral_highlights: bool,
                     encode: bool = False) -> tuple[np.ndarray, float]:
    """H×W×K sensor channels → (linear sRGB H×W×3, its maximum), one compiled pass over the pixels
    (isp.kernels.colour_pixels); with encode the image is sRGB-encoded (the 'swing' normalisation:
    nothing to scale first).
    neutral_highlights: pixels whose brightest sensor channel nears saturation blend towards a
    neutral of their brightest output channel — weight 0 below HIGHLIGHT_START, 1 from
    SATURATED_FRACTION on, smoothstep between — so a clipped white renders white, not pink;
    unsaturated colours are untouched."""
    h, w, k = linear.shape
    if to_rgb.shape != (k, 3):
        raise InvalidValueError(f"colour matrix must be {k}×3 for {k} channels, got {to_rgb.shape}")
    flat = np.ascontiguousarray(linear.reshape(-1, k), dtype=np.float32)
    rgb = np.empty((h * w, 3), dtype=np.float32)
    matrix = np.ascontiguousarray(to_rgb, dtype=np.float64)

    def block(_, rows: slice) -> float:          # rows of the flat pixel array; the kernel releases the GIL
        return kernels.colour_pixels(flat[rows], matrix, bool(neutral_highlights), HIGHLIGHT_START,
                                     SATURATED_FRACTION, bool(encode), rgb[rows])
    peak = max(map_row_blocks(block, h * w, h * w))
    return rgb.reshape(h, w, 3), float(peak)


def xyz_to_srgb(xyz: np.ndarray, normalize: str = "swing") -> np.ndarray:
    """XYZ (H×W×3, Y_white = 1) → encoded sRGB in [0, 1] (float32), normalised as ISPParams says."""
    rgb = linear_to_xyz(np.asarray(xyz, dtype=np.float32), xyz_to_linear_srgb_matrix().T)
    return srgb_encode(rgb, _scale(float(rgb.max()) if rgb.size else 0.0, normalize, []))


def _grey_channel(channel_names: list[str]) -> int | None:
    names = [n.upper() for n in channel_names]
    for n in GREY_CHANNELS:
        if n in names:
            return names.index(n)
    return 0 if len(names) == 1 else None


def _grey(linear: np.ndarray, channel_names: list[str], why: str, notes: list[str]) -> np.ndarray:
    k = _grey_channel(channel_names)
    if k is None:
        notes.append(f"{why}; sRGB is grey from the mean of channels {channel_names}")
        return np.repeat(linear.mean(axis=2, keepdims=True), 3, axis=2)
    notes.append(f"{why}; sRGB is grey from the {channel_names[k]} channel")
    return np.repeat(linear[..., k:k + 1], 3, axis=2)


def _colour_path(image: SensorImage, params: ISPParams, notes: list[str]):
    """Choose how the sensor channels become colour: returns (to_ics K×3 or None, the output
    white in that space, the ColourFit or None, why there is no colour or None)."""
    names = list(image.channel_names)
    upper = [n.upper() for n in names]
    transform = params.colour_transform
    fitted = transform in ("macbeth_d65_wp", "macbeth_d65_lsq")
    if fitted and np.asarray(image.wavelengths_nm).size == 0:
        transform, fitted = "none", False
        notes.append("SensorImage has no QE (wavelengths_nm is empty): no colour matrix can be fitted; "
                     "the sensor channels are shown as they are (colour_transform 'none')")
    if len(names) == 1:
        return None, None, None, f"a {image.pattern} sensor has one channel: no colour"
    if set(upper) == {"R", "C"}:
        return None, None, None, (f"{image.pattern} has only red and clear pixels: no colour can be "
                                  "reconstructed (red alone cannot separate green from blue)")
    if fitted:
        try:
            fit = fit_sensor_to_xyz(image.qe, image.wavelengths_nm, params.max_condition,
                                    preserve_white=transform == "macbeth_d65_wp")
        except ColourFitError as exc:
            return None, None, None, f"no colour transform: {exc}"
        notes.extend(fit.notes)
        return np.asarray(fit.matrix, dtype=np.float64), srgb_white_xyz(), fit, None
    if {"R", "G", "B"} <= set(upper):
        selection = np.zeros((len(names), 3))
        selection[[upper.index(c) for c in "RGB"], [0, 1, 2]] = 1.0
        return selection, np.ones(3), None, None
    return None, None, None, f"colour_transform 'none' needs R, G and B channels, the sensor has {names}"


def _tiny_safe_raw_to_linear(raw, cfa_tile, names, method, black):
    """raw_to_linear, also for a sensor smaller than its CFA tile (1×1, 1×N): the mosaic is
    edge-padded to the tile so each missing channel takes its nearest neighbour's value."""
    tile = np.asarray(cfa_tile)
    h, w = raw.shape
    th, tw = max(tile.shape[0], 2), max(tile.shape[1], 2)
    if h >= th and w >= tw:
        return raw_to_linear(raw, cfa_tile, names, method, black)
    padded = np.pad(raw, ((0, max(0, th - h)), (0, max(0, tw - w))), mode="edge")
    linear, notes = raw_to_linear(padded, cfa_tile, names, "bilinear", black)
    notes.append(f"the {h}×{w} sensor is smaller than its {tile.shape[0]}×{tile.shape[1]} CFA tile: "
                 "missing channels copy the neighbouring pixel (bilinear)")
    return np.ascontiguousarray(linear[:h, :w]), notes


def sensor_image_to_srgb(image: SensorImage, params: ISPParams | None = None) -> ISPResult:
    """Run the ISP on one SensorImage (see module docstring and ISPParams)."""
    params = ISPParams() if params is None else params
    black_dn = _validate(image)
    names = list(image.channel_names)
    raw = _raw(image)
    linear, notes = _tiny_safe_raw_to_linear(raw, image.cfa_tile, names, params.demosaic,
                                             black_dn / image.max_dn)
    to_ics, white, fit, grey_reason = _colour_path(image, params, notes)

    gains = None
    to_xyz = None
    if to_ics is None:
        rgb_linear = _grey(linear, names, grey_reason, notes)
        if params.illuminant_correction != "none":
            notes.append(f"illuminant correction '{params.illuminant_correction}' skipped: no colour")
        encoded = False
        rgb_peak = float(rgb_linear.max()) if params.normalize == "max" and rgb_linear.size else 0.0
    else:
        gains, gain_notes = illuminant_gains(linear, to_ics, params.illuminant_correction, white,
                                             white_world_fraction=params.white_world_fraction,
                                             manual_gains=params.manual_gains,
                                             saturated=SATURATED_FRACTION)
        notes.extend(gain_notes)
        to_ics = to_ics * gains   # gains folded into the matrices: one K×3 product per output
        to_rgb = to_ics @ xyz_to_linear_srgb_matrix().T if fit is not None else to_ics
        encoded = params.normalize == "swing"          # nothing to scale: encoded in the same pass
        to_xyz = to_ics if fit is not None else None
        if not np.all(np.isfinite(to_rgb)):   # the raw image is finite and in [0, 1]: so is every pixel after
            raise InvalidValueError(f"ISP: the colour matrix (fit × illuminant gains) is not finite: {to_rgb.tolist()}")
        rgb_linear, rgb_peak = colour_transform(linear, to_rgb, params.highlights == "neutral", encode=encoded)
    srgb = rgb_linear if encoded else srgb_encode(rgb_linear, _scale(rgb_peak, params.normalize, notes))
    return ISPResult(raw=raw, linear=linear, srgb=srgb, channel_names=names, to_xyz=to_xyz,
                     colour_fit=fit, gains=gains, notes=notes)


REPRESENTATIONS = ("raw", "linear", "srgb")


def representation_to_uint8(result: ISPResult, representation: str) -> np.ndarray:
    """One of the paper's three detector inputs as an H×W×3 uint8 image (round(255·x)).

    'raw': the mosaic replicated to 3 channels; 'linear': the demosaiced sensor channels, no
    colour transform — R, G, B where the sensor has them, otherwise its channels in order with
    the last repeated (RCCB → R, C, B; RCCC → R, C, C; MONO → M, M, M); 'srgb': the full pipeline."""
    if representation == "raw":
        image = np.repeat(result.raw[..., None], 3, axis=2)
    elif representation == "linear":
        upper = [n.upper() for n in result.channel_names]
        if {"R", "G", "B"} <= set(upper):
            order = [upper.index(c) for c in "RGB"]
        else:
            order = [min(i, len(upper) - 1) for i in range(3)]
        image = result.linear[..., order]
    elif representation == "srgb":
        image = result.srgb
    else:
        raise InvalidValueError(f"representation '{representation}' is unknown; allowed: {', '.join(REPRESENTATIONS)}")
    return np.rint(np.clip(image, 0.0, 1.0) * np.float32(255.0)).astype(np.uint8)
