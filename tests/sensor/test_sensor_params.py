"""Parameter validation: every bad value is refused with an error naming the field."""
from __future__ import annotations


import pytest
from pydantic import ValidationError

from workbench.sensor import CFA_PATTERNS, MAX_PIXELS, SENSOR_PRESETS, SensorParams
from workbench.sensor.cfa import cfa_layout

BAD_VALUES = [
    ("rows", 0), ("cols", -3), ("pixel_pitch_um", 0.0), ("fill_factor", 1.5), ("fill_factor", 0.0),
    ("conversion_gain_uV_per_e", 0.0), ("voltage_swing_V", -1.0), ("dark_voltage_V_per_s", -1e-3),
    ("read_noise_V", -1e-3), ("dsnu_sigma_V", -0.1), ("prnu_sigma_pct", 60.0),
    ("column_fpn_offset_sigma_V", -1.0), ("column_fpn_gain_sigma_pct", -1.0), ("analog_gain", 0.0),
    ("bit_depth", 25), ("bit_depth", -1), ("cfa_pattern", "RGBX"), ("noise_flag", 3),
    ("exposure_s", -0.01), ("exposure_s", float("nan")), ("auto_exposure_method", "median"),
    ("auto_exposure_level", 0.0), ("auto_exposure_level", 1.2), ("ev_bias", 20.0), ("seed", -1),
    ("filter_file", "sensors/no_such_file.csv"), ("unknown_field", 1),
]


@pytest.mark.parametrize("field,value", BAD_VALUES)
def test_bad_value_names_the_field(field, value):
    with pytest.raises(ValidationError) as err:
        SensorParams(**{field: value})
    assert field in str(err.value)


def test_defaults_are_the_paper_camera():
    p = SensorParams()
    assert (p.rows, p.cols, p.pixel_pitch_um, p.bit_depth) == (480, 640, 3.0, 8)
    assert p.full_well_e == pytest.approx(10_000.0)
    assert p.read_noise_e == pytest.approx(10.0) and p.dark_current_e_per_s == pytest.approx(10.0)
    assert p == SENSOR_PRESETS["paper_table1"]


def test_presets_match_their_datasheet_numbers():
    rccc = SENSOR_PRESETS["auto_rccc"]
    assert rccc.cfa_pattern == "RCCC" and rccc.ir_cut_file is None
    assert rccc.full_well_e == pytest.approx(25_454.5, rel=1e-4)
    assert SENSOR_PRESETS["isetcam_default"].bit_depth == 0
    assert SENSOR_PRESETS["isetcam_default"].cfa_pattern == "GRBG"
    assert SENSOR_PRESETS["auto_rggb"].full_well_e > 2 * SENSOR_PRESETS["paper_table1"].full_well_e


def test_huge_sensor_refused_with_the_limit():
    with pytest.raises(ValidationError) as err:
        SensorParams(rows=31623, cols=31623)
    msg = str(err.value)
    assert f"{MAX_PIXELS:,}" in msg and "rows" in msg and "cols" in msg


def test_per_cfa_exposure_must_match_tile():
    SensorParams(exposure_s=[[0.01, 0.02], [0.03, 0.04]])
    with pytest.raises(ValidationError, match="exposure_s"):
        SensorParams(exposure_s=[[0.01, 0.02, 0.03]])
    with pytest.raises(ValidationError, match="exposure"):
        SensorParams(exposure_s=[[0.01, -0.02], [0.03, 0.04]])


def test_offset_must_fit_in_swing_and_filters_must_have_the_channels(tmp_path, monkeypatch):
    from workbench import spectrum_csv
    with pytest.raises(ValidationError, match="analog_offset_V"):
        SensorParams(analog_offset_V=1.0, voltage_swing_V=1.0)
    monkeypatch.setattr(spectrum_csv, "RESOURCES", tmp_path)      # spectral files live under resources/
    (tmp_path / "rgb.csv").write_text("wavelength_nm,R,G,B\n400,0.1,0.2,0.3\n700,0.1,0.2,0.3\n")
    SensorParams(filter_file="rgb.csv", photodiode_qe_file=None, ir_cut_file=None, cfa_pattern="RGGB")
    with pytest.raises(ValidationError, match="filter_file 'rgb.csv' has no curve C"):
        SensorParams(filter_file="rgb.csv", photodiode_qe_file=None, ir_cut_file=None, cfa_pattern="RCCC")
    with pytest.raises(ValidationError, match="filter_file"):
        SensorParams(filter_file=None, cfa_pattern="RGGB")
    SensorParams(filter_file=None, cfa_pattern="MONO")


def test_cfa_layouts():
    expected = {"RGGB": [["R", "G"], ["G", "B"]], "GRBG": [["G", "R"], ["B", "G"]],
                "GBRG": [["G", "B"], ["R", "G"]], "BGGR": [["B", "G"], ["G", "R"]],
                "RCCC": [["R", "C"], ["C", "C"]], "RCCB": [["R", "C"], ["C", "B"]],
                "RGBW": [["R", "G"], ["B", "W"]], "MONO": [["M", "M"], ["M", "M"]]}
    assert set(expected) == set(CFA_PATTERNS)
    for name, letters in expected.items():
        tile, names = cfa_layout(name)
        assert [[names[i] for i in row] for row in tile] == letters
