"""The lens camera inside Mitsuba (llvm_ad_spectral): camera equation on axis, agreement with the
numpy estimator, and image orientation against the built-in perspective camera."""
import math

import numpy as np
import pytest

from workbench.optics.lens import irradiance_per_radiance, load_lens, paraxial, relative_illumination

ENV = {"type": "constant", "radiance": {"type": "uniform", "value": 1.0}}


def _film(w, h):
    return {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "luminance"}


def _render(mi, sensor, extra=None, spp=64):
    sensor = dict(sensor, sampler={"type": "independent", "sample_count": spp, "seed": 3})
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 2}, "sensor": sensor, "env": ENV}
    scene.update(extra or {})
    return np.array(mi.render(mi.load_dict(scene)))[..., 0].astype(np.float64)


def _camera(mi):
    return mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])


def test_on_axis_irradiance_is_the_camera_equation(mi):
    from workbench.render.lens_camera import lens_sensor_dict
    lens = load_lens("dgauss.50mm")
    film = _film(32, 24)
    # A 1 mm film: every pixel is within 0.7 mm of the axis (RI > 0.999).
    lens_img = _render(mi, lens_sensor_dict(lens, film, _camera(mi), sensor_width_mm=1.0), spp=256)
    persp = _render(mi, {"type": "perspective", "fov": 10, "to_world": _camera(mi), "film": film}, spp=16)
    e_over_l = lens_img.mean() / persp.mean()
    n = paraxial(lens).f_number
    assert np.isfinite(lens_img).all()
    assert e_over_l == pytest.approx(math.pi / (4 * n * n), rel=0.02)
    assert e_over_l == pytest.approx(irradiance_per_radiance(lens), rel=0.01)


def test_radiance_weighting_and_relative_illumination(mi):
    from workbench.render.lens_camera import lens_sensor_dict
    lens = load_lens("automotive.2.4mm")
    w, h, pitch_mm = 40, 30, 0.048      # the paper's 1.92 × 1.44 mm sensor at 1/8 resolution
    img = _render(mi, lens_sensor_dict(lens, _film(w, h), _camera(mi), sensor_width_mm=w * pitch_mm,
                                       weight="radiance"), spp=256)
    centre = img[h // 2 - 2:h // 2 + 2, w // 2 - 2:w // 2 + 2].mean()
    assert centre == pytest.approx(1.0, abs=0.02)
    # Pixel (0, 0) centre lies at (19.5, 14.5) pitches from the axis.
    r_mm = math.hypot(19.5, 14.5) * pitch_mm
    corner = np.mean([img[0, 0], img[0, -1], img[-1, 0], img[-1, -1]])
    assert corner == pytest.approx(relative_illumination(lens, [r_mm])[0], rel=0.06)
    assert abs(img[:, : w // 2].mean() / img[:, w // 2:].mean() - 1) < 0.02   # symmetric


def test_image_orientation_matches_perspective_camera(mi):
    from workbench.render.lens_camera import lens_sensor_dict
    lens = load_lens("automotive.2.4mm")
    film = _film(32, 24)
    f_mm = paraxial(lens).efl_mm
    width_mm = 2 * f_mm * math.tan(math.radians(22))
    # A bright square up and to the camera's left (+x, +y) 10 m away, on a black sky.
    light = {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([2.0, 1.2, 10.0]).scale(0.6)
             @ mi.ScalarTransform4f().rotate([1, 0, 0], 180),
             "emitter": {"type": "area", "radiance": {"type": "uniform", "value": 10.0}}}
    black = {"env": {"type": "constant", "radiance": {"type": "uniform", "value": 0.0}}, "light": light}
    a = _render(mi, lens_sensor_dict(lens, film, _camera(mi), sensor_width_mm=width_mm), black, spp=32)
    b = _render(mi, {"type": "perspective", "fov": 44, "fov_axis": "x", "to_world": _camera(mi), "film": film},
                black, spp=16)
    assert a.max() > 0 and b.max() > 0
    ca = np.argwhere(a > 0.5 * a.max()).mean(axis=0)
    cb = np.argwhere(b > 0.5 * b.max()).mean(axis=0)
    assert ca[0] < 10 and ca[1] < 14          # up and to the left of the centre (11.5, 15.5)
    assert np.allclose(ca, cb, atol=1.0)    # same place within a pixel (distortion < 1 %)


def test_bad_arguments(mi):
    from workbench.render.lens_camera import lens_sensor_dict
    lens = load_lens("automotive.2.4mm")
    with pytest.raises(ValueError, match="weight"):
        lens_sensor_dict(lens, _film(8, 6), _camera(mi), 1.0, weight="lux")
    with pytest.raises(ValueError, match="sensor_width_mm"):
        lens_sensor_dict(lens, _film(8, 6), _camera(mi), -1.0)
    with pytest.raises(ValueError, match="film_dict"):
        lens_sensor_dict(lens, {"type": "hdrfilm"}, _camera(mi), 1.0)


def test_aspheric_dispersive_lens_matches_numpy_estimator(mi):
    from workbench.optics.lens import Lens, Surface, focus
    from workbench.render.lens_camera import lens_sensor_dict
    lens = focus(Lens((Surface(1 / 20.0, 4.0, "N-BK7", 6.0, conic=-1.0, asphere_coeffs=(0.0, 2e-5)),
                       Surface(-1 / 60.0, 2.0, "air", 6.0),
                       Surface(0.0, 0.0, "air", 3.0, is_stop=True)), name="asph"), math.inf)
    film = _film(16, 12)
    # A 0.4 mm film: every pixel is on axis for this f = 29.5 mm lens; hero-wavelength weighting
    # makes single pixels noisy (≈7 % at 256 spp), so compare film means.
    img = _render(mi, lens_sensor_dict(lens, film, _camera(mi), sensor_width_mm=0.4), spp=256)
    persp = _render(mi, {"type": "perspective", "fov": 5, "to_world": _camera(mi), "film": film}, spp=16)
    assert img.mean() / persp.mean() == pytest.approx(irradiance_per_radiance(lens), rel=0.015)


def test_drjit_trace_agrees_with_numpy_ray_by_ray(mi):
    """The same rays through the dispersive double Gauss: same survivors, exits within float32 error."""
    import drjit as dr
    from workbench.optics.lens import sensor_z_mm, trace_rays
    from workbench.render.lens_camera.kernels import trace_reverse
    lens = load_lens("dgauss.50mm")
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    g = np.linspace(-14.0, 14.0, 90)
    xx, yy = np.meshgrid(g, g)
    src = np.array([3.0, 5.0, zs])
    d = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, zr)]) - src
    d /= np.linalg.norm(d, axis=1)[:, None]
    ref = trace_rays(lens, np.tile(src, (len(d), 1)), d, 486.1, reverse=True)
    f = lambda a: mi.Float(np.ascontiguousarray(a, dtype=np.float32))  # noqa: E731
    n = len(d)
    out = trace_reverse(lens, f(np.full(n, 3.0)), f(np.full(n, 5.0)), f(np.full(n, zs)),
                         f(d[:, 0]), f(d[:, 1]), f(d[:, 2]), mi.Float(486.1), dr, mi)
    ok = np.array(out[6], dtype=bool)
    assert ref.valid.sum() > 1000
    assert (ok != ref.valid).sum() <= 2      # float32 may flip rays grazing an aperture edge
    both = ok & ref.valid
    assert np.allclose(np.column_stack([np.array(v) for v in out[3:6]])[both], ref.dirs[both], atol=2e-5)
