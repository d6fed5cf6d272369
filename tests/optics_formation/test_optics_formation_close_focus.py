"""A real lens focused close: the pinhole geometry every level samples the scene on must image like
the traced lens. It used the thin-lens conjugate with the distance from the entrance pupil, which
a thick lens's principal plane sits millimetres from: the double Gauss focused at 50.5 mm put its
samples 18 m behind a pinhole whose traced lens images at 0.78 m, and psf_grid returned a black
image without a word."""
import math

import pytest

from workbench.optics.formation import lens_setup
from workbench.optics.formation.geometry import camera_equation_factor
from workbench.optics.formation.psf_grid import lens_tables
from workbench.optics.lens import chief_ray_on_sensor
from workbench.optics.lens.paraxial import focus, lateral_magnification, paraxial
from workbench.project import load_project


def _dgauss(**optics):
    p = load_project("uniform_d65_isetcam_pixel")
    return p.updated(sensor=p.sensor.updated(rows=24, cols=32),
                     optics=p.optics.updated(model="psf_grid", lens_file="dgauss.50mm", **optics))


def test_magnification_obeys_newton_equation():
    """m = −f/x, x the object's distance from the front focal point (closed form)."""
    from workbench.optics.lens import load_lens
    lens = load_lens("dgauss.50mm")
    p = paraxial(lens)
    for d_m in (0.03, 0.5, 10.0):
        assert lateral_magnification(lens, d_m) == pytest.approx(-p.efl_mm / (d_m * 1e3 - p.ffl_mm), rel=1e-10)
    assert lateral_magnification(lens, math.inf) == 0.0


@pytest.mark.parametrize("focus_m", [0.0505, 0.06, 1.0, 5.0, math.inf])
def test_the_pinhole_geometry_images_like_the_traced_lens(focus_m):
    """Near the axis a traced chief ray lands where the pinhole at the entrance pupil puts the same
    object point (before: 0.9953 of it at 5 m, and no ray on the sensor at 50.5 mm)."""
    params = _dgauss().optics
    d_m = lens_setup.pinhole_image_distance_m(params, focus_m)
    lens, obj_m = lens_setup.focused_lens(params, focus_m)
    tab = lens_tables(lens, obj_m, d_m, 1e-3 * d_m, (587.6,))
    assert tab["rd"][0][1] / tab["ru"][0][1] == pytest.approx(1.0, abs=1e-6)
    if math.isfinite(focus_m):                # the object point itself, traced from the first vertex
        tan_vertex = 1e-3 * focus_m / obj_m
        h_mm = chief_ray_on_sensor(lens, math.degrees(math.atan(tan_vertex)), 587.6, obj_m)[1]
        assert abs(h_mm) * 1e-3 == pytest.approx(1e-3 * d_m, rel=1e-5)


def test_close_focus_irradiance_follows_the_camera_equation():
    """A uniform field 50.5 mm from the lens (m ≈ −14.7): E/L on the axis is π/(1 + 4 N_w²) with
    N_w = N (1 + |m|/m_p), m_p the pupil magnification (was 0 everywhere)."""
    from workbench.pipeline import Pipeline
    p = _dgauss()
    p = p.updated(scene=p.scene.updated(distance_m=0.0505))
    r = Pipeline(p).run()
    e_over_l = float(r.optical_image.irradiance_photons[12, 16, 10] / r.scene.radiance_photons[12, 16, 10])
    lens, obj_m = lens_setup.focused_lens(p.optics, 0.0505)
    pd = paraxial(lens)
    n_w = pd.f_number * (1 + abs(lateral_magnification(lens, obj_m)) / (pd.exit_pupil_diameter_mm / pd.epd_mm))
    assert n_w > 50
    assert e_over_l == pytest.approx(camera_equation_factor(n_w, 0.0), rel=0.02)


def test_focus_inside_the_front_focal_point_names_the_setting():
    params = _dgauss().optics
    with pytest.raises(ValueError, match=r"cannot focus 0\.04 m from its entrance pupil \(optics\.focus_distance_m, "
                                         r"else scene\.distance_m\).*beyond its front focal point, 0\.047\d+ m"):
        lens_setup.focused_lens(params, 0.04)
    focus(lens_setup.prepared_lens(params), 0.5)        # farther: focuses
