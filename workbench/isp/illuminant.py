"""Illuminant correction (white balance) in the ISP's internal colour space (anchor: ISETCam
imageIlluminantCorrection): per-channel gains chosen so that a reference statistic of the image
takes the chromaticity of the output white. The middle channel (Y, or G) keeps gain 1, so the
correction does not change exposure."""
from __future__ import annotations

import numpy as np

from workbench.isp.blocked import pixels_matmul, pixels_sum
from workbench.registry import Registry

REFERENCE_CHANNEL = 1

ILLUMINANT_CORRECTIONS: Registry = Registry("isp.illuminant_correction", "illuminant correction")
"""name → fn(flat, to_ics, white, white_world_fraction, manual_gains) -> (gains (3,), notes):
flat the N×K sensor pixels, to_ics the K×3 map into the internal colour space, white (3,)."""


def _channel_means(pixels: np.ndarray) -> np.ndarray:
    if pixels.shape[0] == 0:
        return np.zeros(pixels.shape[1])
    return pixels_sum(pixels) / pixels.shape[0]


def _gains_to_white(method: str, means: np.ndarray, white: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Gains that give the statistic `means` (3,) the chromaticity of `white`, the reference
    channel unchanged; ones with a note when a channel of the statistic is zero."""
    if np.any(means <= 0) or not np.all(np.isfinite(means)):
        return np.ones(3), [f"{method}: a channel of the image statistic is zero "
                            f"(means {np.array2string(means, precision=3)}); no correction applied"]
    ref = REFERENCE_CHANNEL
    return (white / white[ref]) * (means[ref] / means), []


@ILLUMINANT_CORRECTIONS.register("none")
def _none(flat, to_ics, white, white_world_fraction, manual_gains):
    """No correction: unit gains."""
    return np.ones(3), []


@ILLUMINANT_CORRECTIONS.register("gray_world")
def _gray_world(flat, to_ics, white, white_world_fraction, manual_gains):
    """The image mean gets the chromaticity of `white`."""
    return _gains_to_white("gray_world", _channel_means(flat) @ to_ics, white)  # the mean commutes with the map


@ILLUMINANT_CORRECTIONS.register("white_world")
def _white_world(flat, to_ics, white, white_world_fraction, manual_gains):
    """The mean of the pixels ≥ white_world_fraction × max of the brightest ics channel gets it."""
    ics = pixels_matmul(flat, to_ics)
    plane = ics[:, int(np.argmax(ics.max(axis=0)))]
    return _gains_to_white("white_world", _channel_means(ics[plane >= white_world_fraction * plane.max()]), white)


@ILLUMINANT_CORRECTIONS.register("manual")
def _manual(flat, to_ics, white, white_world_fraction, manual_gains):
    """The user's gains."""
    gains = np.asarray(manual_gains, dtype=np.float64)
    if gains.shape != (3,) or not np.all(np.isfinite(gains)) or np.any(gains <= 0):
        raise ValueError(f"manual_gains must be three positive numbers, got {manual_gains}")
    return gains, []


def illuminant_gains(linear: np.ndarray, to_ics: np.ndarray, method: str, white: np.ndarray, *,
                     white_world_fraction: float = 0.7,
                     manual_gains: tuple[float, ...] = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, list[str]]:
    """Gains (3,) for the internal colour space ics = linear @ to_ics that correct the illuminant.

    linear: H×W×K sensor channels; to_ics: K×3 matrix into the internal colour space (XYZ, or
    a channel selection). method: a name in ILLUMINANT_CORRECTIONS: 'none' (ones), 'gray_world'
    (the image mean gets the chromaticity of `white`), 'white_world' (the mean of the pixels ≥
    white_world_fraction × max of the brightest ics channel gets it), 'manual' (manual_gains).
    white: the output white in the internal space (3,), e.g. the XYZ of sRGB's D65 white.
    Returns (gains, notes); a zero statistic leaves the image unchanged, with a note."""
    correct = ILLUMINANT_CORRECTIONS[method]
    k = linear.shape[-1]
    if linear.ndim != 3 or to_ics.shape != (k, 3):
        raise ValueError(f"illuminant correction needs an H×W×K image and a K×3 matrix, got "
                         f"shapes {linear.shape} and {to_ics.shape}")
    return correct(linear.reshape(-1, k), to_ics, np.asarray(white, dtype=np.float64),
                   white_world_fraction, manual_gains)
