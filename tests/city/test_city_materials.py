"""Spectral reflectances: physical (0…1, finite, smooth) over 350–1000 nm, with the known
features (vegetation red edge, NIR-bright paints, flat dark asphalt), and plausible colours
(sRGB under D65 computed with colour-science)."""
import numpy as np
import pytest

from workbench.scene.city import city_materials, reflectance
from workbench.scene.city.materials import CAR_PAINTS, MATERIAL_WAVELENGTHS_NM, material_names
from workbench.scene.city.view import material_srgb

WL = MATERIAL_WAVELENGTHS_NM


def _band(name, lo, hi):
    r = reflectance(name)
    return r[(WL >= lo) & (WL <= hi)].mean()


def test_grid_covers_350_to_1000():
    assert WL[0] == 350 and WL[-1] == 1000 and np.allclose(np.diff(WL), 5.0)


@pytest.mark.parametrize("name", material_names())
def test_physical_and_smooth(name):
    r = reflectance(name)
    assert np.all(np.isfinite(r)) and r.min() >= 0.0 and r.max() <= 1.0
    assert np.abs(np.diff(r)).max() <= 0.08          # no steps sharper than 0.08 per 5 nm
    assert np.abs(np.diff(r, 2)).max() <= 0.03       # and no kinks


@pytest.mark.parametrize("name", ["leaves", "grass"])
def test_vegetation_red_edge(name):
    red, green, blue = _band(name, 660, 680), _band(name, 540, 560), _band(name, 440, 470)
    nir = _band(name, 760, 900)
    assert red < 0.07 and blue < 0.07 and green > red + 0.04    # chlorophyll: green bump
    assert nir > 0.4 and nir > 6 * red                            # red edge
    edge = WL[np.argmax(np.diff(reflectance(name)))]
    assert 690 <= edge <= 740


def test_asphalt_dark_and_flat():
    r = reflectance("asphalt")
    assert 0.05 <= r.min() and r.max() <= 0.10 and r.max() - r.min() < 0.05


@pytest.mark.parametrize("name", ["paint_white", "paint_red", "paint_blue", "paint_green",
                                  "paint_yellow", "paint_silver"])
def test_coloured_paints_reflect_in_nir(name):
    assert _band(name, 800, 950) >= 0.4


def test_carbon_black_stays_dark_in_nir():
    assert _band("paint_black", 350, 1000) < 0.06 and _band("rubber", 800, 1000) < 0.06


def test_blue_paint_and_denim_rise_past_700():
    for name in ("paint_blue", "cloth_denim"):
        assert _band(name, 620, 660) < 0.12 and _band(name, 800, 900) > 0.45


def test_skin_haemoglobin_and_nir():
    for name in ("skin_light", "skin_medium", "skin_dark"):
        r = reflectance(name)
        dip = r[WL == 575][0]
        assert dip < r[WL == 520][0] + 0.02 and dip < r[WL == 620][0]
        assert _band(name, 750, 900) > _band(name, 500, 600)
    assert _band("skin_light", 400, 700) > _band("skin_medium", 400, 700) > _band("skin_dark", 400, 700)


def test_colours_under_d65():
    mats = city_materials()
    rgb = {n: material_srgb(mats[n]) for n in ("leaves", "brick", "paint_blue", "lane_yellow",
                                                 "paint_white", "asphalt", "paint_red")}
    assert rgb["leaves"][1] > rgb["leaves"][0] and rgb["leaves"][1] > rgb["leaves"][2]
    assert rgb["brick"][0] > rgb["brick"][1] > rgb["brick"][2]
    assert rgb["paint_blue"][2] > rgb["paint_blue"][0]
    assert rgb["lane_yellow"][0] > rgb["lane_yellow"][2] + 0.3
    assert rgb["paint_red"][0] > rgb["paint_red"][1] + 0.3
    assert np.ptp(rgb["paint_white"]) < 0.05 and rgb["paint_white"].min() > 0.85
    assert rgb["asphalt"].max() < 0.4


def test_resampling_and_errors():
    r = reflectance("concrete", np.array([400.0, 402.5, 950.0]))
    assert r[1] == pytest.approx(0.5 * (reflectance("concrete", [400.0])[0] +
                                        reflectance("concrete", [405.0])[0]))
    with pytest.raises(ValueError, match="unknown material 'unobtainium'"):
        reflectance("unobtainium")
    assert abs(sum(CAR_PAINTS.values()) - 1.0) < 1e-9
    m = city_materials()["asphalt"]
    m.reflectance[:] = 2.0                     # a caller's copy: the table stays intact
    assert reflectance("asphalt").max() < 0.1
