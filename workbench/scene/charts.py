"""Analytic test charts: uniform field, Macbeth ColorChecker, slanted edge, HDR tunnel.

Every chart returns a `Scene` in photons/s/sr/m²/nm. `size` is (rows, cols) of scene samples,
`fov_deg` the horizontal field of view they span. These are the oracles later stages are
checked with, so their radiance is set exactly (no noise, no texture).
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench import spectra
from workbench.registry import Registry
from workbench.scene.types import Scene

CHARTS: Registry = Registry("scene.kind", "chart")
"""The analytic charts: scene kind → fn(…, size, fov_deg, distance_m, wavelengths_nm) -> Scene."""


def _illuminant_photons(illuminant: str, wavelengths_nm: np.ndarray, luminance_cd_m2: float) -> np.ndarray:
    """Radiance (photons/s/sr/m²/nm) of a perfect white diffuser under the illuminant."""
    spd = spectra.illuminant_spd(illuminant, wavelengths_nm)
    return spectra.spd_photons_for_luminance(spd, wavelengths_nm, luminance_cd_m2)


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    rows, cols = (int(size[0]), int(size[1]))
    if rows < 1 or cols < 1:
        raise InvalidValueError(f"scene size must be at least 1×1 samples, got {rows}×{cols}")
    if rows * cols > 64_000_000:
        raise InvalidValueError(f"scene of {rows}×{cols} samples is too large (limit 64 M samples); "
                         "lower the resolution or the oversampling")
    return rows, cols


def plane_depth_m(size: tuple[int, int], fov_deg: float, distance_m: float) -> np.ndarray:
    """Distance (m) along each sample's ray to a fronto-parallel plane at distance_m."""
    rows, cols = size
    t = 2 * np.tan(np.radians(fov_deg) / 2) / cols            # tangent per sample
    x = (np.arange(cols) + 0.5 - cols / 2) * t
    y = (np.arange(rows) + 0.5 - rows / 2) * t
    return (distance_m * np.sqrt(1 + x[None, :] ** 2 + y[:, None] ** 2)).astype(np.float32)


def _scale_to_mean_luminance(reflectance_map: np.ndarray, white_photons: np.ndarray,
                             wavelengths_nm: np.ndarray, mean_luminance_cd_m2: float) -> np.ndarray:
    """radiance = reflectance × illuminant, scaled so the image's mean luminance is as asked."""
    radiance = reflectance_map * white_photons.astype(np.float32)
    mean_lum = float(spectra.luminance_from_photons(radiance.reshape(-1, radiance.shape[-1]).mean(0),
                                                    wavelengths_nm))
    if mean_lum <= 0:
        raise InvalidValueError("the chart has zero luminance under this illuminant")
    return radiance * np.float32(mean_luminance_cd_m2 / mean_lum)


@CHARTS.register("uniform")
def uniform_scene(illuminant: str = "D65", mean_luminance_cd_m2: float = 100.0,
                  size: tuple[int, int] = (64, 64), fov_deg: float = 10.0, distance_m: float = 1.2,
                  wavelengths_nm: np.ndarray = spectra.DEFAULT_WAVELENGTHS_NM,
                  reflectance: float = 1.0) -> Scene:
    """A uniform field: a diffuser of the given reflectance under the illuminant, set luminance."""
    rows, cols = _check_size(size)
    if mean_luminance_cd_m2 < 0:
        raise InvalidValueError(f"mean_luminance_cd_m2 must be ≥ 0, got {mean_luminance_cd_m2}")
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    white = _illuminant_photons(illuminant, wl, 1.0) * mean_luminance_cd_m2
    radiance = np.broadcast_to(white.astype(np.float32), (rows, cols, wl.size)).copy()
    return Scene(radiance, wl, fov_deg, distance_m, depth_m=plane_depth_m((rows, cols), fov_deg, distance_m),
                 name=f"uniform {illuminant}", meta={"illuminant": illuminant, "reflectance": reflectance})


def macbeth_layout(size: tuple[int, int]) -> np.ndarray:
    """Patch index (0–23, row-major 4×6) of each sample, −1 on the black borders between patches."""
    rows, cols = _check_size(size)
    # Each patch is a square cell of 4×6 cells; a border of 1/8 of a cell is left black.
    cell = min(rows / 4.0, cols / 6.0)
    y0 = (rows - 4 * cell) / 2
    x0 = (cols - 6 * cell) / 2
    yy = (np.arange(rows) + 0.5 - y0) / cell
    xx = (np.arange(cols) + 0.5 - x0) / cell
    iy, ix = np.floor(yy).astype(int), np.floor(xx).astype(int)
    fy, fx = yy - iy, xx - ix
    inside_y = (iy >= 0) & (iy < 4) & (fy > 0.0625) & (fy < 0.9375)
    inside_x = (ix >= 0) & (ix < 6) & (fx > 0.0625) & (fx < 0.9375)
    layout = iy[:, None] * 6 + ix[None, :]
    layout[~(inside_y[:, None] & inside_x[None, :])] = -1
    return layout


@CHARTS.register("macbeth")
def macbeth_scene(illuminant: str = "D65", mean_luminance_cd_m2: float = 100.0,
                  size: tuple[int, int] = (96, 144), fov_deg: float = 10.0, distance_m: float = 1.2,
                  wavelengths_nm: np.ndarray = spectra.DEFAULT_WAVELENGTHS_NM,
                  border_reflectance: float = 0.03) -> Scene:
    """The 24-patch ColorChecker under an illuminant; meta['layout'] maps samples to patches."""
    rows, cols = _check_size(size)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    refl = spectra.macbeth_reflectances(wl).astype(np.float32)            # 24×Nλ
    layout = macbeth_layout((rows, cols))
    table = np.vstack([refl, np.full((1, wl.size), border_reflectance, np.float32)])
    refl_map = table[np.where(layout < 0, 24, layout)]
    white = _illuminant_photons(illuminant, wl, 1.0)
    radiance = _scale_to_mean_luminance(refl_map, white, wl, mean_luminance_cd_m2)
    return Scene(radiance, wl, fov_deg, distance_m, depth_m=plane_depth_m((rows, cols), fov_deg, distance_m),
                 name=f"Macbeth {illuminant}", meta={"illuminant": illuminant, "layout": layout})


@CHARTS.register("slanted_edge")
def slanted_edge_scene(angle_deg: float = 5.0, contrast: float = 0.8, illuminant: str = "D65",
                       mean_luminance_cd_m2: float = 100.0, size: tuple[int, int] = (128, 128),
                       fov_deg: float = 5.0, distance_m: float = 10.0,
                       wavelengths_nm: np.ndarray = spectra.DEFAULT_WAVELENGTHS_NM,
                       supersample: int = 8) -> Scene:
    """A dark/bright edge through the centre, tilted by angle_deg from vertical (ISO 12233).

    Each sample's reflectance is its exact area coverage (supersampled `supersample`² points),
    so the chart itself adds no aliasing. contrast = (bright − dark)/bright."""
    rows, cols = _check_size(size)
    if not 0 < contrast <= 1:
        raise InvalidValueError(f"contrast must be in (0, 1], got {contrast}")
    if not -45 <= angle_deg <= 45:
        raise InvalidValueError(f"edge angle must be within ±45° of vertical, got {angle_deg}")
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    t = np.tan(np.radians(angle_deg))
    sub = (np.arange(supersample) + 0.5) / supersample
    ys = (np.arange(rows)[:, None] + sub[None, :]).ravel() - rows / 2
    xs = (np.arange(cols)[:, None] + sub[None, :]).ravel() - cols / 2
    bright = (xs[None, :] > ys[:, None] * t).astype(np.float32)
    coverage = bright.reshape(rows, supersample, cols, supersample).mean(axis=(1, 3))
    refl_map = ((1 - contrast) + contrast * coverage)[..., None].astype(np.float32)
    white = _illuminant_photons(illuminant, wl, 1.0)
    radiance = _scale_to_mean_luminance(np.broadcast_to(refl_map, (rows, cols, 1)), white, wl,
                                        mean_luminance_cd_m2)
    return Scene(radiance, wl, fov_deg, distance_m, depth_m=plane_depth_m((rows, cols), fov_deg, distance_m),
                 name="slanted edge", meta={"angle_deg": angle_deg, "contrast": contrast})


@CHARTS.register("hdr_tunnel")
def hdr_tunnel_scene(exit_luminance_cd_m2: float = 20000.0, tunnel_luminance_cd_m2: float = 0.05,
                     size: tuple[int, int] = (120, 160), fov_deg: float = 44.0,
                     distance_m: float = 30.0,
                     wavelengths_nm: np.ndarray = spectra.DEFAULT_WAVELENGTHS_NM) -> Scene:
    """A dark tunnel (sodium-like lamps on the walls) with a bright daylight exit in the middle.

    Default contrast exit/tunnel wall = 4×10⁵:1. The exit is an arch of daylight (D65); the walls
    are grey concrete lit at tunnel_luminance_cd_m2; a row of lamps (blackbody 2000 K) sits at
    100× the wall luminance; the road is darker than the walls."""
    rows, cols = _check_size(size)
    if exit_luminance_cd_m2 <= 0 or tunnel_luminance_cd_m2 <= 0:
        raise InvalidValueError("tunnel and exit luminances must be > 0 cd/m²")
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    y = (np.arange(rows) + 0.5)[:, None] / rows - 0.5
    x = (np.arange(cols) + 0.5)[None, :] / cols - 0.5
    r_exit = np.hypot(x / 0.16, (y - 0.05) / 0.22)
    exit_mask = np.broadcast_to((r_exit < 1.0) & (y < 0.27), (rows, cols))
    road = np.broadcast_to(y > 0.27, (rows, cols)) & ~exit_mask
    lamp = (np.abs(y + 0.3) < 0.02) & (np.abs(np.mod(x * 8 + 0.5, 1.0) - 0.5) < 0.12) & ~exit_mask
    day = _illuminant_photons("D65", wl, exit_luminance_cd_m2).astype(np.float32)
    wall = _illuminant_photons("blackbody:3000", wl, tunnel_luminance_cd_m2).astype(np.float32)
    lamp_rad = _illuminant_photons("blackbody:2000", wl, 100 * tunnel_luminance_cd_m2).astype(np.float32)
    radiance = np.empty((rows, cols, wl.size), np.float32)
    radiance[:] = wall
    radiance[road] = wall * 0.4
    radiance[lamp] = lamp_rad
    radiance[exit_mask] = day
    depth = np.where(exit_mask, 1000.0, plane_depth_m((rows, cols), fov_deg, distance_m)).astype(np.float32)
    return Scene(radiance, wl, fov_deg, distance_m, depth_m=depth, name="HDR tunnel",
                 meta={"exit_mask": exit_mask,
                       "dynamic_range": exit_luminance_cd_m2 / (0.4 * tunnel_luminance_cd_m2)})
