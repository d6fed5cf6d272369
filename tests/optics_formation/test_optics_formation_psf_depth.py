"""PSF grid × object depth: depth nodes in 1/z, layer blending, defocus against ray-traced blur.

Camera: the double Gauss at f/4 focused at 2 m. Its paraxial blur circle K·|1/z − 1/s| is
~100 µm at 1.5 m and 3 m, ten times the 10 µm samples used below.
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.optics.formation import geometry, lens_setup, psf_grid, raytrace
from workbench.optics.lens import psf_geometric
from workbench.optics.params import OpticsParams
from workbench.scene.charts import plane_depth_m
from workbench.scene.types import Scene

FOCUS_M = 2.0
P = OpticsParams(lens_file="dgauss.50mm", f_number=4.0, focus_distance_m=FOCUS_M, psf_field_zones=2,
                 psf_azimuths=4, psf_wavelengths=1, off_axis="none")
WL = np.array([550.0])


def _image_distance_m() -> float:
    efl = lens_setup.effective_params(P).focal_length_m
    return geometry.image_distance_m(efl, FOCUS_M)


def _fov_deg(cols: int, spacing_m: float) -> float:
    return math.degrees(2 * math.atan(cols * spacing_m / 2 / _image_distance_m()))


def _plane_depth(shape, spacing_m, axial_m):
    """Along-ray distances of fronto-parallel planes at axial distances axial_m (H×W)."""
    x, y = geometry.sample_positions_m(shape, spacing_m)
    d = _image_distance_m()
    return axial_m * np.sqrt(d * d + x * x + y * y) / d


def _texture(shape, seed=5):
    rad = np.random.default_rng(seed).uniform(1e14, 1e15, shape + (1,))
    return rad.astype(np.float32)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 2.0), st.floats(0.0, 2.0), st.floats(0.0, 2.0), st.integers(1, 8))
def test_depth_nodes_cover_the_range_and_hold_the_focus(a, b, focus, count):
    inv = np.array([a, b])
    lo, hi = min(a, b), max(a, b)
    nodes = psf_grid.depth_nodes_inv_m(inv, focus, count, coc_per_inv_m=1e-3, spacing_m=1e-5)
    assert np.all(np.diff(nodes) > 0)
    if nodes.size == 1:
        assert count == 1 or 1e-3 * (hi - lo) <= 0.05 * 1e-5
        return
    assert nodes[0] == lo and nodes[-1] == hi
    if lo < focus < hi:
        assert focus in nodes and 3 <= nodes.size <= max(count, 3) + 1
    else:
        assert nodes.size == count
        assert np.allclose(np.diff(nodes), (hi - lo) / (count - 1))


def test_flat_scene_is_one_node_whatever_the_node_count():
    """A scene in focus, with or without a depth map along the rays, takes the single-node path."""
    rad = _texture((21, 27))
    fov = _fov_deg(27, 10e-6)
    flat = Scene(rad, WL, fov, FOCUS_M)
    chart = Scene(rad, WL, fov, FOCUS_M, depth_m=plane_depth_m((21, 27), fov, FOCUS_M))
    a = psf_grid.radiance_to_irradiance(flat, P)
    b = psf_grid.radiance_to_irradiance(chart, P.model_copy(update={"psf_depth_nodes": 7}))
    assert a.meta["depth_nodes_m"] == [FOCUS_M] == b.meta["depth_nodes_m"]
    assert np.array_equal(a.irradiance_photons, b.irradiance_photons)


def test_two_depths_give_each_half_the_flat_result_at_its_depth():
    rows, cols, dx = 64, 48, 10e-6
    rad = _texture((rows, cols))
    fov = _fov_deg(cols, dx)
    axial = np.where(np.arange(rows)[:, None] < rows // 2, 3.0, 1.5) * np.ones((1, cols))
    two = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, FOCUS_M, depth_m=_plane_depth((rows, cols), dx, axial)), P)
    far = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, 3.0), P)
    near = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, 1.5), P)
    assert np.allclose(two.meta["depth_nodes_m"], [3.0, FOCUS_M, 1.5])
    margin = max(far.meta["psf_size"], near.meta["psf_size"]) // 2 + 1     # PSF radius from the edge
    top, bottom = slice(0, rows // 2 - margin), slice(rows // 2 + margin, rows)
    assert top.stop > 4 and bottom.start < rows - 4
    out, f, n = two.irradiance_photons, far.irradiance_photons, near.irradiance_photons
    assert np.allclose(out[top], f[top], rtol=1e-6)
    assert np.allclose(out[bottom], n[bottom], rtol=1e-6)
    assert not np.allclose(f[bottom], n[bottom], rtol=1e-2)        # the two depths do differ there


def _rms_radius_um(img: np.ndarray, spacing_um: float) -> float:
    yy, xx = np.indices(img.shape)
    w = img / img.sum()
    cy, cx = (yy * w).sum(), (xx * w).sum()
    return math.sqrt((((yy - cy) ** 2 + (xx - cx) ** 2) * w).sum()) * spacing_um


@pytest.mark.parametrize("depth_m", [1.5, 3.0])
def test_defocused_point_spreads_as_the_traced_geometric_defocus(depth_m):
    """Oracle: the geometric PSF (rays binned on the same grid, an independent method from the
    pupil-FFT PSFs of the grid) of the same focused lens for an object at depth_m. Defocus is
    ~6 waves here, so the wave PSF's RMS radius exceeds the geometric one only by diffraction:
    ⟨r²⟩ grows by ~2λN·R/π² (Airy tails out to the PSF grid's radius R ≈ 150 µm), ≤ 60 µm² against
    ⟨r²⟩ ≥ 1000 µm², i.e. ≤ 3 % in radius: tolerance 4 %. The in-focus spot is 4× smaller."""
    n, dx = 61, 5e-6
    rad = np.zeros((n, n, 1), np.float32)
    rad[n // 2, n // 2] = 1e18
    fov = _fov_deg(n, dx)
    oi = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, depth_m), P)
    focused = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, FOCUS_M), P)
    params = lens_setup.effective_params(P)
    lens, _ = lens_setup.focused_lens(params, FOCUS_M)
    geo = psf_geometric(lens, 0.0, 550.0, lens_setup.focused_lens(params, depth_m)[1], dx * 1e6, n)
    r_grid = _rms_radius_um(oi.irradiance_photons[..., 0].astype(np.float64), dx * 1e6)
    assert r_grid == pytest.approx(_rms_radius_um(geo, dx * 1e6), rel=0.04)
    assert r_grid > 4 * _rms_radius_um(focused.irradiance_photons[..., 0].astype(np.float64), dx * 1e6)


def test_tilted_ground_conserves_light_and_stays_finite():
    """Depth from 1.2 m (bottom) to 6 m (top), content away from the border: every sample's light
    is split between depth nodes with weights summing to 1, and each PSF sums to 1."""
    rows, cols, dx = 40, 40, 10e-6
    rad = np.zeros((rows, cols, 1), np.float32)
    rad[14:26, 14:26] = _texture((12, 12))
    fov = _fov_deg(cols, dx)
    axial = np.linspace(6.0, 1.2, rows)[:, None] * np.ones((1, cols))
    tilted = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, FOCUS_M, depth_m=_plane_depth((rows, cols), dx, axial)), P)
    flat = psf_grid.radiance_to_irradiance(Scene(rad, WL, fov, FOCUS_M), P)
    assert len(tilted.meta["depth_nodes_m"]) == 3
    img = tilted.irradiance_photons
    assert np.all(np.isfinite(img)) and img.min() >= 0
    assert img.sum(dtype=np.float64) == pytest.approx(flat.irradiance_photons.sum(dtype=np.float64), rel=1e-5)


def test_depth_inside_the_focal_length_is_refused():
    depth = np.full((9, 9), FOCUS_M)
    depth[4, 4] = 0.04
    scene = Scene(_texture((9, 9)), WL, _fov_deg(9, 10e-6), FOCUS_M, depth_m=depth)
    with pytest.raises(ValueError, match="depth_m must exceed the lens.s focal length.* 1 samples do not, e.g. 0.04"):
        psf_grid.radiance_to_irradiance(scene, P)


def test_heavy_defocus_agrees_with_the_ray_traced_level():
    """Oracle: the raytrace level (rays from each sensor sample traced back to the scene plane).
    f/2 focused at 10 m, a square 1.5 m away: blur ≈ 710 µm = 80 waves of defocus, so the grid
    uses geometric PSFs (GEOMETRIC_DEFOCUS_WAVES; wave PSFs alone miss by 12 %). The ray-traced
    image's sampling error falls with its rays (RMS difference 6 %, 3 %, 2 % at 256, 576 and 1024
    rays per sample): tolerance 4 % at 1024."""
    n, dx, depth = 61, 24e-6, 1.5
    p = P.model_copy(update={"f_number": 2.0, "focus_distance_m": 10.0, "rays_per_sample": 1024})
    d_img = geometry.image_distance_m(lens_setup.effective_params(p).focal_length_m, 10.0)
    rad = np.zeros((n, n, 1), np.float32)
    rad[n // 2 - 6:n // 2 + 7, n // 2 - 6:n // 2 + 7] = 1e16
    scene = Scene(rad, WL, math.degrees(2 * math.atan(n * dx / 2 / d_img)), depth)
    a = psf_grid.radiance_to_irradiance(scene, p).irradiance_photons[..., 0].astype(np.float64)
    b = raytrace.radiance_to_irradiance(scene, p).irradiance_photons[..., 0].astype(np.float64)
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.04 * np.sqrt(np.mean(b ** 2))
    assert a.sum() == pytest.approx(b.sum(), rel=0.04)
