"""The headless command line: simulate, characterize, bench pipeline, errors."""
import json

import numpy as np
import pytest

from workbench.cli import main
from workbench.project import load_project, save_project


@pytest.fixture
def small_project(tmp_path):
    p = load_project("paper_camera")
    p = p.updated(sensor=p.sensor.updated(rows=60, cols=80, pixel_pitch_um=24.0))
    path = tmp_path / "small.json"
    save_project(p, path)
    return path


def test_simulate_writes_every_stage(tmp_path, small_project, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(small_project), "--out", str(out)]) == 0
    for name in ("irradiance.png", "raw.png", "linear.png", "srgb.png", "stages.npz", "report.json"):
        assert (out / name).is_file(), name
    report = json.loads((out / "report.json").read_text())
    assert report["exposure_s"] > 0
    assert set(report["channels"]) == {"R", "G", "B"}
    for ch in report["channels"].values():
        assert ch["mean_electrons"] > 0 and ch["snr_dB"] > 0
    assert set(report["stage_times_s"]) == {"scene", "optics", "signal", "sensor", "isp"}
    with np.load(out / "stages.npz") as z:
        units = json.loads(str(z["units"]))
        assert units["irradiance"] == "photons/s/m^2/nm"
        assert z["irradiance"].shape == (60, 80, z["wavelengths"].size)
        assert z["dn"].shape == (60, 80) and z["srgb"].shape == (60, 80, 3)
    assert not list(out.glob(".*tmp*"))


def test_bad_project_gives_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    data = json.loads(load_project("paper_camera").model_dump_json())
    data["sensor"]["voltage_swing_V"] = -1
    bad.write_text(json.dumps(data))
    assert main(["simulate", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "sensor.voltage_swing_V" in err and "greater than 0" in err


def test_characterize_writes_json_and_plot(tmp_path, small_project):
    out = tmp_path / "emva"
    assert main(["characterize", str(small_project), "--out", str(out)]) == 0
    result = json.loads((out / "emva.json").read_text())
    assert (out / "photon_transfer.png").stat().st_size > 1000
    assert result  # the values themselves are checked in tests/sensor


def test_bench_pipeline_json(capsys):
    assert main(["bench", "pipeline", "--quick", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    row = data["rows"][0]
    assert row["resolution"] == "640x480" and row["bands"] == 16
    for key in ("scene_ms", "optics_ms", "signal_ms", "sensor_ms", "isp_ms",
                "sensor+isp_from_cached_irradiance_ms", "peak_traced_MB"):
        assert row[key] > 0
    for stage in ("scene", "optics", "signal", "sensor", "isp"):
        assert row[f"{stage}_cpu_ms"] > 0
    # the live path is signal + sensor + ISP: it costs more CPU than its ISP step alone
    assert row["sensor+isp_from_cached_irradiance_cpu_ms"] > row["isp_cpu_ms"]
    assert data["sensor_isp_ms"] == row["sensor_ms"] + row["isp_ms"]            # the window's goals' figures
    assert data["sensor_malvar_ms"] == row["sensor_ms"] + row["isp_malvar2004_ms"]


def test_bench_city_json(capsys):
    assert main(["bench", "city", "--quick", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["blocks"] for r in rows] == ["1x1", "2x2"]
    assert rows[1]["objects"] > rows[0]["objects"] and all(r["generate_ms"] > 0 for r in rows)


@pytest.mark.parametrize("bug", [TypeError("unsupported operand"), ValueError("operands could not be broadcast"),
                                 KeyError("x")])
def test_an_exception_that_is_not_bad_input_is_reported_as_a_bug(monkeypatch, tmp_path, capsys, bug):
    """Only WorkbenchError and OSError are the user's: a numpy ValueError (or any other exception)
    is a bug, said so in one line naming the log, with its traceback in the log, exit code 3."""
    monkeypatch.setenv("WORKBENCH_LOG_DIR", str(tmp_path / "logs"))
    import logging
    for handler in list(logging.getLogger("workbench").handlers):    # a fresh log in tmp_path
        logging.getLogger("workbench").removeHandler(handler)

    def broken(_args):
        raise bug
    import workbench.cli as cli
    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    for action in parser._subparsers._group_actions[0].choices.values():
        if action.get_default("func") is not None and action.prog.endswith("simulate"):
            action.set_defaults(func=broken)
    assert main(["simulate", "paper_camera", "--out", str(tmp_path / "o")]) == 3
    err = capsys.readouterr().err.strip()
    assert err.startswith("workbench simulate: internal error (a bug, not your input):")
    assert type(bug).__name__ in err and str(tmp_path / "logs") in err and "\n" not in err
    log = (tmp_path / "logs" / "workbench.log").read_text()
    assert "Traceback" in log and "broken" in log
