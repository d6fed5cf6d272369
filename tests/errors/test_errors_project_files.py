"""Project files: every way a file can be unusable is an InputFileError naming it; bad values are a
ParameterError naming the dotted field; saving refuses what would not load back and is atomic."""
import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from workbench.errors import InputFileError, OutputPathError, ParameterError
from workbench.files import atomic_write_text
from workbench.project import PROJECTS_DIR, SCHEMA_VERSION, load_project, project_from_dict, save_project

ROOT = Path(__file__).resolve().parents[2]
AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def _paper_text() -> str:
    return (PROJECTS_DIR / "paper_camera.json").read_text()


@pytest.mark.parametrize("content,problem", [
    (b'{"format": "camera-workbench-project", "name": "cut', "not valid JSON at line 1"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe", "not UTF-8 text"),
    (b"{" + b"\x00" * 20 + b"}", "binary file"),
    (b"[" * 5000 + b"]" * 5000, "nested too deeply"),
    (b"[" * 100000, "nested too deeply"),
    (b'{"format": "camera-workbench-project", "name": "a", "name": "b"}', "key 'name' twice"),
    (b"", "not valid JSON"),
])
def test_unreadable_project_file_names_the_file(tmp_path, content, problem):
    path = tmp_path / "p.json"
    path.write_bytes(content)
    with pytest.raises(InputFileError) as info:
        load_project(path)
    assert info.value.path == str(path) and problem in str(info.value)
    assert "\n" not in str(info.value)


def test_folder_and_missing_file_are_named(tmp_path):
    with pytest.raises(InputFileError, match="is a folder"):
        load_project(tmp_path)
    with pytest.raises(InputFileError, match="no such project file"):
        load_project(tmp_path / "nope.json")
    with pytest.raises(InputFileError, match="no such project file"):
        load_project("x" * 5000)
    with pytest.raises(InputFileError, match="not a regular file"):
        load_project("/dev/null")


def test_file_without_read_permission(tmp_path, monkeypatch):
    path = tmp_path / "secret.json"
    path.write_text(_paper_text())
    path.chmod(0)
    if AS_ROOT:      # root reads anything: simulate the refusal the kernel gives other users
        real_open = open

        def refuse(p, *a, **k):
            if Path(p) == path:
                raise PermissionError(13, "Permission denied", str(p))
            return real_open(p, *a, **k)
        monkeypatch.setattr("builtins.open", refuse)
    with pytest.raises(InputFileError, match="no permission to read"):
        load_project(path)


def test_error_never_echoes_file_contents(tmp_path):
    secret = "hunter2-private-token"
    path = tmp_path / "p.json"
    path.write_text('{"format": "camera-workbench-project", "x": ' + secret)
    with pytest.raises(InputFileError) as info:
        load_project(path)
    assert secret not in str(info.value)


@pytest.mark.parametrize("path,value,allowed", [
    (("sensor", "exposure_s"), float("nan"), "finite"),
    (("optics", "f_number"), float("nan"), "must be a finite number"),
    (("optics", "focus_distance_m"), float("inf"), "finite"),
    (("experiment", "ev_biases", 1), float("nan"), "must be a finite number"),
    (("sensor", "rows"), True, "valid integer"),
    (("sensor", "rows"), "120", "valid integer"),
    (("sensor", "exposure_s"), "0.01", "valid number"),
    (("experiment", "ev_biases", 1), 99.0, "less than or equal to 16"),
    (("experiment", "ev_biases"), [], "at least 1"),
    (("experiment", "auto_exposure_method"), "magic", "mean"),
    (("scene", "illuminant"), "blackbody:inf", "1000"),
    (("scene", "illuminant"), "blackbody:nan", "1000"),
    (("scene", "illuminant"), "blackbody:1", "1000"),
    (("optics", "lens_file"), "no_such_lens.json", "no such lens"),
    (("optics", "focus_distance_m"), 1e-100, "must exceed the effective focal length (2.376 mm)"),
    (("scene", "distance_m"), 1e-6, "must exceed the effective focal length"),
    (("render", "daylight", "time_of_day_h"), 1.0, "daylight needs the sun above the horizon"),
])
def test_bad_values_name_the_field(path, value, allowed):
    data = json.loads(_paper_text())
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ParameterError) as info:
        project_from_dict(data, "bad.json")
    field = ".".join(str(p) for p in path)
    assert info.value.field == field, str(info.value)
    assert allowed in str(info.value)


def test_a_lens_model_without_a_lens_is_refused_when_it_loads():
    data = json.loads(_paper_text())
    data["optics"]["model"] = "raytrace"
    with pytest.raises(ParameterError) as info:
        project_from_dict(data)
    assert info.value.field == "optics.lens_file" and "needs a lens file" in str(info.value)


def test_schema_1_migrates_and_drops_the_unused_illuminance():
    data = json.loads(_paper_text())
    data["schema_version"] = 1
    data["experiment"]["mean_illuminance_lux"] = 500.0
    project = project_from_dict(data)
    assert project.schema_version == SCHEMA_VERSION
    assert "mean_illuminance_lux" not in project.experiment.model_dump()
    assert project.scene.adjust_illuminance_lux == 1000.0       # what sets the illuminance
    with pytest.raises(ParameterError, match="experiment.mean_illuminance_lux"):
        project_from_dict(json.loads(_paper_text()) | {"experiment": {"mean_illuminance_lux": 1.0}})
    with pytest.raises(ParameterError, match="schema_version"):
        project_from_dict(json.loads(_paper_text()) | {"schema_version": True})


# ---------------------------------------------------------------- save
def test_save_refuses_non_finite_instead_of_writing_null(tmp_path):
    project = load_project("paper_camera")
    bad = project.model_copy(update={"optics": project.optics.model_copy(update={"focus_distance_m": float("inf")})})
    target = tmp_path / "p.json"
    with pytest.raises(ParameterError) as info:
        save_project(bad, target)
    assert info.value.field == "optics.focus_distance_m" and "finite" in str(info.value)
    bad = project.model_copy(update={"experiment": project.experiment.model_copy(
        update={"ev_biases": [0.0, float("nan")]})})
    with pytest.raises(ParameterError) as info:
        save_project(bad, target)
    assert info.value.field == "experiment.ev_biases.1"
    assert not target.exists() and list(tmp_path.iterdir()) == []


def test_save_writes_through_a_symlink_and_keeps_permissions(tmp_path):
    real = tmp_path / "real" / "p.json"
    real.parent.mkdir()
    save_project(load_project("paper_camera"), real)
    real.chmod(0o600)
    link = tmp_path / "link.json"
    link.symlink_to(real)
    project = load_project("paper_camera").updated(name="renamed")
    save_project(project, link)
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert load_project(real).name == "renamed"
    assert stat.S_IMODE(real.stat().st_mode) == 0o600
    new = tmp_path / "new.json"
    save_project(project, new)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(new.stat().st_mode) == 0o666 & ~umask


def test_save_to_bad_places_is_an_output_path_error(tmp_path):
    project = load_project("paper_camera")
    with pytest.raises(OutputPathError, match="is a folder"):
        save_project(project, tmp_path)
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputPathError, match="a folder in the path is a file"):
        save_project(project, tmp_path / "file" / "p.json")


def test_a_killed_save_leaves_a_temporary_that_the_next_save_removes(tmp_path):
    target = tmp_path / "p.json"
    script = textwrap.dedent(f"""
        import os, signal
        from workbench.files import atomic_write_text
        os.replace = lambda *a: os.kill(os.getpid(), signal.SIGKILL)   # die after writing, before rename
        atomic_write_text({str(target)!r}, "x" * 100000)
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", script], env=env, timeout=60)
    assert proc.returncode == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(".p.json.") and left[0].endswith(".tmp")
    (tmp_path / ".p.json.notours.tmp").write_text("someone else's")     # not our pattern: kept
    atomic_write_text(target, "hello")
    assert sorted(p.name for p in tmp_path.iterdir()) == [".p.json.notours.tmp", "p.json"]
    assert target.read_text() == "hello"


def test_a_live_writers_temporary_is_kept(tmp_path):
    live = tmp_path / f".p.json.{os.getppid()}.0123abcd.tmp"       # the parent process is alive
    live.write_text("in flight")
    atomic_write_text(tmp_path / "p.json", "x")
    assert live.exists()


def test_every_sample_round_trips_through_save(tmp_path):
    for path in sorted(PROJECTS_DIR.glob("*.json")):
        project = load_project(path)
        out = save_project(project, tmp_path / path.name)
        again = load_project(out)
        assert again.model_dump() == project.model_dump()
        assert out.read_text() == path.read_text(), f"{path.name} is not in its saved form (run make_samples)"


def test_schema_2_migrates_to_the_default_world():
    """A version-2 city file (before sky models, night, fog, glass) renders as before: uniform sky,
    day, clear air, diffuse glass."""
    data = json.loads(_paper_text())
    data["schema_version"] = 2
    project = project_from_dict(data)
    assert project.schema_version == SCHEMA_VERSION == 3
    assert project.render.daylight.sky_model == "uniform"
    world = project.render.world
    assert (world.lighting, world.fog, world.glass) == ("day", None, "diffuse")


def test_city_counts_that_do_not_fit_are_refused_at_run_naming_the_field():
    """A valid document whose city cannot hold its objects (found by the big fuzz run): a
    StageError of the 'city' stage naming the field, not a bare ValueError."""
    from workbench.errors import StageError
    from workbench.pipeline import Pipeline
    project = load_project("city_low_sun")
    project = project.updated(city=project.city.updated(n_mailboxes=4000),
                              sensor=project.sensor.updated(rows=12, cols=16))
    with pytest.raises(StageError, match=r"stage 'city': frame 0: too many pedestrians.*n_mailboxes=4000"):
        Pipeline(project).run()
