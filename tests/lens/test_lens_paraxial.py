"""Paraxial data of the shipped lenses against optics.md's published values, optiland and rayoptics."""
import math

import pytest

from workbench.optics.lens import focus, image_distance_mm, load_lens, paraxial, sensor_distance_mm

# optics.md §4 (values agreed by optiland, rayoptics and a y-nu trace).
EXPECTED = {
    "dgauss.50mm": dict(efl_mm=50.3582, bfl_mm=36.1059, epd_mm=24.805, f_number=2.030, entrance_pupil_mm=19.946),
    "wide.22mm": dict(efl_mm=22.0235, bfl_mm=14.3183, epd_mm=8.206, f_number=2.684, entrance_pupil_mm=12.089),
    "fisheye.10mm": dict(efl_mm=9.9914, bfl_mm=23.1605, epd_mm=2.532, f_number=3.947, entrance_pupil_mm=11.542),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_paraxial_matches_published_values(name):
    p = paraxial(load_lens(name))
    for key, val in EXPECTED[name].items():
        digits = len(str(val).split(".")[1])
        assert getattr(p, key) == pytest.approx(val, abs=0.51 * 10 ** -digits), key


@pytest.mark.parametrize("name", sorted(EXPECTED) + ["automotive.2.4mm"])
def test_paraxial_matches_rayoptics(name, oracles):
    lens = load_lens(name)
    p, fod = paraxial(lens), oracles["rayoptics"](lens)
    assert p.efl_mm == pytest.approx(fod.efl, rel=1e-4)
    assert p.bfl_mm == pytest.approx(fod.bfl, rel=1e-4)
    assert p.f_number == pytest.approx(fod.fno, rel=1e-4)
    assert p.entrance_pupil_mm == pytest.approx(fod.enp_dist, rel=1e-4)
    assert p.epd_mm == pytest.approx(2 * fod.enp_radius, rel=1e-4)
    assert p.exit_pupil_mm == pytest.approx(fod.exp_dist, rel=1e-4)
    assert p.exit_pupil_diameter_mm == pytest.approx(2 * fod.exp_radius, rel=1e-4)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_paraxial_matches_optiland(name, oracles):
    lens = load_lens(name)
    p, o = paraxial(lens), oracles["optiland"](lens)
    assert p.efl_mm == pytest.approx(float(o.paraxial.f2()), rel=1e-4)
    assert p.entrance_pupil_mm == pytest.approx(float(o.paraxial.EPL()), rel=1e-4)
    assert p.f_number == pytest.approx(float(o.paraxial.FNO()), rel=1e-4)
    # optiland measures the exit pupil from the image plane
    assert p.exit_pupil_mm - sensor_distance_mm(lens) == pytest.approx(float(o.paraxial.XPL()), rel=1e-4)


def test_fov_for_sensor():
    p = paraxial(load_lens("dgauss.50mm"))
    assert p.fov_deg(36.0) == pytest.approx(math.degrees(2 * math.atan(18 / p.efl_mm)))


def test_focus_obeys_newton_equation():
    lens = load_lens("dgauss.50mm")
    p = paraxial(lens)
    for d_m in (0.5, 2.0, 10.0):
        f = focus(lens, d_m)
        # Newton: x·x' = −f² with x, x' measured from the focal points.
        x = -(d_m * 1e3 - p.ffl_mm)
        xp = f.image_distance_mm - p.bfl_mm
        assert x * xp == pytest.approx(-p.efl_mm ** 2, rel=1e-10)
    assert sensor_distance_mm(focus(lens, math.inf)) == pytest.approx(p.bfl_mm)


def test_focus_closer_than_possible_is_a_clear_error():
    lens = load_lens("dgauss.50mm")
    with pytest.raises(ValueError, match="cannot focus at object_distance_m=0.02.*farther than 0.0271"):
        focus(lens, 0.02)
    with pytest.raises(ValueError, match="object_distance_m"):
        focus(lens, -1.0)


def test_thin_lens_limit():
    from workbench.optics.lens import Lens, Surface
    # Biconvex thin lens R = ±100, n = 1.5: f = 1/((n−1)(2/R)) = 100 mm.
    lens = Lens((Surface.from_radius(100, 1e-9, "1.5", 10, is_stop=False),
                 Surface.from_radius(-100, 0, "air", 10)))
    assert paraxial(lens).efl_mm == pytest.approx(100.0, rel=1e-9)
    assert image_distance_mm(lens, 0.2) == pytest.approx(200.0, rel=1e-8)


def test_scaling_scales_lengths_not_f_number():
    from workbench.optics.lens import Lens, Surface
    lens = Lens((Surface(1 / 20.0, 4.0, "N-BK7", 6.0, conic=-0.5, asphere_coeffs=(1e-4, 2e-5)),
                 Surface(-1 / 60.0, 2.0, "air", 6.0), Surface(0.0, 0.0, "air", 3.0, is_stop=True)))
    big = lens.scaled(2.5)
    p, q = paraxial(lens), paraxial(big)
    assert q.efl_mm == pytest.approx(2.5 * p.efl_mm, rel=1e-12)
    assert q.f_number == pytest.approx(p.f_number, rel=1e-12)
    assert big.surfaces[0].sag_mm(2.5 * 4.0) == pytest.approx(2.5 * lens.surfaces[0].sag_mm(4.0), rel=1e-12)
    with pytest.raises(ValueError, match="scale factor"):
        lens.scaled(0.0)


def test_patent_glasses_shift_the_double_gauss_as_published():
    """optics.md §4: with Tronnier's patent indices the double Gauss has EFL 50.0075, f/2.013."""
    import dataclasses
    from workbench.optics.lens import material
    patent = {1.67: "1.67125/47.1", 1.699: "1.69842/30.1", 1.603: "1.60266/38.4", 1.658: "1.65953/57.0",
              1.717: "1.71740/48.1"}
    lens = load_lens("dgauss.50mm")
    surfs = tuple(dataclasses.replace(s, material=material(patent[s.material.nd]))
                  if s.material.nd in patent else s for s in lens.surfaces)
    p = paraxial(dataclasses.replace(lens, surfaces=surfs))
    assert p.efl_mm == pytest.approx(50.0075, abs=6e-5)
    assert p.f_number == pytest.approx(2.013, abs=6e-4)


def test_reading_a_lens_resolves_its_unflagged_stop():
    """A prescription with no stop row gets the surface that limits the axial beam as its stop
    when read; a Lens built in code keeps None until paraxial.with_aperture_stop resolves it."""
    from workbench.optics.lens import Lens, Surface
    from workbench.optics.lens.io import lens_from_dat
    from workbench.optics.lens.paraxial import with_aperture_stop
    # Two surfaces; the second (semi-aperture 2 mm) clips the axial beam before the first (10 mm).
    text = "100 5 1.5 20\n-100 95 1.0 4\n"
    lens = lens_from_dat(text, "two")
    assert lens.stop_index == 1
    assert paraxial(lens).epd_mm < 20.0 * 0.5      # the pupil is the image of the 2 mm rear surface
    built = Lens((Surface.from_radius(100, 5, "1.5", 10), Surface.from_radius(-100, 0, "air", 2)))
    assert built.stop_index is None
    assert with_aperture_stop(built).stop_index == 1
    with pytest.raises(ValueError, match="no resolved aperture stop"):
        built.with_stop_semi_aperture(1.0)
    flagged = Lens((Surface.from_radius(0, 1, "air", 3, is_stop=True), Surface.from_radius(-50, 0, "air", 1)))
    assert flagged.stop_index == 0 and with_aperture_stop(flagged).stop_index == 0
