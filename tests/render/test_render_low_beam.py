"""The low-beam head-light (render/low_beam.py, issue 33's last night fireflies).

Oracles: the SAE J1383 low-beam table (every minimum and maximum, over each range's whole extent),
the closed-form pattern against what Mitsuba's own `spot` returns with the pattern as its projection
texture (the texture's orientation and interpolation), and the pattern's flux integrated a second way
(over the texture's texels with the gnomonic solid angle). The head-light that replaced a symmetric
20,000 cd cone (full within 10°, aimed 1.7° down) lit the road 2 m ahead of the car at ~800 lx
(measured 690–1,580 lx in city_night frames, 2026-11-28): a small bright patch that one bounce
found rarely, the night's remaining fireflies. The low beam lights it at ~6 lx."""
import numpy as np
import pytest

from workbench.errors import InvalidValueError
from workbench.render.lamps import headlight_emitter
from workbench.render.low_beam import (J1383_LOW_BEAM, J1383_PEAK_CD, TEXTURE_CUTOFF_DEG, low_beam_cd,
                                       low_beam_flux_lm, texture_array, direction_angles_deg)


@pytest.mark.parametrize("row", J1383_LOW_BEAM, ids=[r[0] for r in J1383_LOW_BEAM])
def test_the_pattern_meets_sae_j1383_low_beam(row):
    _, (v0, v1), (h0, h1), lo, hi = row
    v = np.linspace(v0, v1, 41) if v1 > v0 else np.array([v0])
    h = np.linspace(h0, h1, 181) if h1 > h0 else np.array([h0])
    cd = low_beam_cd(h[None, :], v[:, None], J1383_PEAK_CD)
    if lo is not None:
        assert cd.min() >= lo, cd.min()
    if hi is not None:
        assert cd.max() <= hi, cd.max()


def test_the_hot_spot_is_the_peak_and_the_cut_off_is_sharp():
    h, v = np.meshgrid(np.linspace(-45, 45, 361), np.linspace(-20, 10, 301))
    cd = low_beam_cd(h, v, 1.0)
    assert cd.max() == pytest.approx(low_beam_cd(2.0, -1.5, 1.0), rel=1e-3) == pytest.approx(1.0, rel=1e-3)
    # UN R112 / R149 cut-off sharpness G = log10 E(β) − log10 E(β + 0.1°) at 2.5° left, at the steepest point
    beta = np.arange(-3.0, 1.0, 0.01)
    e = np.log10(low_beam_cd(-2.5, beta, 1.0))
    g = e[:-10] - e[10:]
    assert 0.13 <= g.max() <= 0.40, g.max()


def _angles_to_points(h_deg, v_deg, origin, distance):
    h, v = np.radians(h_deg), np.radians(v_deg)
    d = np.stack([np.cos(v) * np.sin(h), np.cos(v) * np.cos(h), np.sin(v)], -1)        # lamp faces +y: right is +x
    return origin + distance * d


def _spot_values(mi, spot_dict, points):
    import drjit as dr
    si = dr.zeros(mi.SurfaceInteraction3f, len(points))
    si.p = mi.Point3f(*(mi.Float(c) for c in np.asarray(points, np.float32).T))
    si.wavelengths = mi.UnpolarizedSpectrum(555.0)
    spot = mi.load_dict({"type": "scene", "s": spot_dict}).emitters()[0]
    value = np.array(spot.sample_direction(si, mi.Point2f(0.5, 0.5))[1], dtype=np.float64)[0]
    wl, i = (np.array(x) for x in zip(*spot_dict["intensity"]["value"]))
    return value / np.interp(555.0, wl, i)                 # × r²: the relative intensity toward the point


def test_mitsuba_s_spot_with_the_texture_gives_the_pattern(mi):
    origin = np.array([0.0, 0.0, 0.65])
    head = headlight_emitter(origin, [0.0, 1.0, 0.0], "led", 20000.0)
    hs, vs = np.meshgrid(np.linspace(-40, 40, 33), np.r_[np.linspace(-30, -2, 15), np.linspace(-1.9, 3, 50), 5, 10, 20])
    points = _angles_to_points(hs.ravel(), vs.ravel(), origin, 10.0)
    got = _spot_values(mi, head, points) * 100.0
    want = low_beam_cd(hs.ravel(), vs.ravel(), 1.0)
    err = np.abs(got - want) / want
    assert np.median(err) < 1e-3, np.median(err)
    assert err.max() < 0.15, err.max()                     # bilinear texels across the cut-off
    away = np.abs(vs.ravel() - (-0.5)) > 1.0
    assert err[away].max() < 0.03, err[away].max()          # the hot spot's kinks


def test_the_flux_is_the_integral_over_the_texture_s_texels():
    rows, cols = 2048, 1024
    f = np.tan(np.radians(TEXTURE_CUTOFF_DEG))
    y = (2.0 * (np.arange(rows) + 0.5) / rows - 1.0) * f
    x = (2.0 * (np.arange(cols) + 0.5) / cols - 1.0) * f
    xx, yy = np.meshgrid(x, y)
    h, v = direction_angles_deg(xx, yy, 1.0)
    inside = 1.0 / np.sqrt(1 + xx ** 2 + yy ** 2) > np.cos(np.radians(TEXTURE_CUTOFF_DEG))
    solid_angle = (2 * f / cols) * (2 * f / rows) / (1 + xx ** 2 + yy ** 2) ** 1.5     # gnomonic texel, sr
    flux = (low_beam_cd(h, v, J1383_PEAK_CD) * inside * solid_angle).sum()
    assert low_beam_flux_lm(J1383_PEAK_CD) == pytest.approx(flux, rel=0.01)
    assert 200.0 < flux < 2000.0, flux
    assert texture_array((64, 32)).max() == 1.0


def test_the_road_just_ahead_of_a_car_gets_a_few_lux_not_hundreds(mi):
    origin = np.array([0.0, 0.0, 0.65])
    head = headlight_emitter(origin, [0.0, 1.0, 0.0], "led", 20000.0)
    road = np.array([[0.0, 2.0, 0.0], [0.5, 3.0, 0.0], [-0.3, 1.1, 0.0]])
    to_lamp = origin - road
    r = np.linalg.norm(to_lamp, axis=1)
    lux = 20000.0 * _spot_values(mi, head, road) * (to_lamp[:, 2] / r)      # I cos θ / r²
    assert lux.max() < 20.0, lux
    h = np.degrees(np.arctan2(road[:, 0], road[:, 1]))
    v = np.degrees(np.arctan2(-origin[2], np.hypot(road[:, 0], road[:, 1])))
    np.testing.assert_allclose(lux, low_beam_cd(h, v) * (to_lamp[:, 2] / r) / r ** 2, rtol=0.02)


def test_a_head_light_is_aimed_by_its_pattern_not_by_tilting():
    with pytest.raises(InvalidValueError, match="horizontal"):
        headlight_emitter([0.0, 0.0, 0.65], [1.0, 0.0, -0.03], "led", 20000.0)
    with pytest.raises(InvalidValueError, match="peak_cd"):
        low_beam_flux_lm(0.0)


def test_the_view_weights_read_the_pattern(mi):
    """NightParams.light_selection 'view' weighs a head-light by spot_importance, which reads the
    texture (nearest texel) as the lamp set does: it follows I(h, v) cos θ / r² to 5 %."""
    from workbench.render.lamps import spot_importance
    origin = np.array([0.0, 0.0, 0.65])
    head = headlight_emitter(origin, [0.0, 1.0, 0.0], "led", 20000.0)
    points = np.array([[0.9, 25.0, 0.0], [0.0, 2.0, 0.0], [0.0, 20.0, 3.0], [-6.0, 12.0, 0.0]])
    d = points - origin
    r = np.linalg.norm(d, axis=1)
    want = (low_beam_cd(np.degrees(np.arctan2(d[:, 0], d[:, 1])), np.degrees(np.arcsin(d[:, 2] / r)))
            * np.abs(d[:, 2]) / r / r ** 2)
    got = spot_importance(points, np.tile([0.0, 0.0, 1.0], (len(points), 1)), head)
    np.testing.assert_allclose(got, want, rtol=0.05)
