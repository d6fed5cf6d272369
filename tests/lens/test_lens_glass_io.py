"""Glass catalogue and lens file formats (ISETCam JSON, PBRT .dat, Zemax .zmx subset)."""
import numpy as np
import pytest

from workbench.errors import InputFileError

from workbench.optics.lens import (LINE_C_NM, LINE_D_NM, LINE_F_NM, available_lenses, glass_catalogue,
                                   load_lens, material, paraxial, save_lens)
from workbench.optics.lens.io import lens_from_dat

# Smith, Modern Lens Design p.312 as written in PBRT's dgauss.50mm.dat (optics.md §4).
DGAUSS_DAT = """# dgauss 50 mm
29.475 3.76 1.67 25.2
84.83 0.12 1 25.2
19.275 4.025 1.67 23
40.77 3.275 1.699 23
12.75 5.705 1 18
0 4.5 0 17.1
-14.495 1.18 1.603 17
40.77 6.065 1.658 20
-20.385 0.19 1 20
437.065 3.22 1.717 20
-39.73 0 1 20
"""


def test_catalogue_has_twelve_glasses_and_recomputed_nd_vd_match():
    cat = glass_catalogue()
    assert len(cat) >= 12
    for name, g in cat.items():
        m = material(name)
        nd, nf, nc = (m.index(w) for w in (LINE_D_NM, LINE_F_NM, LINE_C_NM))
        assert nd == pytest.approx(g["nd"], abs=2e-5), name
        assert (nd - 1) / (nf - nc) == pytest.approx(g["vd"], abs=0.02), name


def test_abbe_fallback_reproduces_nd_and_vd():
    m = material("1.67/47.1")
    nd, nf, nc = (m.index(w) for w in (LINE_D_NM, LINE_F_NM, LINE_C_NM))
    assert nd == pytest.approx(1.67, abs=1e-12)
    assert (nd - 1) / (nf - nc) == pytest.approx(47.1, rel=1e-10)


def test_fallback_close_to_sellmeier_in_the_visible():
    wl = np.linspace(450, 650, 9)
    assert np.allclose(material("1.5168/64.17").index(wl), material("N-BK7").index(wl), atol=3e-4)


@pytest.mark.parametrize("bad", ["unobtainium", "0.5", "1.5/-3", "", {"wavelength_nm": [500], "n": []}])
def test_bad_material_names_the_value(bad):
    with pytest.raises(ValueError, match="material"):
        material(bad)


def test_table_material_interpolates():
    m = material({"wavelength_nm": [400, 700], "n": [1.6, 1.5]})
    assert m.index(550) == pytest.approx(1.55)


def test_shipped_lenses_load():
    names = available_lenses()
    for n in ("dgauss.50mm", "wide.22mm", "fisheye.10mm", "automotive.2.4mm"):
        assert n in names
        assert load_lens(n).surfaces


def test_automotive_lens_gives_papers_44_degree_field():
    p = paraxial(load_lens("automotive.2.4mm"))
    assert p.efl_mm == pytest.approx(2.376, abs=1e-3)
    assert p.fov_deg(640 * 3e-3) == pytest.approx(44.0, abs=1e-6)


def test_dat_reader_and_round_trips(tmp_path):
    lens = lens_from_dat(DGAUSS_DAT, name="dg")
    assert lens.stop_index == 5 and lens.surfaces[5].semi_aperture_mm == pytest.approx(8.55)
    assert lens.surfaces[0].material.nd == 1.67 and lens.surfaces[1].material.is_air
    p0 = paraxial(lens)
    for ext in (".dat", ".json"):
        back = load_lens(save_lens(lens, tmp_path / f"x{ext}"))
        p1 = paraxial(back)
        assert p1.efl_mm == pytest.approx(p0.efl_mm, rel=1e-12)
        assert p1.epd_mm == pytest.approx(p0.epd_mm, rel=1e-12)
        assert back.stop_index == 5


def test_json_round_trip_keeps_dispersion_and_focus(tmp_path):
    from workbench.optics.lens import focus
    lens = focus(load_lens("dgauss.50mm"), 2.0)
    back = load_lens(save_lens(lens, tmp_path / "f.json"))
    assert back.image_distance_mm == pytest.approx(lens.image_distance_mm)
    assert paraxial(back, LINE_F_NM).bfl_mm == pytest.approx(paraxial(lens, LINE_F_NM).bfl_mm, rel=1e-12)


def test_isetcam_style_json_with_ior_table(tmp_path):
    import json
    data = {"name": "t", "surfaces": [
        {"radius": 20, "thickness": 3, "ior": [[400, 700], [1.52, 1.50]], "semi_aperture": 5},
        {"radius": 0, "thickness": 1, "ior": 0, "semi_aperture": 3},
        {"radius": -20, "thickness": 0, "ior": 1, "semi_aperture": 5}]}
    p = tmp_path / "t.json"
    p.write_text(json.dumps(data))
    lens = load_lens(p)
    assert lens.surfaces[1].is_stop and lens.surfaces[1].material.index(550) == pytest.approx(1.51)


ZMX = """VERS 190513 80 123457 L123457
UNIT MM X W X CM MR CPMM
SURF 0
  TYPE STANDARD
  CURV 0.0
  DISZ INFINITY
SURF 1
  TYPE STANDARD
  CURV 0.02
  DISZ 5
  GLAS N-BK7 1 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 10
SURF 2
  STOP
  TYPE STANDARD
  CURV 0.0
  DISZ 2
  GLAS MYGLASS 1 0 1.6 40 0 0 0 0 0 0
  DIAM 8
SURF 3
  TYPE EVENASPH
  CURV -0.01
  CONI -1.5
  PARM 1 0
  PARM 2 1e-5
  PARM 3 -2e-8
  DISZ 80
  DIAM 10
SURF 4
  TYPE STANDARD
  CURV 0.0
  DISZ 0
"""


@pytest.mark.parametrize("encoding", ["utf-8", "utf-16"])
def test_zmx_subset_reader(tmp_path, encoding):
    p = tmp_path / "l.zmx"
    p.write_bytes(ZMX.encode(encoding))   # Zemax often writes UTF-16 with a BOM
    lens = load_lens(p)
    assert len(lens.surfaces) == 3
    s1, s2, s3 = lens.surfaces
    assert s1.material.spec == "N-BK7" and s1.semi_aperture_mm == 10
    assert s2.is_stop and s2.material.nd == pytest.approx(1.6) and s2.material.vd == pytest.approx(40)
    assert s3.conic == -1.5 and s3.asphere_coeffs == (0.0, 1e-5, -2e-8)
    assert lens.image_distance_mm == 80


def test_zmx_unsupported_surface_type_is_refused(tmp_path):
    p = tmp_path / "l.zmx"
    p.write_text(ZMX.replace("TYPE EVENASPH", "TYPE TOROIDAL"))
    with pytest.raises(ValueError, match="surface TYPE is not supported") as err:
        load_lens(p)
    assert "TOROIDAL" not in str(err.value)            # the file's content is not echoed


def test_errors_never_echo_lens_file_tokens_or_long_names(tmp_path):
    from workbench.errors import MAX_SHOWN_NAME
    p = tmp_path / "l.zmx"
    p.write_text(ZMX.replace("TYPE EVENASPH", "TYPE SECRETTOKEN42"))
    with pytest.raises(ValueError) as err:
        load_lens(p)
    assert "SECRETTOKEN42" not in str(err.value)
    long_name = "x" * 5000
    with pytest.raises(InputFileError) as err:
        load_lens(long_name)
    assert long_name not in str(err.value) and len(str(err.value).split(":")[0]) <= MAX_SHOWN_NAME


def test_unknown_lens_name_lists_available():
    with pytest.raises(InputFileError, match="dgauss.50mm"):
        load_lens("no-such-lens")


def test_bad_dat_line_names_line():
    with pytest.raises(ValueError, match="line 2"):
        lens_from_dat("10 1 1.5 5\n10 1 x 5\n")


def test_automotive_real_field_of_view():
    from workbench.optics.lens import real_fov_deg
    assert real_fov_deg(load_lens("automotive.2.4mm"), 640 * 3e-3) == pytest.approx(44.0, abs=0.5)


def test_asphere_and_flat_surfaces_round_trip(tmp_path):
    from workbench.optics.lens import Lens, Surface
    lens = Lens((Surface(1 / 20.0, 4.0, "N-BK7", 6.0, conic=-1.0, asphere_coeffs=(0.0, 2e-5, -1e-8)),
                 Surface(0.0, 2.0, "air", 6.0),
                 Surface(0.0, 1.0, "air", 3.0, is_stop=True),
                 Surface.from_radius(-30.0, 0.0, "air", 5.0)), name="a", image_distance_mm=25.0)
    back = load_lens(save_lens(lens, tmp_path / "a.json"))
    assert back.surfaces == lens.surfaces and back.image_distance_mm == 25.0
    dat = load_lens(save_lens(lens, tmp_path / "a.dat"))
    assert dat.surfaces[1].radius_mm == 1e6 and not dat.surfaces[1].is_stop and dat.surfaces[2].is_stop
    assert dat.surfaces[0].material.kind == "constant"   # PBRT keeps only n_d


@pytest.mark.parametrize("field,value", [("thickness_mm", -1.0), ("semi_aperture_mm", 0.0),
                                         ("curvature_per_mm", float("nan"))])
def test_bad_surface_values_name_the_field(field, value):
    from workbench.optics.lens import Surface
    kw = dict(curvature_per_mm=0.01, thickness_mm=1.0, material="air", semi_aperture_mm=5.0)
    kw[field] = value
    with pytest.raises(ValueError, match=field):
        Surface(**kw)
