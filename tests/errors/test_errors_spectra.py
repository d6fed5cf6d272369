"""Spectral data files: confined to resources/ like lenses, every file validated (finite, in [0, 1],
strictly increasing wavelengths), errors name the file and line and never echo its contents."""
import json

import numpy as np
import pytest

from workbench import spectrum_csv
from workbench.errors import InputFileError, ParameterError
from workbench.project import PROJECTS_DIR, project_from_dict
from workbench.spectra import illuminant_spd, load_spectrum_csv

GOOD = "wavelength_nm,QE\n400,0.1\n500,0.5\n600,0.9\n700,0.4\n"


@pytest.fixture
def resources(tmp_path, monkeypatch):
    """A private resources/ folder holding sensors/ for the test's files."""
    (tmp_path / "sensors").mkdir()
    monkeypatch.setattr(spectrum_csv, "RESOURCES", tmp_path)
    return tmp_path


def _write(resources, text: str, name: str = "sensors/s.csv") -> str:
    (resources / name).write_text(text)
    return name


@pytest.mark.parametrize("text,problem", [
    (GOOD.replace("0.5", "-0.5"), "line 3, curve 'QE': transmittance / QE must lie in [0, 1]"),
    (GOOD.replace("0.5", "1.5"), "line 3, curve 'QE'"),
    (GOOD.replace("0.5", "inf"), "line 3: every value must be a finite number"),
    (GOOD.replace("0.5", "nan"), "line 3: every value must be a finite number"),
    ("wavelength_nm,QE\n700,0.1\n600,0.5\n500,0.9\n", "line 3: wavelengths must increase strictly"),
    ("wavelength_nm,QE\n400,0.1\n600,0.5\n500,0.9\n", "line 4: wavelengths must increase strictly"),
    ("wavelength_nm,QE\n400,0.1\n500,0.5\n500,0.9\n", "line 4: wavelengths must increase strictly"),
    ("wavelength_nm,QE\n400,0.1\n500,secret-word\n", "line 3: expected 2 comma-separated numbers"),
    ("wavelength_nm,QE\n400,0.1,7\n500,0.2\n", "line 2: expected 2"),
    ("wavelength_nm,QE,QE\n400,0.1,0.1\n500,0.2,0.2\n", "distinct"),
    ("wavelength_nm,QE\n400,0.1\n", "at least two rows"),
    ("wavelength_nm,QE\n4,0.1\n5,0.2\n", "wavelengths must lie in"),
])
def test_bad_spectrum_file_is_refused_naming_file_and_line(resources, text, problem):
    name = _write(resources, text)
    with pytest.raises(InputFileError) as info:
        load_spectrum_csv(name, np.arange(400.0, 701.0, 10.0))
    msg = str(info.value)
    assert problem in msg and str(resources / name) in msg
    assert "secret-word" not in msg


def test_binary_file_and_paths_outside_resources(resources):
    (resources / "sensors" / "b.csv").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00")
    with pytest.raises(InputFileError, match="b.csv"):
        load_spectrum_csv("sensors/b.csv", np.array([500.0]))
    for name in ("/etc/passwd", "../secret.csv", "sensors/../../x.csv"):
        with pytest.raises(ValueError, match="relative to"):
            load_spectrum_csv(name, np.array([500.0]))
    with pytest.raises(InputFileError, match="no such spectral data file"):
        load_spectrum_csv("sensors/missing.csv", np.array([500.0]))


def test_a_good_file_reads_and_is_zero_outside_its_range(resources):
    values, names = load_spectrum_csv(_write(resources, GOOD), np.array([350.0, 450.0, 700.0, 750.0]))
    assert names == ["QE"]
    np.testing.assert_allclose(values[:, 0], [0.0, 0.3, 0.4, 0.0])


@pytest.mark.parametrize("field", ["filter_file", "photodiode_qe_file", "ir_cut_file"])
def test_project_naming_a_bad_spectrum_is_refused_when_it_loads(resources, field):
    _write(resources, "wavelength_nm,R,G,B,IRCUT,QE\n400,0.1,0.1,0.1,0.1,0.1\n500,0.2,0.2,0.2,0.2,0.2\n",
           "sensors/ok.csv")
    bad = _write(resources, GOOD.replace("0.5", "-1"), "sensors/bad.csv")
    data = json.loads((PROJECTS_DIR / "paper_camera.json").read_text())
    for f in ("filter_file", "photodiode_qe_file", "ir_cut_file"):
        data["sensor"][f] = "sensors/ok.csv"
    data["sensor"][field] = bad
    with pytest.raises(ParameterError) as info:
        project_from_dict(data, "p.json")
    assert info.value.field == f"sensor.{field}" and "must lie in [0, 1]" in str(info.value)
    data["sensor"][field] = "/etc/passwd"
    with pytest.raises(ParameterError) as info:
        project_from_dict(data, "p.json")
    assert info.value.field == f"sensor.{field}" and "relative to" in str(info.value)


@pytest.mark.parametrize("name", ["blackbody:inf", "blackbody:nan", "blackbody:1", "blackbody:-5000",
                                  "blackbody:1e9"])
def test_blackbody_outside_its_range_is_refused_with_the_range(name):
    with pytest.raises(ValueError, match="1000–100000 K"):
        illuminant_spd(name, np.arange(400.0, 701.0, 10.0))
    spd = illuminant_spd("blackbody:1000", np.arange(300.0, 1101.0, 10.0))
    assert np.all(np.isfinite(spd)) and spd.max() == 1.0
