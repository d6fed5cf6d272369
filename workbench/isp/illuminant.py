"""Illuminant correction (white balance) in the ISP's internal colour space (anchor: ISETCam
imageIlluminantCorrection): per-channel gains chosen so that a reference statistic of the image
takes the chromaticity of the output white. The middle channel (Y, or G) keeps gain 1, so the
correction does not change exposure."""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import InvalidValueError
from workbench.isp import kernels
from workbench.compute.pixel_threads import map_row_blocks
from workbench.isp.blocked import pixels_sum
from workbench.registry import Registry

REFERENCE_CHANNEL = 1

ILLUMINANT_CORRECTIONS: Registry = Registry("isp.illuminant_correction", "illuminant correction")
"""name → fn(flat, to_ics, white, white_world_fraction, manual_gains, saturated) -> (gains (3,), notes):
flat the N×K sensor pixels, to_ics the K×3 map into the internal colour space, white (3,);
pixels with a channel ≥ saturated (math.inf: none) are left out of the statistic."""


def _unsaturated(method: str, flat: np.ndarray, saturated: float) -> tuple[np.ndarray | None, list[str]]:
    """The mask of pixels whose every channel is below `saturated` (None: all are); when no
    pixel is, None and a note that the statistic uses them all."""
    if saturated == math.inf:
        return None, []
    valid = np.maximum.reduce([flat[:, c] for c in range(flat.shape[1])]) < saturated
    if not valid.any():
        return None, [f"{method}: every pixel is saturated; the statistic uses them all"]
    return (None if valid.all() else valid), []


def _channel_means(pixels: np.ndarray) -> np.ndarray:
    if pixels.shape[0] == 0:
        return np.zeros(pixels.shape[1])
    return pixels_sum(pixels) / pixels.shape[0]


def _gains_to_white(method: str, means: np.ndarray, white: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Gains that give the statistic `means` (3,) the chromaticity of `white`, the reference
    channel unchanged; ones with a note when a channel of the statistic is zero."""
    if not all(0.0 < m < math.inf for m in means.tolist()):      # a NaN fails too
        return np.ones(3), [f"{method}: a channel of the image statistic is zero "
                            f"(means {np.array2string(means, precision=3)}); no correction applied"]
    ref = REFERENCE_CHANNEL
    return (white / white[ref]) * (means[ref] / means), []


@ILLUMINANT_CORRECTIONS.register("none")
def _none(flat, to_ics, white, white_world_fraction, manual_gains, saturated):
    """No correction: unit gains."""
    return np.ones(3), []


@ILLUMINANT_CORRECTIONS.register("gray_world")
def _gray_world(flat, to_ics, white, white_world_fraction, manual_gains, saturated):
    """The image mean gets the chromaticity of `white`."""
    valid, notes = _unsaturated("gray_world", flat, saturated)
    if valid is None:
        means = _channel_means(flat)
    else:                                          # a masked mean needs no copy of the pixels
        means = (valid.astype(np.float32) @ flat).astype(np.float64) / np.count_nonzero(valid)
    gains, more = _gains_to_white("gray_world", means @ to_ics, white)   # the mean commutes with the map
    return gains, notes + more


GREY_PIXEL_TOLERANCES = (0.12, 0.06, 0.03, 0.03)   # chromatic distance from white, per round
GREY_PIXEL_MIN_SHARE = 0.005    # fewer grey pixels than this share of the image: gray world
GREY_PIXEL_SAMPLES = 8192       # the statistic looks at about this many pixels, evenly spread


def _sample_ics(flat: np.ndarray, step: int, saturated: float, to_ics: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gray-pixels sample (every step-th pixel below saturation) in the internal colour space,
    and its sum; gathered by row blocks in threads (its reads are a cache miss each)."""
    n = len(flat)
    parts = map_row_blocks(lambda _i, rows: kernels.sample_ics(flat, rows.start, rows.stop, step, saturated, to_ics),
                           n, n)
    return np.concatenate([ics for ics, _ in parts]), np.sum([part for _, part in parts], axis=0)


def _percentile_99(values: np.ndarray) -> float:
    """The 99th percentile of values (n ≥ 1) by the nearest rank at or above it, numpy's 'higher'
    method (one partition: a quarter of np.percentile's time on 8,192 values)."""
    rank = math.ceil(0.99 * (len(values) - 1))
    return float(np.partition(values, rank)[rank])


@ILLUMINANT_CORRECTIONS.register("gray_pixels")
def _gray_pixels(flat, to_ics, white, white_world_fraction, manual_gains, saturated):
    """Gray world over the pixels that are nearly grey once corrected (r, g, b chromaticity within
    a tolerance of the white's), iterated from gray world with a tolerance that narrows each round,
    so a scene whose mean is coloured (a Macbeth chart, a red wall) does not tint its greys."""
    step = max(1, len(flat) // GREY_PIXEL_SAMPLES)                # an even subsample is statistic enough
    flat = np.ascontiguousarray(flat, dtype=np.float32)
    to_ics = np.ascontiguousarray(to_ics, dtype=np.float64)
    ics, sums = _sample_ics(flat, step, saturated, to_ics)
    saturation_notes = []
    if not len(ics) and len(flat):
        saturation_notes = ["gray_pixels: every pixel is saturated; the statistic uses them all"]
        ics, sums = _sample_ics(flat, step, math.inf, to_ics)
    gains, notes = _gains_to_white("gray_pixels", sums / max(len(ics), 1), white)
    target = white / white.sum()
    lit_totals = ics @ gains                       # by the first round's gains: not the darkest
    lit = lit_totals > 0.02 * _percentile_99(lit_totals) if len(ics) else np.zeros(0, bool)
    for tolerance in GREY_PIXEL_TOLERANCES:        # (noise) pixels
        sums, count = kernels.grey_pixel_sums(ics, lit, gains, target, tolerance)
        if count < GREY_PIXEL_MIN_SHARE * len(ics):
            notes.append(f"gray_pixels: fewer than {100 * GREY_PIXEL_MIN_SHARE:g} % of the pixels are near grey; "
                         "gray world over all of them")
            break
        gains, notes = _gains_to_white("gray_pixels", sums / count, white)
    return gains, saturation_notes + notes


@ILLUMINANT_CORRECTIONS.register("white_world")
def _white_world(flat, to_ics, white, white_world_fraction, manual_gains, saturated):
    """The mean of the pixels ≥ white_world_fraction × max of the brightest ics channel gets it
    (compiled passes over row blocks: the maxima, then the sums; no masked copies of the frame)."""
    to_ics = np.ascontiguousarray(to_ics, dtype=np.float64)
    ics = np.empty((len(flat), 3))                 # NaN rows: saturated pixels

    def maxima(limit):
        return map_row_blocks(lambda _i, rows: kernels.ics_maxima(flat[rows], to_ics, limit, ics[rows]),
                              len(flat), len(flat))
    notes = []
    parts = maxima(saturated)
    if sum(valid for _top, valid in parts) == 0 and len(flat) and saturated != math.inf:
        notes.append("white_world: every pixel is saturated; the statistic uses them all")
        parts = maxima(math.inf)
    top = np.max([top for top, _valid in parts], axis=0)
    channel = int(np.argmax(top))
    threshold = white_world_fraction * top[channel]
    parts = map_row_blocks(lambda _i, rows: kernels.bright_sums(ics[rows], channel, threshold), len(flat), len(flat))
    sums = np.sum([part for part, _n in parts], axis=0)      # fixed blocks, fixed order: thread-independent
    gains, more = _gains_to_white("white_world", sums / max(sum(n for _part, n in parts), 1), white)
    return gains, notes + more


@ILLUMINANT_CORRECTIONS.register("manual")
def _manual(flat, to_ics, white, white_world_fraction, manual_gains, saturated):
    """The user's gains."""
    gains = np.asarray(manual_gains, dtype=np.float64)
    if gains.shape != (3,) or not np.all(np.isfinite(gains)) or np.any(gains <= 0):
        raise InvalidValueError(f"manual_gains must be three positive numbers, got {manual_gains}")
    return gains, []


def illuminant_gains(linear: np.ndarray, to_ics: np.ndarray, method: str, white: np.ndarray, *,
                     white_world_fraction: float = 0.7, manual_gains: tuple[float, ...] = (1.0, 1.0, 1.0),
                     saturated: float | None = None) -> tuple[np.ndarray, list[str]]:
    """Gains (3,) for the internal colour space ics = linear @ to_ics that correct the illuminant.

    linear: H×W×K sensor channels; to_ics: K×3 matrix into the internal colour space (XYZ, or
    a channel selection). method: a name in ILLUMINANT_CORRECTIONS: 'none' (ones), 'gray_world'
    (the image mean gets the chromaticity of `white`), 'white_world' (the mean of the pixels ≥
    white_world_fraction × max of the brightest ics channel gets it), 'manual' (manual_gains).
    white: the output white in the internal space (3,), e.g. the XYZ of sRGB's D65 white.
    saturated: pixels whose brightest channel is at or above this are left out of the statistics
    (their colour is the clipping's, not the scene's); when every pixel is, all are used, with a note.
    Returns (gains, notes); a zero statistic leaves the image unchanged, with a note."""
    correct = ILLUMINANT_CORRECTIONS[method]
    k = linear.shape[-1]
    if linear.ndim != 3 or to_ics.shape != (k, 3):
        raise InvalidValueError(f"illuminant correction needs an H×W×K image and a K×3 matrix, got "
                         f"shapes {linear.shape} and {to_ics.shape}")
    flat = linear.reshape(-1, k)
    return correct(flat, to_ics, np.asarray(white, dtype=np.float64), white_world_fraction, manual_gains,
                   math.inf if saturated is None else float(saturated))
