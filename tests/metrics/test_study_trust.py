"""Studies trust only what the grid makes (issue 34): a study.json with an extra or doubled design
is refused naming the file and design; --vary with a repeated value or a field given twice is
refused naming it; a grid beyond MAX_DESIGNS (and a data set beyond its frame limit) is refused
with an estimate of its time unless confirmed; every command that writes a folder holds its lock,
so a second one started on the same --out is refused."""
from __future__ import annotations

import json
import math

import pytest

from workbench.cli import main
from workbench.compute.folder_lock import hold_file_lock, hold_folder_lock
from workbench.errors import ParameterError
from workbench.metrics.study import parse_vary
from workbench.project import load_project, save_project


@pytest.fixture(scope="module")
def small_camera(tmp_path_factory):
    """paper_camera on a 120×160 sensor (the smallest the charts fit): a design measures in seconds."""
    p = load_project("paper_camera")
    p = p.updated(name="small_camera", sensor=p.sensor.updated(rows=120, cols=160))
    return save_project(p, tmp_path_factory.mktemp("projects") / "small_camera.json")


@pytest.fixture(scope="module")
def measured(small_camera, tmp_path_factory):
    """A finished study folder of two designs (its study.json as written)."""
    out = tmp_path_factory.mktemp("study") / "s"
    assert main(["study", str(small_camera), "--vary", "optics.f_number=4,8", "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("items, fragment", [
    (["optics.f_number=4,4"], "each value once"),
    (["optics.f_number=2,2.0"], "each value once"),
    (["optics.f_number=2", "optics.f_number=4"], "each field once"),
    (["optics.f_number=2", " optics.f_number =4"], "each field once"),
])
def test_vary_refuses_a_repeated_value_or_field_naming_it(items, fragment):
    with pytest.raises(ParameterError, match=fragment) as info:
        parse_vary(items)
    assert "f_number" in str(info.value)


def test_a_huge_grid_is_refused_at_once_with_an_estimate_unless_confirmed(small_camera, tmp_path, capsys):
    values = ",".join(str(1 + k / 1000) for k in range(1000))
    args = ["study", str(small_camera), "--vary", f"optics.f_number={values}",
            "--vary", f"sensor.read_noise_V={','.join(str(k * 1e-5) for k in range(1, 1001))}", "--out",
            str(tmp_path / "s")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "1,000,000 designs" in err and "--confirm-large" in err and "h of CPU time" in err
    assert not (tmp_path / "s").exists()


def test_a_data_set_beyond_the_frame_limit_needs_confirmation(tmp_path, capsys):
    assert main(["dataset", "city_detection_quick", "--frames", "100000", "--out", str(tmp_path / "set")]) == 2
    err = capsys.readouterr().err
    assert "--frames" in err and "--confirm-large" in err and "h of CPU" in err
    assert not (tmp_path / "set").exists()


def _rerun(small_camera, out, capsys, edit) -> tuple[int, str]:
    path = out / "study.json"
    saved = path.read_text()
    doc = json.loads(saved)
    edit(doc)
    path.write_text(json.dumps(doc))
    try:
        capsys.readouterr()
        code = main(["study", str(small_camera), "--vary", "optics.f_number=4,8", "--out", str(out)])
        return code, capsys.readouterr().err
    finally:
        path.write_text(saved)


def _second_value(doc):
    doc["designs"][1]["values"] = {"optics.f_number": 4}


@pytest.mark.parametrize("edit, fragment", [
    (lambda d: d["designs"].append(d["designs"][0]), "listed twice"),
    (lambda d: d["designs"].append({**d["designs"][0], "design": "f_number=16", "values": {"optics.f_number": 16}}),
     "not a design of this grid"),
    (_second_value, "values are not the grid's"),
    (lambda d: d["designs"][0]["summary"].update(mtf50_cy_px=math.nan), "finite numbers"),
    (lambda d: d["designs"][0]["summary"].update(mtf50_cy_px="abc"), "finite numbers"),
    (lambda d: d["designs"][0]["summary"].update(mtf50_cy_px=0.9), "checksum"),
    (lambda d: d["designs"][0].update(seconds=-1), "seconds"),
    (lambda d: d.update(designs={"a": 1}), "'designs' must be a list"),
    (lambda d: d["designs"].append(7), "not a design's measurements"),
])
def test_a_study_file_with_a_design_the_grid_did_not_make_is_refused(small_camera, measured, capsys, edit, fragment):
    code, err = _rerun(small_camera, measured, capsys, edit)
    assert code == 2 and fragment in err and "study.json" in err and err.count("\n") == 1
    assert "[3/2]" not in err


def test_designs_measured_before_checksums_still_count(small_camera, measured, capsys):
    def unseal(doc):
        for d in doc["designs"]:
            d.pop("checksum")
    code, err = _rerun(small_camera, measured, capsys, unseal)
    assert code == 0 and "2 designs, 2 already measured" in err


COMMANDS = {
    "study": lambda cam, out: ["study", str(cam), "--vary", "optics.f_number=4", "--out", str(out)],
    "metrics": lambda cam, out: ["metrics", str(cam), "--out", str(out)],
    "compare": lambda cam, out: ["compare", str(cam), str(cam), "--out", str(out)],
    "characterize": lambda cam, out: ["characterize", str(cam), "--out", str(out)],
    "lens plot": lambda cam, out: ["lens", "plot", "dgauss.50mm", "--out", str(out)],
    "render": lambda cam, out: ["render", "city_detection_quick", "--out", str(out)],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_second_writer_of_an_output_folder_is_refused(small_camera, tmp_path, capsys, command):
    out = tmp_path / "out"
    out.mkdir()
    with hold_folder_lock(out, f"workbench {command}"):          # the first run, still going
        assert main(COMMANDS[command](small_camera, out)) == 2
    err = capsys.readouterr().err
    assert f"is in use by workbench {command} (pid" in err and err.count("\n") == 1
    assert [p.name for p in out.iterdir()] == [".workbench.lock"]


def test_a_second_writer_of_a_claims_report_or_contact_sheet_is_refused(tmp_path, capsys):
    for args, target in ((["experiment", "claims", "--isp", str(tmp_path), "--exposure", str(tmp_path)], "c.md"),
                         (["contact-sheet", "city_detection_quick"], "sheet.png")):
        with hold_file_lock(tmp_path / target, "the first run"):
            assert main(args + ["--out", str(tmp_path / target)]) == 2
        assert "is in use by the first run" in capsys.readouterr().err
        assert not (tmp_path / target).exists()
