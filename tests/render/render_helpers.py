"""Helpers shared by the render tests: closed-form band means, a tolerance check from the
image's own Monte-Carlo error, a flat Lambertian city and the ray directions of a level pinhole."""
import numpy as np

from workbench.render.demo_scene import plane_mesh
from workbench.scene.city.types import City, CityObject, Material
from workbench.units import photon_energy_J

RHO = 0.6


def band_mean_photons(wl, energy, film):
    """Exact band means of a piecewise-linear energy spectrum, in photons."""
    fine = np.arange(300.0, 1100.0, 0.01)
    e = np.interp(fine, wl, energy, left=0, right=0) / photon_energy_J(fine)
    s = np.stack([np.interp(fine, film.wavelengths_nm, r, left=0, right=0) for r in film.responses])
    return np.trapezoid(s * e, fine, axis=1) / np.trapezoid(s, fine, axis=1)


def check(img, expected, label):
    p = img.reshape(-1, img.shape[-1])
    sem = p.std(axis=0) / np.sqrt(p.shape[0])
    tol = 5 * sem + 3e-3 * expected
    err = np.abs(p.mean(axis=0) - expected)
    assert np.all(tol < 0.02 * expected), f"{label}: tolerance {tol / expected} too loose to test anything"
    assert np.all(err <= tol), f"{label}: rel err {err / expected} > tol {tol / expected}"


def flat_city(half_size_m=1.0e4):
    wl = np.array([350.0, 1000.0])
    mat = Material("white", wl, np.array([RHO, RHO]))
    return City([CityObject("ground", 1, [plane_mesh(half_size_m, 0.0, "white")])], {"white": mat},
                seed=0, extent_m=(-1, -1, 1, 1))


def north_rays(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """Unit pixel-centre ray directions (height×width×3) of a level pinhole looking along +y."""
    f_px = (width / 2) / np.tan(np.radians(hfov_deg / 2))
    u = (np.arange(width) + 0.5 - width / 2) / f_px
    v = (height / 2 - np.arange(height) - 0.5) / f_px
    d = np.stack(np.broadcast_arrays(u[None, :], 1.0, v[:, None]), -1).astype(np.float64)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)
