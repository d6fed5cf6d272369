"""Real-ray tracing: against optiland, exactness on flat / nearly flat surfaces, hard cases."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.optics.lens import (Lens, Surface, chief_ray_on_sensor, distortion, load_lens, sensor_z_mm,
                                   trace_from_object, trace_from_sensor, trace_rays)
from workbench.optics.lens.pupil import make_bundle
from workbench.optics.lens.trace import intersect, refract, to_plane

WL = 587.5618


@pytest.mark.parametrize("name,theta", [("dgauss.50mm", 0.0), ("dgauss.50mm", 14.0), ("wide.22mm", 20.0),
                                        ("fisheye.10mm", 40.0)])
def test_real_rays_match_optiland(name, theta, oracles):
    """Rays over the field's pupil box (plus some that miss) land where optiland puts them (1e-9 mm)."""
    from optiland.rays import RealRays
    lens = load_lens(name)
    b = make_bundle(lens, theta, math.inf, WL)
    u0, u1, v0, v1 = b.box
    n = 41
    p, d = b.rays(np.linspace(u0, u1, n) * 0.3, np.linspace(v0, v1, n) * 1.1)
    o = oracles["optiland"](lens)
    rays = RealRays(*p.T, *d.T, np.ones(n), np.full(n, WL * 1e-3))
    o.surfaces.trace(rays)
    ox, oy = np.asarray(o.surfaces.x[-1]), np.asarray(o.surfaces.y[-1])
    pts, dirs, ok = trace_from_object(lens, p, d, WL)
    img, ok = to_plane(pts, dirs, ok, sensor_z_mm(lens))
    assert 10 <= ok.sum() < n  # optiland ignores clear apertures: ours is a subset of its rays
    assert np.isfinite(oy[ok]).all()
    assert np.allclose(img[ok, 0], ox[ok], atol=1e-9)
    assert np.allclose(img[ok, 1], oy[ok], atol=1e-9)


def _plane_lens(radius_mm):
    return Lens((Surface.from_radius(radius_mm, 5.0, "1.5", 20.0), Surface.from_radius(0.0, 0.0, "air", 20.0)))


def test_flat_surface_intersection_is_exact():
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(-5, 5, (100, 2)), rng.uniform(-20, -1, 100)])
    d = np.column_stack([rng.uniform(-0.5, 0.5, (100, 2)), np.ones(100)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    t, ok = intersect(Surface(0.0, 1.0, "air", 50.0), 3.0, p, d)
    assert ok.all()
    assert np.array_equal(p[:, 2] + t * d[:, 2], np.full(100, 3.0)) or np.allclose(p[:, 2] + t * d[:, 2], 3.0,
                                                                                    atol=4e-15)


def test_nearly_flat_surface_has_no_precision_loss():
    """R = 1e5 mm: hit points agree with a long-double reference of the same geometry to < 1e-12 mm."""
    rng = np.random.default_rng(2)
    n = 200
    p = np.column_stack([rng.uniform(-8, 8, (n, 2)), np.full(n, -2.0)])
    d = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    R = 1e5
    t, ok = intersect(Surface.from_radius(R, 1.0, "air", 20.0), 0.0, p, d)
    assert ok.all()
    # Reference: sag equation solved by Newton in long double from the plane hit.
    P, D = p.astype(np.longdouble), d.astype(np.longdouble)
    tt = -P[:, 2] / D[:, 2]
    for _ in range(8):
        x, y, z = P[:, 0] + tt * D[:, 0], P[:, 1] + tt * D[:, 1], P[:, 2] + tt * D[:, 2]
        rho = x * x + y * y
        sag = rho / (np.longdouble(R) * (1 + np.sqrt(1 - rho / np.longdouble(R) ** 2)))
        dsag = 1 / (2 * np.sqrt(np.longdouble(R) ** 2 - rho))
        tt -= (z - sag) / (D[:, 2] - 2 * dsag * (x * D[:, 0] + y * D[:, 1]))
    assert np.max(np.abs(t - tt.astype(np.float64))) < 1e-12


def test_nearly_flat_converges_to_flat():
    rays = (np.array([[1.0, 2.0, -3.0]]), np.array([[0.1, -0.05, 1.0]]))
    flat = trace_rays(_plane_lens(0.0), *rays, WL)
    near = trace_rays(_plane_lens(1e9), *rays, WL)
    assert np.allclose(flat.points, near.points, atol=1e-10) and np.allclose(flat.dirs, near.dirs, atol=1e-12)


def test_grazing_and_parallel_rays_stay_finite():
    lens = _plane_lens(10.0)
    # A ray tangent to the sphere cap, one exactly parallel to the flat rear face, one grazing the edge.
    p = np.array([[0.0, 10.0, -5.0], [0.0, 0.0, 6.0], [0.0, 19.999999, -1.0]])
    d = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    r = trace_rays(lens, p, d, WL, record=True)
    assert np.isfinite(r.points).all() and np.isfinite(r.dirs).all() and np.isfinite(r.opl_mm).all()
    assert not r.valid[1]


def test_total_internal_reflection_clears_valid():
    lens = Lens((Surface.from_radius(0.0, 5.0, "1.8", 10.0), Surface.from_radius(-5.0, 0.0, "air", 4.9)))
    h = np.array([1.0, 4.5])  # incidence asin(h/5): 11.5° passes, 64° > critical 33.7° reflects
    r = trace_rays(lens, np.column_stack([np.zeros(2), h, np.full(2, -1.0)]), np.tile([0.0, 0.0, 1.0], (2, 1)), WL)
    assert r.valid.tolist() == [True, False]
    assert np.isfinite(r.points).all() and np.isfinite(r.dirs).all()
    d, ok = refract(np.array([[math.sin(0.7), 0.0, math.cos(0.7)]]), np.array([[0.0, 0.0, 1.0]]),
                    np.array([1.8]), np.array([1.0]))
    assert not ok[0]


def test_refraction_obeys_snell():
    rng = np.random.default_rng(3)
    th = rng.uniform(0, 1.2, 50)
    d = np.column_stack([np.sin(th), np.zeros(50), np.cos(th)])
    out, ok = refract(d, np.tile([0.0, 0.0, -1.0], (50, 1)), np.ones(50), np.full(50, 1.6))
    assert ok.all()
    assert np.allclose(np.sin(th), 1.6 * out[:, 0], atol=1e-14)


def test_fisheye_chief_heights_and_beyond_65_degrees():
    lens = load_lens("fisheye.10mm")
    ang = np.array([10, 20, 30, 40, 50, 60, 70, 80])
    dist = distortion(lens, ang)
    measured = [1.744, 3.491, 5.244, 7.002, 8.766, 10.528]  # optics.md §4, independent trace
    assert np.allclose(dist.real_height_mm[:6], measured, atol=2e-3)
    f = 9.9914
    assert np.all(np.abs(dist.real_height_mm[:6] / (f * np.radians(ang[:6])) - 1) < 0.007)  # equidistant within 0.6 %
    assert dist.valid[:6].all() and not dist.valid[7]
    for arr in (dist.real_height_mm, dist.distortion_percent):
        assert np.isfinite(arr).all()


def test_field_with_no_ray_through_the_lens_is_a_clear_error():
    lens = load_lens("dgauss.50mm")
    with pytest.raises(ValueError, match="no ray from field 60°"):
        make_bundle(lens, 60.0, math.inf, WL)
    with pytest.raises(ValueError, match="field 60°"):
        chief_ray_on_sensor(lens, 60.0, WL)
    d = distortion(lens, [10.0, 60.0])
    assert d.valid.tolist() == [True, False] and np.isfinite(d.distortion_percent).all()


def test_even_asphere_hit_lies_on_surface_and_normal_is_gradient():
    s = Surface(1 / 15.0, 1.0, "air", 6.0, conic=-0.7, asphere_coeffs=(0.0, 2e-4, -3e-6))
    rng = np.random.default_rng(4)
    p = np.column_stack([rng.uniform(-4, 4, (50, 2)), np.full(50, -3.0)])
    d = np.column_stack([rng.uniform(-0.2, 0.2, (50, 2)), np.ones(50)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    t, ok = intersect(s, 2.0, p, d)
    assert ok.all()
    hit = p + t[:, None] * d
    assert np.allclose(hit[:, 2] - 2.0, s.sag_mm(np.hypot(hit[:, 0], hit[:, 1])), atol=1e-11)
    from workbench.optics.lens.trace import surface_normal
    nrm = surface_normal(s, 2.0, hit)
    eps = 1e-6
    r = np.hypot(hit[:, 0], hit[:, 1])
    slope = (s.sag_mm(r + eps) - s.sag_mm(r - eps)) / (2 * eps)
    radial = np.column_stack([hit[:, 0] / r, hit[:, 1] / r])
    expect = np.column_stack([-slope[:, None] * radial, np.ones(50)])
    expect /= np.linalg.norm(expect, axis=1)[:, None]
    assert np.allclose(nrm, expect, atol=1e-8)


@settings(max_examples=40, deadline=None)
@given(st.floats(-12, 12), st.floats(-12, 12), st.floats(-0.4, 0.4), st.floats(-0.4, 0.4))
def test_trace_is_finite_and_reversible(x, y, a, b):
    """Any ray: finite output; a ray that passes, traced back from where it left, returns to its start line."""
    lens = load_lens("dgauss.50mm")
    p0 = np.array([[x, y, -10.0]])
    d0 = np.array([[a, b, 1.0]]) / math.sqrt(a * a + b * b + 1)
    pts, dirs, ok = trace_from_object(lens, p0, d0, 500.0)
    assert np.isfinite(pts).all() and np.isfinite(dirs).all()
    if ok[0]:
        start = pts + 5.0 * dirs
        bp, bd, bok = trace_from_sensor(lens, start, -dirs, 500.0)
        assert bok[0]
        assert np.allclose(-bd, d0, atol=1e-9)
        back, _ = to_plane(bp, bd, bok, -10.0)
        assert np.allclose(back, p0, atol=1e-8)


def test_bad_ray_input_names_the_problem():
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        trace_from_object(load_lens("dgauss.50mm"), np.zeros((2, 2)), np.zeros((2, 2)), WL)
    with pytest.raises(ValueError, match="wavelength_nm"):
        trace_from_object(load_lens("dgauss.50mm"), np.zeros((1, 3)), [[0, 0, 1]], -5)


@settings(max_examples=60, deadline=None)
@given(st.floats(-0.3, 0.3), st.floats(-3.0, 0.5), st.floats(-4, 4), st.floats(-4, 4),
       st.floats(-0.5, 0.5), st.floats(-0.5, 0.5))
def test_intersection_lies_on_the_conic(c, k, x, y, a, b):
    """Any curvature (flat included), conic and ray: the hit satisfies c(x²+y²+(1+k)z²) = 2z."""
    s = Surface(c, 1.0, "air", 50.0, conic=k)
    p = np.array([[x, y, -6.0]])
    d = np.array([[a, b, 1.0]]) / math.sqrt(a * a + b * b + 1)
    t, ok = intersect(s, 0.0, p, d)
    assert np.isfinite(t).all()
    if ok[0]:
        h = p[0] + t[0] * d[0]
        assert abs(c * (h[0] ** 2 + h[1] ** 2 + (1 + k) * h[2] ** 2) - 2 * h[2]) < 1e-12
        assert (1 + k) * c * h[2] <= 1 + 1e-9 and t[0] >= 0


def test_even_asphere_lens_matches_optiland():
    from optiland import optic
    from optiland.materials import IdealMaterial
    from optiland.rays import RealRays
    from workbench.optics.lens import focus, sensor_distance_mm
    coeffs = (1e-4, 2e-5, -1e-7)   # r², r⁴, r⁶ — optiland's EvenAsphere uses the same order
    lens = focus(Lens((Surface(1 / 20.0, 4.0, "1.5168", 6.0, conic=-1.0, asphere_coeffs=coeffs),
                       Surface(-1 / 60.0, 2.0, "air", 6.0),
                       Surface(0.0, 0.0, "air", 3.0, is_stop=True))), math.inf)
    o = optic.Optic()
    o.surfaces.add(index=0, thickness=np.inf)
    o.surfaces.add(index=1, radius=20.0, thickness=4.0, material=IdealMaterial(n=1.5168),
                   surface_type="even_asphere", conic=-1.0, coefficients=list(coeffs))
    o.surfaces.add(index=2, radius=-60.0, thickness=2.0, material="air")
    o.surfaces.add(index=3, radius=np.inf, thickness=sensor_distance_mm(lens), is_stop=True)
    o.surfaces.add(index=4)
    o.set_aperture("EPD", 5.0)
    o.fields.set_type("angle")
    o.fields.add(y=0)
    o.wavelengths.add(WL * 1e-3, is_primary=True)
    n = 21
    p = np.column_stack([np.linspace(-1, 1, n), np.linspace(-3, 3, n), np.full(n, -3.0)])
    d = np.column_stack([np.zeros(n), np.full(n, 0.1), np.ones(n)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    o.surfaces.trace(RealRays(*p.T, *d.T, np.ones(n), np.full(n, WL * 1e-3)))
    pts, dirs, ok = trace_from_object(lens, p, d, WL)
    img, ok = to_plane(pts, dirs, ok, sensor_z_mm(lens))
    assert ok.sum() >= 15
    assert np.allclose(img[ok, 0], np.asarray(o.surfaces.x[-1])[ok], atol=1e-8)
    assert np.allclose(img[ok, 1], np.asarray(o.surfaces.y[-1])[ok], atol=1e-8)


@settings(max_examples=80, deadline=None)
@given(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.05, 1), st.floats(-0.6, 0.6), st.floats(-0.6, 0.6),
       st.floats(1.0, 2.0), st.floats(1.0, 2.0))
def test_refraction_invariants(a, b, c, nx, ny, n1, n2):
    """Unit output, in the plane of incidence, n1 (d × N) = n2 (d' × N); TIR exactly when predicted."""
    d = np.array([[a, b, c]]) / math.sqrt(a * a + b * b + c * c)
    nrm = np.array([[nx, ny, 1.0]]) / math.sqrt(nx * nx + ny * ny + 1.0)
    out, ok = refract(d, nrm, np.array([n1]), np.array([n2]))
    sin_i = np.linalg.norm(np.cross(d[0], nrm[0]))
    assert ok[0] == (n1 * sin_i <= n2 * (1 + 1e-12)) or abs(n1 * sin_i - n2) < 1e-9
    if ok[0]:
        assert np.linalg.norm(out[0]) == pytest.approx(1.0, abs=1e-12)
        assert np.allclose(n1 * np.cross(d[0], nrm[0]), n2 * np.cross(out[0], nrm[0]), atol=1e-12)
        assert np.dot(out[0], nrm[0]) * np.dot(d[0], nrm[0]) >= 0   # transmitted, not reflected
