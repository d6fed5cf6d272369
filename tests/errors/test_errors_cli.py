"""The command line: every error a user can act on is one line `workbench CMD: error: …` and a
non-zero exit, never a traceback; bad --out folders are refused before any work is done."""
import json
import os
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.project import load_project, save_project

AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.fixture
def tiny_project(tmp_path):
    p = load_project("paper_camera")
    p = p.updated(sensor=p.sensor.updated(rows=12, cols=16, pixel_pitch_um=80.0))
    return save_project(p, tmp_path / "tiny.json")


def _one_error_line(capsys, command: str) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"workbench {command}: error: "), lines[0]
    assert "Traceback" not in captured.err + captured.out
    return lines[0]


@pytest.mark.parametrize("command", ["simulate", "characterize"])
def test_out_that_is_not_a_writable_folder(tmp_path, tiny_project, capsys, command):
    existing = tmp_path / "existing.txt"
    existing.write_text("keep me")
    for out, problem in ((existing, "not a folder"), ("/dev/null", "not a folder"),
                         (existing / "below", "a folder in the path is a file")):
        assert main([command, str(tiny_project), "--out", str(out)]) == 2
        line = _one_error_line(capsys, command)
        assert str(out) in line and problem in line
    assert existing.read_text() == "keep me"


@pytest.mark.skipif(AS_ROOT, reason="root may write into a read-only folder")
@pytest.mark.parametrize("command", ["simulate", "characterize"])
def test_out_in_a_read_only_folder(tmp_path, tiny_project, capsys, command):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert main([command, str(tiny_project), "--out", str(ro)]) == 2
        assert "cannot write in the folder" in _one_error_line(capsys, command)
    finally:
        ro.chmod(0o700)


def test_read_only_folder_is_refused_even_as_root(tmp_path, monkeypatch):
    """The write probe is what refuses a read-only folder; simulate the kernel's answer under root."""
    from workbench import files
    from workbench.errors import OutputPathError
    real_open = os.open

    def refuse(path, flags, mode=0o777, **kw):
        if Path(path).parent == tmp_path and flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, flags, mode, **kw)
    monkeypatch.setattr(files.os, "open", refuse)
    with pytest.raises(OutputPathError, match="cannot write in the folder"):
        files.prepare_output_folder(tmp_path)


@pytest.mark.parametrize("argv,needle", [
    (["simulate", "{dir}", "--out", "{out}"], "is a folder"),
    (["simulate", "{dir}/missing.json", "--out", "{out}"], "no such project file"),
    (["simulate", "{bad_json}", "--out", "{out}"], "not valid JSON at line 1"),
    (["simulate", "{deep_json}", "--out", "{out}"], "nested too deeply"),
    (["simulate", "{nan_field}", "--out", "{out}"], "sensor.read_noise_V"),
    (["lens", "info", "dgauss.50mm", "--sensor-mm", "nan", "nan"], "--sensor-mm"),
    (["lens", "info", "dgauss.50mm", "--sensor-mm", "inf", "24"], "--sensor-mm"),
    (["lens", "info", "dgauss.50mm", "--focus-m", "nan"], "--focus-m"),
    (["lens", "info", "{truncated_lens}"], "truncated.json: not valid JSON"),
    (["lens", "info", "{deep_lens}"], "nested too deeply"),
    (["lens", "plot", "dgauss.50mm", "--out", "/dev/null"], "not a folder"),
])
def test_each_error_is_one_line(tmp_path, capsys, argv, needle):
    (tmp_path / "bad.json").write_text('{"format": "camera-')
    (tmp_path / "deep.json").write_text("[" * 5000 + "]" * 5000)
    data = json.loads(load_project("paper_camera").model_dump_json())
    data["sensor"]["read_noise_V"] = float("nan")
    (tmp_path / "nan.json").write_text(json.dumps(data))
    (tmp_path / "truncated.json").write_text((Path(__file__).parents[2] / "resources/lenses/dgauss.50mm.json")
                                             .read_text()[:300])
    (tmp_path / "deeplens.json").write_text('{"surfaces": ' + "[" * 6000)
    subs = {"{dir}": str(tmp_path), "{out}": str(tmp_path / "out"), "{bad_json}": str(tmp_path / "bad.json"),
            "{deep_json}": str(tmp_path / "deep.json"), "{nan_field}": str(tmp_path / "nan.json"),
            "{truncated_lens}": str(tmp_path / "truncated.json"), "{deep_lens}": str(tmp_path / "deeplens.json")}
    args = []
    for a in argv:
        for key, value in subs.items():
            a = a.replace(key, value)
        args.append(a)
    assert main(args) == 2
    command = " ".join(argv[:2]) if argv[0] == "lens" else argv[0]
    assert needle in _one_error_line(capsys, command)


def test_stale_outputs_of_an_earlier_run_are_removed(tmp_path, tiny_project, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "labels.png").write_bytes(b"from an earlier city run")
    (out / "notes.txt").write_text("the user's own file")
    assert main(["simulate", str(tiny_project), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert not (out / "labels.png").exists() and (out / "notes.txt").exists()
    assert "removed" in printed and "labels.png" in printed
    assert json.loads((out / "report.json").read_text())["removed_stale"] == ["labels.png"]


def test_an_empty_out_is_refused_and_two_writers_of_one_folder_are_refused(tmp_path, tiny_project, capsys,
                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", str(tiny_project), "--out", ""]) == 2
    assert "empty output folder" in capsys.readouterr().err and not list(tmp_path.glob("*.png"))
    out = tmp_path / "out"
    out.mkdir()
    import subprocess
    import sys
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from workbench.compute.folder_lock import hold_folder_lock\n"
                               "with hold_folder_lock(sys.argv[1], 'a test'):\n print('held', flush=True); time.sleep(60)", str(out)],
                              stdout=subprocess.PIPE, text=True)
    try:                                            # another process holds the folder
        assert holder.stdout.readline().strip() == "held"
        assert main(["simulate", str(tiny_project), "--out", str(out)]) == 2
        assert "is in use by a test (pid" in capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    assert not list(out.glob("*.png")) and not list(out.glob(".*.tmp"))
    assert main(["simulate", str(tiny_project), "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} >= {"srgb.png", "stages.npz", "report.json"}
    assert not list(out.glob(".*.tmp"))


def test_a_data_set_of_a_chart_project_is_refused_before_anything_is_written(tmp_path, capsys):
    assert main(["dataset", "paper_camera", "--frames", "2", "--out", str(tmp_path / "set")]) == 2
    err = capsys.readouterr().err
    assert "scene.kind" in err and "city" in err and "resume" not in err
    assert not (tmp_path / "set").exists()


def test_a_spectral_image_too_large_for_memory_is_refused_naming_its_fields(tmp_path, capsys):
    """2²⁵ pixels pass the pixel cap, but with 401 wavelengths the spectral image needs ~300 GiB."""
    data = json.loads(load_project("paper_camera").model_dump_json())
    data["sensor"].update(rows=4096, cols=8192)
    data["scene"]["wavelengths"] = {"start_nm": 300.0, "stop_nm": 1100.0, "step_nm": 2.0}
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "GiB" in err and "scene.wavelengths" in err and "sensor.rows/cols" in err and err.count("\n") == 1
    data["scene"]["wavelengths"]["step_nm"] = 50.0                    # 17 wavelengths: 13 GiB, allowed
    from workbench.project import project_from_dict, spectral_memory_gib
    assert spectral_memory_gib(project_from_dict(data)) < 16


@pytest.mark.parametrize("section, values, field", [
    ("sensor", {"conversion_gain_uV_per_e": 1e-300}, "conversion_gain_uV_per_e"),
    ("optics", {"distortion_k": [1e300]}, "distortion_k"),
])
def test_values_that_broke_a_later_stage_are_refused_naming_their_field(tmp_path, capsys, section, values, field):
    """A conversion gain of 1e-300 was reported as 'exposure_s … nan'; distortion_k 1e300 as a
    black optical image."""
    data = json.loads(load_project("paper_camera").model_dump_json())
    data[section].update(values)
    path = tmp_path / "p.json"
    path.write_text(json.dumps(data))
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert field in err and "nan" not in err and "black" not in err and err.count("\n") == 1


def test_a_long_allowed_render_says_how_long_before_it_starts(capsys):
    """render.spp 1,048,576 is allowed; the user is told it takes hours before waiting for it."""
    from workbench.commands.core import warn_long_render
    p = load_project("city_detection_quick")
    warn_long_render(p)
    assert capsys.readouterr().err == ""                      # 144 spp: seconds, nothing to say
    warn_long_render(p.updated(render=p.render.updated(spp=1_048_576)))
    err = capsys.readouterr().err
    assert "render.spp 1,048,576" in err and "min per frame" in err
