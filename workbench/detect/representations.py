"""Network inputs for the paper's three image representations (numpy only).

Fixed scaling, never per-image normalisation (which would erase the exposure bias being studied):
    raw     the mosaic as (DN − black level) / (max DN − black level), clipped to [0, 1] — no white
            balance, no gamma — packed to 4 × H/2 × W/2 (pack_raw); input stride 2.
    linear  the ISP's demosaiced sensor channels (ISPResult.linear, the same scaling), K × H × W.
    srgb    the ISP's sRGB in [0, 1] (the full pipeline), 3 × H × W.
The raw scaling is the one the ISP demosaics, so 'linear' is exactly the demosaic of 'raw'.

Packed-raw plane order (pack_raw, for every 2×2 pattern: CFA_PATTERNS and their mirror images): the four sites of the 2×2
tile sorted by channel letter in the sensor's order R, G, B, C, W, M; sites with the same letter in the
order: same row as plane 0's site, same column, diagonal. Every Bayer phase therefore packs as
(R, G on the red row, G on the red column, B); RCCB as (R, B, C, C); RCCC as (R, C, C, C);
RGBW as (R, G, B, W); MONO as the sites (0,0), (0,1), (1,0), (1,1). (Training mirrors the scene
before the CFA samples it, workbench.detect.data, so no packed mosaic is ever flipped.)
"""
from __future__ import annotations

import numpy as np

from workbench.errors import ParameterError
from workbench.isp.process import BLACK_LEVEL_KEY, REPRESENTATIONS
from workbench.sensor.cfa import cfa_layout
from workbench.sensor.params import CFA_PATTERNS

_LETTER_ORDER = "RGBCWM"


def input_stride(representation: str) -> int:
    """Pixels of the image per input pixel: 2 for packed raw, 1 for linear and sRGB."""
    _check_representation(representation)
    return 2 if representation == "raw" else 1


def input_channels(representation: str, cfa_pattern: str) -> int:
    """C of network_input: 4 (raw), the sensor's channel count (linear), 3 (srgb)."""
    _check_representation(representation)
    if representation == "raw":
        return 4
    return len(cfa_layout(cfa_pattern)[1]) if representation == "linear" else 3


def packed_sites(cfa_pattern: str) -> list[tuple[int, int]]:
    """(row, col) in the 2×2 tile of each packed-raw plane, in plane order (module docstring)."""
    try:
        tile, names = cfa_layout(cfa_pattern)
    except ValueError:
        raise ParameterError("cfa_pattern", cfa_pattern,
                             f"a 2×2 pattern such as {', '.join(CFA_PATTERNS)}") from None
    sites = [(r, c) for r in range(2) for c in range(2)]
    letter = {s: names[tile[s]] for s in sites}
    first = min(sites, key=lambda s: _LETTER_ORDER.index(letter[s]))
    return sorted(sites, key=lambda s: (_LETTER_ORDER.index(letter[s]), s[0] != first[0], s[1] != first[1]))


def packed_channel_names(cfa_pattern: str) -> list[str]:
    """Channel letter of each packed-raw plane, e.g. ['R', 'G', 'G', 'B'] for every Bayer phase."""
    sites = packed_sites(cfa_pattern)
    tile, names = cfa_layout(cfa_pattern)
    return [names[tile[s]] for s in sites]


def pack_raw(mosaic: np.ndarray, cfa_pattern: str) -> np.ndarray:
    """H×W mosaic (H, W even) → 4×H/2×W/2, planes in packed_sites order; exact (no arithmetic)."""
    mosaic = np.asarray(mosaic)
    if mosaic.ndim != 2 or mosaic.shape[0] % 2 or mosaic.shape[1] % 2 or min(mosaic.shape) < 2:
        raise ParameterError("mosaic", tuple(mosaic.shape), "an H×W array with H and W even (≥ 2)")
    return np.stack([mosaic[r::2, c::2] for r, c in packed_sites(cfa_pattern)])


def unpack_raw(packed: np.ndarray, cfa_pattern: str) -> np.ndarray:
    """The exact inverse of pack_raw: 4×h×w → 2h×2w mosaic."""
    packed = np.asarray(packed)
    if packed.ndim != 3 or packed.shape[0] != 4:
        raise ParameterError("packed", tuple(packed.shape), "a 4×h×w array from pack_raw")
    mosaic = np.empty((2 * packed.shape[1], 2 * packed.shape[2]), dtype=packed.dtype)
    for plane, (r, c) in zip(packed, packed_sites(cfa_pattern)):
        mosaic[r::2, c::2] = plane
    return mosaic


def raw_scaled(sensor_image) -> np.ndarray:
    """H×W float32 (DN − black level) / (max DN − black level), clipped to [0, 1] (the ISP's scaling)."""
    black = np.float32(sensor_image.meta.get(BLACK_LEVEL_KEY, 0.0))
    scale = np.float32(1.0) / (np.float32(sensor_image.max_dn) - black)
    return np.clip((np.asarray(sensor_image.dn, dtype=np.float32) - black) * scale, 0.0, 1.0)


def network_input(sensor_image, isp_result, representation: str) -> np.ndarray:
    """C×h×w float32 input of one frame (module docstring); isp_result may be None for 'raw'."""
    _check_representation(representation)
    if representation == "raw":
        return pack_raw(raw_scaled(sensor_image), sensor_image.pattern)
    if isp_result is None:
        raise ParameterError("isp_result", None, f"an ISPResult for representation '{representation}'")
    image = isp_result.linear if representation == "linear" else isp_result.srgb
    return np.ascontiguousarray(np.moveaxis(np.asarray(image, dtype=np.float32), 2, 0))


def _check_representation(representation: str) -> None:
    if representation not in REPRESENTATIONS:
        raise ParameterError("representation", representation, f"one of {', '.join(REPRESENTATIONS)}")
