"""Aberration analysis: chief-ray aiming against optiland, ray fans, spots, colour, illumination."""
import math

import numpy as np
import pytest

from workbench.optics.lens import (Lens, Surface, axial_color, chief_ray_on_sensor, distortion,
                                   field_angle_for_height, irradiance_per_radiance, lateral_color, load_lens,
                                   paraxial, psf_geometric, ray_fan, relative_illumination, sensor_z_mm,
                                   spot_diagram)

WL = 587.5618


@pytest.mark.parametrize("name,fields", [("dgauss.50mm", (10.0, 20.0)), ("wide.22mm", (15.0, 30.0))])
def test_chief_ray_matches_optiland_iterative_aiming(name, fields, oracles):
    lens = load_lens(name)
    o = oracles["optiland"](lens)
    for a in fields:
        o.fields.add(y=a)
    o.ray_tracer.set_aiming("iterative", max_iter=30, tol=1e-10)
    for a in fields:
        o.trace_generic(0.0, a / fields[-1], 0.0, 0.0, WL * 1e-3)
        assert chief_ray_on_sensor(lens, a, WL)[1] == pytest.approx(float(o.surfaces.y[-1][0]), abs=1e-6)


def test_field_angle_for_height_inverts_chief_ray():
    lens = load_lens("wide.22mm")
    a = field_angle_for_height(lens, 9.0, WL)
    assert chief_ray_on_sensor(lens, a, WL)[1] == pytest.approx(9.0, abs=1e-8)


def test_on_axis_fans_and_spot_are_symmetric():
    lens = load_lens("dgauss.50mm")
    fan = ray_fan(lens, 0.0, WL, n=21)
    assert fan.valid_t.all()
    assert np.allclose(fan.error_t_um, -fan.error_t_um[::-1], atol=1e-9)   # odd in the pupil
    assert fan.error_t_um[10] == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(fan.error_t_um, fan.error_s_um, atol=1e-9)          # rotational symmetry
    sd = spot_diagram(lens, 0.0, WL)
    assert np.allclose(sd.centroid_um, 0.0, atol=1e-9) and sd.rms_um > 0


def test_spot_rms_agrees_with_geometric_psf_moment():
    lens = load_lens("automotive.2.4mm")
    sd = spot_diagram(lens, 0.0, 550.0, n_side=96)
    psf = psf_geometric(lens, 0.0, 550.0, math.inf, 0.1, 161, n_side=256)
    yy, xx = (np.mgrid[:161, :161] - 80) * 0.1
    rms = math.sqrt((psf * (xx ** 2 + yy ** 2)).sum())
    assert rms == pytest.approx(sd.rms_um, rel=0.05)


def test_axial_color_of_thin_singlet_is_minus_f_over_v():
    lens = Lens((Surface.from_radius(100.0, 0.1, "1.5/50", 2.0),
                 Surface.from_radius(-100.0, 0.0, "air", 2.0)))
    f = paraxial(lens).efl_mm
    assert axial_color(lens) == pytest.approx(-f / 50.0, rel=0.02)


def test_lateral_color_zero_without_dispersion_and_present_with_it():
    val, ok = lateral_color(load_lens("wide.22mm"), [10.0, 20.0])
    assert ok.all() and np.allclose(val, 0.0, atol=1e-9)
    val, ok = lateral_color(load_lens("dgauss.50mm"), [0.0, 15.0])
    assert ok.all() and val[0] == pytest.approx(0.0, abs=1e-9) and abs(val[1]) > 0.1


def test_small_stop_at_thin_lens_gives_cos4():
    """A 0.2 mm stop against a thin lens: the pinhole limit, RI = cos⁴θ (θ seen from the stop)."""
    lens = Lens((Surface.from_radius(0.0, 0.0, "air", 0.2, is_stop=True),
                 Surface.from_radius(100.0, 0.1, "1.5", 2.0),
                 Surface.from_radius(-100.0, 0.0, "air", 2.0)))
    z = sensor_z_mm(lens)
    h = np.array([0.0, 10.0, 25.0, 40.0])
    ri = relative_illumination(lens, h, n_side=256)
    assert np.allclose(ri, np.cos(np.arctan(h / z)) ** 4, rtol=3e-3)   # grid quantisation of the disc
    assert irradiance_per_radiance(lens, n_side=256) == pytest.approx(math.pi * 0.2 ** 2 / z ** 2, rel=3e-3)


def test_relative_illumination_of_vignetted_lens_is_monotone_and_below_cos4():
    lens = load_lens("dgauss.50mm")
    a = np.array([0.0, 5.0, 10.0, 15.0, 20.0])
    d = distortion(lens, a)
    ri = relative_illumination(lens, d.real_height_mm, n_side=64)
    assert np.all(np.diff(ri) < 0)
    assert np.all(ri <= np.cos(np.radians(a)) ** 4 + 1e-3)
    # optics.md §5.3 (independent trace): 0.91/0.74/0.56/0.38 at 4.6/9.1/13.5/17.7 deg.
    ri2 = relative_illumination(lens, 50.3582 * np.tan(np.radians([4.6, 9.1, 13.5, 17.7])), n_side=96)
    assert np.allclose(ri2, [0.91, 0.74, 0.56, 0.38], atol=0.012)


def test_distortion_small_for_double_gauss():
    d = distortion(load_lens("dgauss.50mm"), [0.0, 5.0, 22.0])
    assert d.valid.all() and d.distortion_percent[0] == 0.0
    assert -2.0 < d.distortion_percent[2] < -1.0   # barrel, about −1.4 %


def test_fisheye_chief_rays_past_65_degrees_match_optiland_robust_aiming(oracles):
    """Wide fields where simple aiming fails (optics.md §4): ours agrees with optiland's robust aimer."""
    lens = load_lens("fisheye.10mm")
    o = oracles["optiland"](lens)
    fields = (60.0, 70.0, 74.0)
    for a in fields:
        o.fields.add(y=a)
    o.ray_tracer.set_aiming("robust")
    for a in fields:
        o.trace_generic(0.0, a / fields[-1], 0.0, 0.0, WL * 1e-3)
        assert chief_ray_on_sensor(lens, a, WL)[1] == pytest.approx(float(o.surfaces.y[-1][0]), abs=1e-6)
