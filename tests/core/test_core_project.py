"""Project files: round trip, atomic save, and a clear error for every malformed field."""
import json
import os

import pytest

from workbench.errors import InputFileError, ParameterError
from workbench.project import PROJECTS_DIR, Project, load_project, project_from_dict, save_project


def _paper() -> dict:
    return json.loads((PROJECTS_DIR / "paper_camera.json").read_text())


def test_samples_load_and_round_trip(tmp_path):
    samples = sorted(PROJECTS_DIR.glob("*.json"))
    assert any("paper" in p.name for p in samples)
    for path in samples:
        project = load_project(path)
        out = tmp_path / path.name
        save_project(project, out)
        assert load_project(out) == project
    assert load_project("paper_camera").sensor.rows == 480      # by sample name


@pytest.mark.parametrize("path,value,expect", [
    (("sensor", "pixel_pitch_um"), -3.0, "sensor.pixel_pitch_um"),
    (("sensor", "cfa_pattern"), "RGBX", "sensor.cfa_pattern"),
    (("sensor", "exposure_s"), -0.01, "exposure"),
    (("sensor", "rows"), 100000, "sensor.rows"),
    (("sensor", "bit_depth"), "eight", "sensor.bit_depth"),
    (("optics", "f_number"), 0.0, "optics.f_number"),
    (("optics", "model"), "fisheye-magic", "optics.model"),
    (("isp", "demosaic"), "magic", "isp.demosaic"),
    (("scene", "kind"), "moon", "scene.kind"),
    (("scene", "illuminant"), "D66", "scene.illuminant"),
    (("scene", "wavelengths", "step_nm"), 0, "scene.wavelengths.step_nm"),
    (("scene", "unknown_field"), 1, "scene.unknown_field"),
    (("experiment", "auto_exposure_level"), 2.0, "experiment.auto_exposure_level"),
])
def test_each_malformed_field_is_named(path, value, expect):
    data = _paper()
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ParameterError) as info:
        project_from_dict(data, "bad.json")
    msg = str(info.value)
    assert info.value.field == ".".join(path) and info.value.source == "bad.json"
    assert expect in msg and "bad.json" in msg
    assert "given" in msg


def test_sensor_of_a_billion_pixels_says_what_to_change():
    data = _paper()
    data["sensor"]["rows"], data["sensor"]["cols"] = 31623, 31623
    with pytest.raises(ParameterError, match="reduce rows/cols"):
        project_from_dict(data)


def test_document_level_errors(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    with pytest.raises(InputFileError, match="not valid JSON at line 1"):
        load_project(bad)
    with pytest.raises(ParameterError, match="format: must be"):
        project_from_dict({"schema_version": 1})
    newer = _paper() | {"schema_version": 99}
    with pytest.raises(ParameterError, match="newer workbench"):
        project_from_dict(newer)
    with pytest.raises(InputFileError, match="JSON object"):
        project_from_dict([1, 2])
    with pytest.raises(InputFileError, match="sample projects"):
        load_project(tmp_path / "missing.json")


def test_atomic_save_keeps_the_old_file_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "p.json"
    save_project(Project(name="first"), target)
    before = target.read_text()

    def boom(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        save_project(Project(name="second"), target)
    assert target.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]      # no temporary left behind
