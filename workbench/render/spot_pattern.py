"""What a Mitsuba `spot` emitter dict (lamps.spot_emitter, lamps.headlight_emitter) sheds toward a
direction, in numpy, for the light-selection weights (lamps.view_light_weights, render/lamp_set.py):
its peak luminous intensity, its local frame, and its relative intensity — Mitsuba's linear falloff
between beam_width and cutoff_angle times its projection texture, if it has one.

A texture is looked up as Mitsuba's spot does (uv = ½ + ½ (x, y)/(z tan cutoff) in the spot's frame:
x left, y up, z along the axis). For weights, which must not miss light, coarse_tables max-pools a
texture onto a small grid, and dilates it for directions known only to within an angle.
"""
from __future__ import annotations

import numpy as np

from workbench.spectra import luminous_efficiency
from workbench.units import MAX_LUMINOUS_EFFICACY_LM_W
COARSE_TEXELS = 128            # the coarse tables' texels each way
COARSE_LEVELS = 8              # dilations by 2^j texels, j < COARSE_LEVELS


def peak_cd(emitter: dict) -> float:
    """Peak luminous intensity (cd) of a spot dict: 683 lm/W ∫ I(λ) V(λ) dλ of its intensity."""
    wl, v = (np.array(x, dtype=np.float64) for x in zip(*emitter["intensity"]["value"]))
    return float(MAX_LUMINOUS_EFFICACY_LM_W * np.trapezoid(v * luminous_efficiency(wl), wl))


def frame(emitter: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(position, left, up, axis) of a spot dict's to_world (columns 3, 0, 1, 2; unit vectors)."""
    m = np.array(emitter["to_world"].matrix, dtype=np.float64)
    unit = [m[:3, i] / np.linalg.norm(m[:3, i]) for i in range(3)]
    return m[:3, 3], unit[0], unit[1], unit[2]


_DATA: dict[int, tuple[object, np.ndarray]] = {}     # id(texture) → (texture, its texels): read once


def texture_data(texture) -> np.ndarray:
    """A loaded Mitsuba bitmap texture's texels (rows × columns, the first channel, float64)."""
    import mitsuba as mi

    held = _DATA.get(id(texture))
    if held is None or held[0] is not texture:
        data = np.array(mi.traverse(texture)["data"], dtype=np.float64)
        held = _DATA[id(texture)] = (texture, data[..., 0] if data.ndim == 3 else data)
    return held[1]


def _texel(data: np.ndarray, uv: np.ndarray) -> np.ndarray:
    rows, cols = data.shape
    j = np.clip((uv[..., 0] * cols).astype(np.int64), 0, cols - 1)
    i = np.clip((uv[..., 1] * rows).astype(np.int64), 0, rows - 1)
    return data[i, j]


def relative_intensity(emitter: dict, directions: np.ndarray, data: np.ndarray | None = None) -> np.ndarray:
    """Relative intensity (0–1) of a spot dict toward unit world directions (N×3, from the lamp):
    the linear falloff × the texture's nearest texel (`data`: texture_data of its texture, read if
    None)."""
    _, left, up, axis = frame(emitter)
    d = np.asarray(directions, dtype=np.float64)
    z = d @ axis
    cut, beam = np.radians(float(emitter["cutoff_angle"])), np.radians(float(emitter["beam_width"]))
    ang = np.arccos(np.clip(z, -1.0, 1.0))
    fall = np.where(ang <= beam, 1.0, np.clip((cut - ang) / max(cut - beam, 1e-9), 0.0, 1.0))
    fall = np.where(z > np.cos(cut), fall, 0.0)
    if "texture" not in emitter:
        return fall
    data = texture_data(emitter["texture"]) if data is None else data
    f = np.tan(cut)
    zs = np.where(z > 1e-9, z, 1.0)
    uv = 0.5 + 0.5 * np.stack([d @ left, d @ up], -1) / (zs[:, None] * f)
    return np.where(z > 1e-9, fall * _texel(data, uv), 0.0)


def coarse_tables(data: np.ndarray, texels: int = COARSE_TEXELS, levels: int = COARSE_LEVELS) -> np.ndarray:
    """levels × texels × texels tables: level 0 the texture max-pooled onto texels × texels cells
    and dilated by one cell (so a nearest lookup bounds the bilinear texture near it), level j that
    dilated by 2^j cells (square max filter)."""
    from scipy.ndimage import maximum_filter

    rows, cols = data.shape
    ri = np.minimum(np.arange(rows) * texels // rows, texels - 1)
    ci = np.minimum(np.arange(cols) * texels // cols, texels - 1)
    pooled = np.zeros((texels, texels))
    np.maximum.at(pooled, (ri[:, None], ci[None, :]), data)
    out = [maximum_filter(pooled, size=3, mode="nearest")]
    for j in range(1, levels):
        out.append(maximum_filter(out[0], size=2 * 2 ** j + 1, mode="nearest"))
    return np.stack(out)


def coarse_bound(tables: np.ndarray, cutoff_deg: float, local: np.ndarray, radius_rad: np.ndarray) -> np.ndarray:
    """An upper bound of the texture over the directions within radius_rad of the local directions
    `local` (…×3: left, up, axis; any length) from coarse_tables: the gnomonic map stretches an
    angle α at θ off the axis by at most sec²(θ + α), so the dilation level is the first whose half
    width covers α sec²(θ + α); 1 where that reaches the cut-off or the table's top level."""
    levels, texels = tables.shape[0], tables.shape[1]
    f = np.tan(np.radians(cutoff_deg))
    norm = np.linalg.norm(local, axis=-1)
    z = local[..., 2] / np.maximum(norm, 1e-12)
    theta = np.arccos(np.clip(z, -1.0, 1.0))
    reach = theta + radius_rad
    ok = reach < np.radians(min(cutoff_deg, 89.0))
    half_cells = np.where(ok, radius_rad / np.cos(np.where(ok, reach, 0.0)) ** 2 / (2.0 * f / texels), 1.0)
    level = np.where(ok, np.ceil(np.log2(np.maximum(half_cells, 1.0))), levels).astype(np.int64)
    zs = np.where(ok, local[..., 2], 1.0)
    uv = 0.5 + 0.5 * local[..., :2] / (zs[..., None] * f)
    j = np.clip((uv[..., 0] * texels).astype(np.int64), 0, texels - 1)
    i = np.clip((uv[..., 1] * texels).astype(np.int64), 0, texels - 1)
    value = tables[np.clip(level, 0, levels - 1), i, j]
    return np.where(ok & (level < levels), value, 1.0)
