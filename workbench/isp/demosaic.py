"""Demosaicing: a CFA mosaic (H×W) → one full-resolution plane per channel (H×W×K).

Every method keeps its output within the range of the mosaic's values.

`DEMOSAIC_METHODS` maps a name to fn(mosaic, cfa_tile, n_channels, channel_names) -> (planes,
notes). 'bilinear' is our own normalised convolution with the tent kernel [1 2 1]ᵀ[1 2 1]
(mirror borders): on a Bayer tile it is the bilinear demosaic of ISETCam's ieBilinear and of
colour-demosaicing (identical in the interior; at the outermost pixels we mirror without repeating
the edge, which keeps the CFA phase, where colour-demosaicing's scipy 'reflect' does not), and it
works for any CFA tile (RCCC, RCCB, RGBW, MONO, larger periods).
'malvar2004' and 'menon2007' call colour-demosaicing and need a 2×2 Bayer tile; on other CFAs
they fall back to bilinear and say so.
"""
from __future__ import annotations

import warnings
from functools import lru_cache
from typing import Callable

import numpy as np

from workbench.errors import InvalidValueError
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
    output stays within the data range. 2×2 tiles take the fast phase-plane route, larger tiles
    the full-resolution convolution (same result). Returns (H×W×K float32, notes)."""
    mosaic, tile = _check_inputs(mosaic, cfa_tile, n_channels)
    if n_channels == 1:
        return mosaic[..., None].copy(), []
    if tile.shape == (2, 2):
        return bilinear_phase_planes(mosaic, tile, n_channels), []
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


def bilinear_phase_planes(mosaic: np.ndarray, tile: np.ndarray, n_channels: int) -> np.ndarray:
    """The same normalised tent convolution for a 2×2 tile, computed on quarter-size phase planes.

    Mirror borders keep the CFA phase, so every missing value is the tent-weighted mean (2 for
    edge, 1 for diagonal neighbours) of the same-channel samples among its 8 neighbours; on the
    phase planes mirror padding of the mosaic is edge padding. Odd sizes are mirror-padded to
    even and cropped."""
    h, w = mosaic.shape
    if h % 2 or w % 2:
        even = np.pad(mosaic, ((0, h % 2), (0, w % 2)), mode="reflect")
        return np.ascontiguousarray(bilinear_phase_planes(even, tile, n_channels)[:h, :w])
    hq, wq = h // 2, w // 2
    phases = {(r, c): np.pad(mosaic[r::2, c::2], 1, mode="edge") for r in (0, 1) for c in (0, 1)}
    out = np.empty((h, w, n_channels), dtype=np.float32)
    for k in range(n_channels):
        for tr in (0, 1):
            for tc in (0, 1):
                if tile[tr, tc] == k:
                    out[tr::2, tc::2, k] = mosaic[tr::2, tc::2]
                    continue
                sums: dict[int, np.ndarray] = {}      # tent weight (1 or 2) → sum of those neighbours
                total = 0
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        sr, sc = (tr + dy) % 2, (tc + dx) % 2
                        if (dy, dx) == (0, 0) or tile[sr, sc] != k:
                            continue
                        oy, ox = (tr + dy - sr) // 2, (tc + dx - sc) // 2
                        view = phases[sr, sc][1 + oy:1 + oy + hq, 1 + ox:1 + ox + wq]
                        weight = (2 - abs(dy)) * (2 - abs(dx))
                        total += weight
                        if weight in sums:
                            sums[weight] += view
                        else:
                            sums[weight] = view.copy()
                value = None
                for weight, part in sums.items():
                    part *= np.float32(weight / total)
                    value = part if value is None else np.add(value, part, out=value)
                out[tr::2, tc::2, k] = value
    return out


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
DEMOSAIC_METHODS.register("malvar2004")(_colour_demosaicing("demosaicing_CFA_Bayer_Malvar2004"))
DEMOSAIC_METHODS.register("menon2007")(_colour_demosaicing("demosaicing_CFA_Bayer_Menon2007"))


def demosaic(mosaic: np.ndarray, cfa_tile: np.ndarray, channel_names: list[str],
             method: str = "bilinear") -> tuple[np.ndarray, list[str]]:
    """Demosaic with a registered method; returns (H×W×K float32, notes)."""
    return DEMOSAIC_METHODS[method](mosaic, cfa_tile, len(channel_names), list(channel_names))
