"""The sensor's output: what the ISP consumes."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SensorImage:
    """One simulated exposure.

    electrons: H×W float32 collected electrons (after shot noise, before read noise).
    volts: H×W float32 pixel voltage after noise, gain/offset and clipping (V).
    dn: H×W float32 digital numbers (quantised; equals volts when bit_depth is 0 = analog).
    cfa_tile: (2, 2) int array, index into channel_names of the pixel at (row % 2, col % 2).
        (Patterns with a larger period use a larger tile; row r, col c has channel
        cfa_tile[r % tile_rows, c % tile_cols].)
    channel_names: e.g. ['R', 'G', 'B'], ['R', 'C'], ['R', 'G', 'B', 'W'], ['M'].
    pattern: the CFA name, e.g. 'RGGB', 'RCCC', 'MONO'.
    qe: Nλ×K effective quantum efficiency per channel (filter × IR cut × photodiode), unitless.
    wavelengths_nm: the Nλ wavelengths of qe.
    exposure_s: exposure time (s); a scalar, or a tile-shaped array for per-CFA exposure.
    max_dn: the largest code (2**bits − 1), or the voltage swing (V) for an analog read-out.
    """

    electrons: np.ndarray
    volts: np.ndarray
    dn: np.ndarray
    cfa_tile: np.ndarray
    channel_names: list[str]
    pattern: str
    qe: np.ndarray
    wavelengths_nm: np.ndarray
    exposure_s: float | np.ndarray
    max_dn: float
    meta: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.dn.shape

    def channel_mask(self, k: int) -> np.ndarray:
        """Boolean H×W mask of the pixels of channel k."""
        h, w = self.shape
        th, tw = self.cfa_tile.shape
        tile = self.cfa_tile == k
        return np.tile(tile, (h // th + 1, w // tw + 1))[:h, :w]
