"""Illuminant correction (white balance) in the ISP's internal colour space (anchor: ISETCam
imageIlluminantCorrection): per-channel gains chosen so that a reference statistic of the image
takes the chromaticity of the output white. The middle channel (Y, or G) keeps gain 1, so the
correction does not change exposure."""
from __future__ import annotations

import numpy as np

from workbench.isp.blocked import pixels_matmul, pixels_sum

ILLUMINANT_CORRECTIONS = ("none", "gray_world", "white_world", "manual")
REFERENCE_CHANNEL = 1


def _channel_means(pixels: np.ndarray) -> np.ndarray:
    if pixels.shape[0] == 0:
        return np.zeros(pixels.shape[1])
    return pixels_sum(pixels) / pixels.shape[0]


def illuminant_gains(linear: np.ndarray, to_ics: np.ndarray, method: str, white: np.ndarray, *,
                     white_world_fraction: float = 0.7,
                     manual_gains: tuple[float, ...] = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, list[str]]:
    """Gains (3,) for the internal colour space ics = linear @ to_ics that correct the illuminant.

    linear: H×W×K sensor channels; to_ics: K×3 matrix into the internal colour space (XYZ, or
    a channel selection). method: 'none' (ones), 'gray_world' (the image mean gets the
    chromaticity of `white`), 'white_world' (the mean of the pixels ≥ white_world_fraction × max
    of the brightest ics channel gets it), 'manual' (manual_gains). white: the output white in
    the internal space (3,), e.g. the XYZ of sRGB's D65 white. Returns (gains, notes); a zero
    statistic leaves the image unchanged, with a note."""
    k = linear.shape[-1]
    if linear.ndim != 3 or to_ics.shape != (k, 3):
        raise ValueError(f"illuminant correction needs an H×W×K image and a K×3 matrix, got "
                         f"shapes {linear.shape} and {to_ics.shape}")
    white = np.asarray(white, dtype=np.float64)
    if method == "none":
        return np.ones(3), []
    if method == "manual":
        gains = np.asarray(manual_gains, dtype=np.float64)
        if gains.shape != (3,) or not np.all(np.isfinite(gains)) or np.any(gains <= 0):
            raise ValueError(f"manual_gains must be three positive numbers, got {manual_gains}")
        return gains, []
    flat = linear.reshape(-1, k)
    if method == "gray_world":
        means = _channel_means(flat) @ to_ics          # the mean commutes with the linear map
    elif method == "white_world":
        ics = pixels_matmul(flat, to_ics)
        brightest = int(np.argmax(ics.max(axis=0)))
        plane = ics[:, brightest]
        means = _channel_means(ics[plane >= white_world_fraction * plane.max()])
    else:
        raise ValueError(f"illuminant correction '{method}' is unknown; "
                         f"allowed: {', '.join(ILLUMINANT_CORRECTIONS)}")
    if np.any(means <= 0) or not np.all(np.isfinite(means)):
        return np.ones(3), [f"{method}: a channel of the image statistic is zero "
                            f"(means {np.array2string(means, precision=3)}); no correction applied"]
    ref = REFERENCE_CHANNEL
    gains = (white / white[ref]) * (means[ref] / means)
    return gains, []
