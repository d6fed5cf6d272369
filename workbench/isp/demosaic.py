"""Demosaicing: a CFA mosaic (H×W) → one full-resolution plane per channel (H×W×K).

Every method keeps its output within the range of the mosaic's values.

`DEMOSAIC_METHODS` maps a name to fn(mosaic, cfa_tile, n_channels, channel_names) -> (planes,
notes). 'bilinear' is our own normalised convolution with the tent kernel [1 2 1]ᵀ[1 2 1]
(mirror borders): on a Bayer tile it is the bilinear demosaic of ISETCam's ieBilinear and of
colour-demosaicing (identical in the interior; at the outermost pixels we mirror without repeating
the edge, which keeps the CFA phase, where colour-demosaicing's scipy 'reflect' does not), and it
works for any CFA tile (RCCC, RCCB, RGBW, MONO, larger periods).
'malvar2004' is our compiled Malvar–He–Cutler filter set (colour-demosaicing's filters, tested
against it; mirrored borders as for bilinear), 'menon2007' calls colour-demosaicing; both need a
2×2 Bayer tile and on other CFAs fall back to bilinear and say so.
"""
from __future__ import annotations

import warnings
from functools import lru_cache
from typing import Callable

import numpy as np

from workbench.compute.pixel_threads import map_row_blocks
from workbench.errors import InvalidValueError
from workbench.isp import kernels
from workbench.registry import Registry

BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


def _tent(radius: int) -> np.ndarray:
    return np.concatenate([np.arange(1, radius + 2), np.arange(radius, 0, -1)]).astype(np.float32)


def _separable_tent(plane: np.ndarray, radius: int) -> np.ndarray:
    """Convolve an H×W float32 plane with tent(radius)ᵀ·tent(radius), mirror borders."""
    weights = _tent(radius)
    padded = np.pad(plane, radius, mode="reflect")
    h, w = plane.shape
    rows = padded[radius:radius + h, :] * weights[radius]
    for i in range(weights.size):
        if i != radius:
            rows += padded[i:i + h, :] if weights[i] == 1 else weights[i] * padded[i:i + h, :]
    out = rows[:, radius:radius + w] * weights[radius]
    for j in range(weights.size):
        if j != radius:
            out += rows[:, j:j + w] if weights[j] == 1 else weights[j] * rows[:, j:j + w]
    return out


@lru_cache(maxsize=32)
def _inverse_weights(shape: tuple[int, int], tile_bytes: bytes, tile_shape: tuple[int, int],
                     k: int) -> np.ndarray:
    """1 / (tent-convolved mask of channel k): the normalisation of the normalised convolution."""
    tile = np.frombuffer(tile_bytes, dtype=np.int64).reshape(tile_shape)
    mask = _channel_mask(shape, tile, k).astype(np.float32)
    den = _separable_tent(mask, max(tile_shape) - 1)
    if np.any(den <= 0):
        raise InvalidValueError(f"CFA channel {k} has pixels with no sample of it within the kernel; "
                         f"tile {tile.tolist()} is not supported by bilinear demosaicing")
    out = (1.0 / den).astype(np.float32)
    out.setflags(write=False)
    return out


def _channel_mask(shape: tuple[int, int], tile: np.ndarray, k: int) -> np.ndarray:
    h, w = shape
    th, tw = tile.shape
    return np.tile(tile == k, (h // th + 1, w // tw + 1))[:h, :w]


def _check_inputs(mosaic: np.ndarray, cfa_tile: np.ndarray, n_channels: int) -> tuple[np.ndarray, np.ndarray]:
    mosaic = np.asarray(mosaic, dtype=np.float32)
    tile = np.asarray(cfa_tile, dtype=np.int64)
    if mosaic.ndim != 2 or min(mosaic.shape) < 2:
        raise InvalidValueError(f"demosaic needs an H×W mosaic with H, W ≥ 2, got shape {mosaic.shape}")
    if tile.ndim != 2 or tile.size == 0:
        raise InvalidValueError(f"cfa_tile must be a 2-D integer array, got shape {tile.shape}")
    if tile.shape[0] > mosaic.shape[0] or tile.shape[1] > mosaic.shape[1]:
        raise InvalidValueError(f"cfa_tile {tile.shape} is larger than the mosaic {mosaic.shape}")
    present = set(np.unique(tile).tolist())
    if present != set(range(n_channels)):
        raise InvalidValueError(f"cfa_tile holds channel indices {sorted(present)}, but the sensor has "
                         f"{n_channels} channels (every index 0..{n_channels - 1} must appear)")
    return mosaic, tile


def demosaic_bilinear(mosaic: np.ndarray, cfa_tile: np.ndarray, n_channels: int,
                      channel_names: list[str] | None = None) -> tuple[np.ndarray, list[str]]:
    """Bilinear demosaic of any CFA by normalised convolution; measured samples are kept.

    Each missing value is a positively weighted mean of nearby samples of its channel, so the
    output stays within the data range. 2×2 tiles take the compiled route, larger tiles
    the full-resolution convolution (same result). Returns (H×W×K float32, notes)."""
    mosaic, tile = _check_inputs(mosaic, cfa_tile, n_channels)
    if n_channels == 1:
        return mosaic[..., None].copy(), []
    if tile.shape == (2, 2):
        return bilinear_2x2_tile(mosaic, tile, n_channels), []
    return bilinear_tent_convolution(mosaic, tile, n_channels), []


def bilinear_tent_convolution(mosaic: np.ndarray, tile: np.ndarray, n_channels: int) -> np.ndarray:
    """Normalised convolution of each channel's samples with the tent kernel of the tile's period
    (mirror borders), measured samples kept. Any tile; H×W float32 in, H×W×K out."""
    h, w = mosaic.shape
    th, tw = tile.shape
    radius = max(th, tw) - 1
    out = np.empty((h, w, n_channels), dtype=np.float32)
    for k in range(n_channels):
        sites = [(r, c) for r in range(th) for c in range(tw) if tile[r, c] == k]
        sparse = np.zeros((h, w), dtype=np.float32)
        for r, c in sites:
            sparse[r::th, c::tw] = mosaic[r::th, c::tw]
        plane = _separable_tent(sparse, radius)
        plane *= _inverse_weights((h, w), tile.tobytes(), tile.shape, k)
        for r, c in sites:
            plane[r::th, c::tw] = mosaic[r::th, c::tw]
        out[..., k] = plane
    return out


@lru_cache(maxsize=32)
def _bilinear_coefficients(tile_bytes: bytes, n_channels: int) -> np.ndarray:
    """coef (4 phases × K × 6) of kernels.demosaic_2x2 for a 2×2 tile: for each phase and
    channel, the weights of its neighbour groups — the channel's samples among the 8 neighbours
    with the tent weights (2 for edge, 1 for diagonal neighbours) normalised to sum 1, or the
    pixel itself where it measured the channel."""
    tile = np.frombuffer(tile_bytes, dtype=np.int64).reshape(2, 2)
    coef = np.zeros((4, n_channels, 6), dtype=np.float32)
    for ty in (0, 1):
        for tx in (0, 1):
            p = 2 * ty + tx
            for k in range(n_channels):
                if tile[ty, tx] == k:
                    coef[p, k, 0] = 1.0
                    continue
                # (group, tent weight of each member, members) of the neighbour groups holding k
                groups = [(g, wt, n) for g, wt, n, phase in ((1, 2.0, 2, tile[ty, 1 - tx]), (2, 2.0, 2, tile[1 - ty, tx]),
                                                             (3, 1.0, 4, tile[1 - ty, 1 - tx])) if phase == k]
                total = sum(wt * n for _, wt, n in groups)
                for g, wt, _ in groups:
                    coef[p, k, g] = wt / total          # applied to the group's sum
    coef.setflags(write=False)
    return coef


def bilinear_2x2_tile(mosaic: np.ndarray, tile: np.ndarray, n_channels: int) -> np.ndarray:
    """The same normalised tent convolution for a 2×2 tile (H×W×K), one compiled pass per row
    block (in threads for large frames)."""
    h, w = mosaic.shape
    mosaic = np.ascontiguousarray(mosaic, dtype=np.float32)
    coef = _bilinear_coefficients(np.ascontiguousarray(tile, dtype=np.int64).tobytes(), n_channels)
    out = np.empty((h, w, n_channels), dtype=np.float32)
    map_row_blocks(lambda _, rows: kernels.demosaic_2x2(mosaic, coef, False, rows.start, rows.stop, out), h, h * w)
    return out


# Malvar, He & Cutler (2004) filters as weights (×8) of (centre, horizontal pair, vertical pair,
# four diagonals, horizontal pair at 2, vertical pair at 2): the green filter at red and blue
# sites, red/blue at a green site whose horizontal (or vertical) neighbours hold it, and red at
# blue / blue at red sites.
MALVAR_GREEN = (4.0, 2.0, 2.0, 0.0, -1.0, -1.0)
MALVAR_ACROSS = (5.0, 4.0, 0.0, -1.0, -1.0, 0.5)
MALVAR_ALONG = (5.0, 0.0, 4.0, -1.0, 0.5, -1.0)
MALVAR_DIAGONAL = (6.0, 0.0, 0.0, 2.0, -1.5, -1.5)


@lru_cache(maxsize=32)
def _malvar_coefficients(tile_bytes: bytes) -> np.ndarray:
    """coef (4 phases × 3 × 6) of kernels.demosaic_2x2 for a 2×2 Bayer tile (channel indices)."""
    tile = np.frombuffer(tile_bytes, dtype=np.int64).reshape(2, 2)
    green = int(np.bincount(tile.ravel()).argmax())          # the channel on the tile's diagonal
    coef = np.zeros((4, 3, 6), dtype=np.float32)
    for ty in (0, 1):
        for tx in (0, 1):
            p = 2 * ty + tx
            for k in range(3):
                if tile[ty, tx] == k:
                    coef[p, k, 0] = 1.0
                    continue
                weights = (MALVAR_GREEN if k == green else MALVAR_ACROSS if tile[ty, 1 - tx] == k
                           else MALVAR_ALONG if tile[1 - ty, tx] == k else MALVAR_DIAGONAL)
                coef[p, k] = np.asarray(weights) / 8.0
    coef.setflags(write=False)
    return coef


def demosaic_malvar2004(mosaic: np.ndarray, cfa_tile: np.ndarray, n_channels: int,
                        channel_names: list[str] | None = None) -> tuple[np.ndarray, list[str]]:
    """Malvar–He–Cutler (2004) gradient-corrected linear demosaic of a 2×2 Bayer R/G/B tile, one
    compiled pass per row block (colour-demosaicing's
    demosaicing_CFA_Bayer_Malvar2004 is the same filters with edge-repeating borders, where we
    mirror and keep the CFA phase; kernels.demosaic_2x2); clipped to the mosaic's range (the gradient terms can
    overshoot). Other CFAs: bilinear, with a note."""
    names = list(channel_names or [])
    if bayer_pattern(cfa_tile, names) is None:
        planes, notes = demosaic_bilinear(mosaic, cfa_tile, n_channels, names)
        return planes, notes + [f"malvar2004 needs a 2×2 Bayer R/G/B tile; channels {names} with tile "
                                f"{np.asarray(cfa_tile).tolist()} were demosaiced bilinearly"]
    mosaic, tile = _check_inputs(mosaic, cfa_tile, n_channels)
    h, w = mosaic.shape
    if min(h, w) < 3:                      # the 5×5 filters need 3 pixels to mirror into
        return demosaic_bilinear(mosaic, tile, n_channels, names)
    mosaic = np.ascontiguousarray(mosaic, dtype=np.float32)
    coef = _malvar_coefficients(np.ascontiguousarray(tile, dtype=np.int64).tobytes())
    out = np.empty((h, w, 3), dtype=np.float32)
    map_row_blocks(lambda _, rows: kernels.demosaic_2x2(mosaic, coef, True, rows.start, rows.stop, out), h, h * w)
    np.clip(out, mosaic.min(), mosaic.max(), out=out)
    return out, []


def bayer_pattern(cfa_tile: np.ndarray, channel_names: list[str]) -> str | None:
    """The colour-demosaicing pattern name ('RGGB', …) of a 2×2 R/G/B tile, else None."""
    tile = np.asarray(cfa_tile)
    names = [n.upper() for n in channel_names]
    if tile.shape != (2, 2) or sorted(names) != ["B", "G", "R"]:
        return None
    name = "".join(names[int(i)] for i in tile.ravel())
    return name if name in BAYER_PATTERNS else None


def _colour_demosaicing(fn_name: str) -> Callable:
    def method(mosaic, cfa_tile, n_channels, channel_names=None):
        names = list(channel_names or [])
        pattern = bayer_pattern(cfa_tile, names)
        if pattern is None:
            planes, notes = demosaic_bilinear(mosaic, cfa_tile, n_channels, names)
            return planes, notes + [f"{fn_name} needs a 2×2 Bayer R/G/B tile; channels {names} with "
                                    f"tile {np.asarray(cfa_tile).tolist()} were demosaiced bilinearly"]
        mosaic, _ = _check_inputs(mosaic, cfa_tile, n_channels)
        with warnings.catch_warnings():     # its scipy.ndimage.filters import is deprecated
            warnings.simplefilter("ignore", DeprecationWarning)
            import colour_demosaicing
        rgb = getattr(colour_demosaicing, fn_name)(mosaic, pattern)
        order = ["RGB".index(n.upper()) for n in names]
        planes = np.ascontiguousarray(rgb[..., order], dtype=np.float32)
        # these methods add gradient corrections that can overshoot the data range
        np.clip(planes, mosaic.min(), mosaic.max(), out=planes)
        return planes, []
    method.__name__ = f"demosaic_{fn_name}"
    method.__doc__ = f"Bayer demosaic by colour_demosaicing.{fn_name} (bilinear on other CFAs)."
    return method


DEMOSAIC_METHODS: Registry[Callable] = Registry("isp.demosaic", "demosaic method")
DEMOSAIC_METHODS.register("bilinear")(demosaic_bilinear)
DEMOSAIC_METHODS.register("malvar2004")(demosaic_malvar2004)
DEMOSAIC_METHODS.register("menon2007")(_colour_demosaicing("demosaicing_CFA_Bayer_Menon2007"))


def demosaic(mosaic: np.ndarray, cfa_tile: np.ndarray, channel_names: list[str],
             method: str = "bilinear") -> tuple[np.ndarray, list[str]]:
    """Demosaic with a registered method; returns (H×W×K float32, notes)."""
    return DEMOSAIC_METHODS[method](mosaic, cfa_tile, len(channel_names), list(channel_names))
