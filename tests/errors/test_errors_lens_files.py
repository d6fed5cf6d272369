"""Lens files (.json/.dat/.zmx): every bad file is an InputFileError naming it, never echoing its
lines, and nothing read from a file sizes an allocation without a bound."""
import json
import time
from pathlib import Path

import pytest

from errors_fuzz import ZMX

from workbench.cli import main
from workbench.errors import InputFileError, ParameterError
from workbench.optics.lens.io import LENS_DIR, load_lens, save_lens
from workbench.project import PROJECTS_DIR, project_from_dict

DGAUSS = json.loads((LENS_DIR / "dgauss.50mm.json").read_text())
DAT = "# r t n d\n40 5 1.5168 20\n0 2 0 16\n-40 80 1 20\n"


def _dgauss(**surface0) -> str:
    data = json.loads(json.dumps(DGAUSS))
    data["surfaces"][0].update(surface0)
    return json.dumps(data)


@pytest.mark.parametrize("suffix,text,problem", [
    (".json", json.dumps(DGAUSS)[:200], "not valid JSON"),
    (".json", "[" * 5000 + "]" * 5000, "nested too deeply"),
    (".json", '{"surfaces": [], "surfaces": []}', "key 'surfaces' twice"),
    (".json", _dgauss(thickness=-3.0), "thickness"),
    (".json", _dgauss(radius=float("nan")), "finite"),
    (".json", _dgauss(semi_aperture="wide"), "semi_aperture"),
    (".json", _dgauss(glass="UNOBTAINIUM-7"), "not a catalogue glass"),
    (".json", _dgauss(aspheric_coefficients=[0.0] * 100000), "at most 16"),
    (".json", json.dumps({"surfaces": [DGAUSS["surfaces"][0]] * 1000}), "allowed 1–256"),
    (".dat", DAT[:-4], "expected 4 numbers"),
    (".dat", DAT.replace("0 2 0 16", "0 -2 0 16"), "thickness"),
    (".dat", DAT.replace("1.5168", "nan"), "finite"),
    (".dat", DAT.replace("1.5168", "0.5"), "not a catalogue glass"),
    (".dat", "40 5 1.5 20\n" * 1000, "more than 256 surfaces"),
    (".zmx", ZMX.replace("PARM 2 1e-5", "PARM 100000000 1e-5"), "PARM index 100000000 outside 0–16"),
    (".zmx", ZMX.replace("DISZ 5", "DISZ -5"), "thickness"),
    (".zmx", ZMX.replace("GLAS N-BK7 1 0 1.5168 64.17 0 0 0 0 0 0", "GLAS UNOBTAINIUM"), "not in the catalogue"),
    (".zmx", ZMX.replace("CURV 0.02", "CURV nan"), "finite"),
    (".zmx", ZMX[:80], "needs an object surface"),
    (".zmx", ZMX.replace("DIAM 10", "DIAM 0"), "DIAM"),
    (".zmx", "SURF 0\n" * 1000, "more than 256 surfaces"),
    (".json", "x" * (2 ** 20 + 1), "a lens file is at most 1,048,576 bytes"),
])
def test_bad_lens_file_names_the_file(tmp_path, suffix, text, problem):
    path = tmp_path / f"lens{suffix}"
    path.write_text(text)
    t0 = time.perf_counter()
    with pytest.raises(InputFileError) as info:
        load_lens(path)
    assert time.perf_counter() - t0 < 10
    msg = str(info.value)
    assert msg.startswith(str(path)) and problem in msg, msg
    assert "\n" not in msg


@pytest.mark.parametrize("suffix", [".json", ".dat", ".zmx"])
def test_binary_and_empty_lens_files(tmp_path, suffix):
    path = tmp_path / f"b{suffix}"
    path.write_bytes(bytes(range(256)) * 8)
    with pytest.raises(InputFileError, match="not UTF-8 text|binary"):
        load_lens(path)
    path.write_bytes(b"")
    with pytest.raises(InputFileError, match=str(path)):
        load_lens(path)


def test_lens_errors_never_echo_the_file(tmp_path):
    secret = "TOKEN-hunter2"
    for suffix, text in ((".dat", f"40 5 1.5 20\n{secret} 1 1 1\n"),
                         (".zmx", ZMX.replace("CURV 0.02", f"CURV {secret}")),
                         (".json", _dgauss(radius=secret))):
        path = tmp_path / f"l{suffix}"
        path.write_text(text)
        with pytest.raises(InputFileError) as info:
            load_lens(path)
        assert secret not in str(info.value)


def test_zero_radii_load_or_are_refused_cleanly(tmp_path, capsys):
    """A lens of flat faces only has no power: `lens info` says so in one line (no traceback)."""
    path = tmp_path / "flat.dat"
    path.write_text("0 2 0 16\n1e9 5 1.5 20\n")
    code = main(["lens", "info", str(path)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert code == 0 or (code == 2 and len(err.strip().splitlines()) == 1 and str(path) in err), err


def test_good_files_still_round_trip(tmp_path):
    for suffix, text in ((".dat", DAT), (".zmx", ZMX)):
        path = tmp_path / f"ok{suffix}"
        path.write_text(text)
        lens = load_lens(path)
        assert len(lens.surfaces) >= 2
    lens = load_lens("dgauss.50mm")
    again = load_lens(save_lens(lens, tmp_path / "d.json"))
    assert [s.radius_mm for s in again.surfaces] == pytest.approx([s.radius_mm for s in lens.surfaces])


def test_project_with_missing_or_broken_lens_is_refused_when_it_loads(tmp_path, monkeypatch):
    from workbench.optics.lens import io
    data = json.loads((PROJECTS_DIR / "paper_camera.json").read_text())
    for missing in ("no_such.lens", "é" * 300):          # the second is too long for a file name
        data["optics"]["lens_file"] = missing
        with pytest.raises(ParameterError) as info:
            project_from_dict(data)
        assert info.value.field == "optics.lens_file" and "no such lens" in str(info.value)
    (tmp_path / "broken.json").write_text(json.dumps(DGAUSS)[:100])
    monkeypatch.setattr(io, "LENS_DIR", tmp_path)
    data["optics"]["lens_file"] = "broken.json"
    with pytest.raises(ParameterError) as info:
        project_from_dict(data)
    assert info.value.field == "optics.lens_file" and "not valid JSON" in str(info.value)
    assert str(Path(tmp_path) / "broken.json") in str(info.value)


def _single(r1, thickness, r2) -> dict:
    return {"name": "single", "surfaces": [
        {"radius": r1, "thickness": thickness, "ior": 1.5, "semi_aperture": 4, "glass": "1.5/60"},
        {"radius": r2, "thickness": 10, "ior": 1.0, "semi_aperture": 4, "glass": "air"}]}


@pytest.mark.parametrize("lens, problem", [
    (_single(-20.0, 3.0, 20.0), r"focal length is negative \(EFL=-19\.\d+ mm\): a diverging lens"),
    (_single(1e9, 2.0, -1e9), r"almost no power \(EFL=1e\+09 mm"),
    (_single(10.0, 40.0, 0.0), r"rear focal point lies inside the lens \(BFL=-6\.667 mm")])
def test_a_lens_that_cannot_image_is_refused_when_a_project_loads(tmp_path, monkeypatch, lens, problem):
    """A lens file that reads but forms no real image behind it (it failed at the optics stage with
    'Surface.semi_aperture_mm=-2.69' or 'Lens.image_distance_mm=-57.4' and the project echoed)."""
    from workbench.optics.lens import io
    (tmp_path / "odd.json").write_text(json.dumps(lens))
    monkeypatch.setattr(io, "LENS_DIR", tmp_path)
    load_lens(tmp_path / "odd.json")                      # a valid prescription: the editor may open it
    data = json.loads((PROJECTS_DIR / "paper_camera.json").read_text())
    data["optics"].update(model="psf_grid", lens_file="odd.json")
    with pytest.raises(ParameterError, match=problem) as info:
        project_from_dict(data)
    assert info.value.field == "optics.lens_file" and "cannot image" in str(info.value)


def test_a_clear_aperture_beyond_the_sphere_is_refused(tmp_path):
    """A radius of 1 µm under a 12.6 mm clear radius: no sphere reaches that far (the tracer clamped
    the sag and the lens failed later, at focusing)."""
    f = tmp_path / "tiny.json"
    f.write_text(_dgauss(radius=0.001))
    with pytest.raises(InputFileError, match=r"surface 0's clear radius 12\.6 mm .*radius 0\.001 mm.*at most \|radius\|"):
        load_lens(f)
    from workbench.optics.lens import Surface
    assert Surface.from_radius(5.0, 1.0, "1.5", 5.0).reaches_its_aperture                # a hemisphere
    assert Surface.from_radius(5.0, 1.0, "1.5", 8.0, conic=-2.0).reaches_its_aperture    # a hyperboloid reaches any radius
    assert not Surface.from_radius(5.0, 1.0, "1.5", 5.1).reaches_its_aperture
