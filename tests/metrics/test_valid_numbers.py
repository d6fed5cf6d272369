"""Issue 34, valid numbers only: every JSON the workbench writes is strict JSON (no NaN/Infinity),
an SNR with the noise off is null with its reason and shown in words, compare calls no
difference against an unbounded figure a number, and read-outs stay physical (a dynamic range
without read noise is against the ADC's step; characterize refuses a swing it cannot measure)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.errors import ParameterError
from workbench.project import load_project, save_project

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


def strict_load(path: Path):
    """json.load that refuses NaN and ±Infinity (which Python's json writes by default)."""
    def refuse(name):
        raise AssertionError(f"{path}: {name} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.fixture(scope="module")
def quiet_and_noisy(tmp_path_factory):
    """paper_camera on 120×160, as it is (A) and with the sensor noise and the read noise off (B)."""
    folder = tmp_path_factory.mktemp("projects")
    p = load_project("paper_camera")
    p = p.updated(name="small_camera", sensor=p.sensor.updated(rows=120, cols=160))
    quiet = p.updated(name="quiet", sensor=p.sensor.updated(noise_flag=0, read_noise_V=0.0))
    return save_project(p, folder / "a.json"), save_project(quiet, folder / "b.json"), quiet


def test_json_text_refuses_nan_and_infinity_naming_the_place():
    from workbench.files import json_text
    assert json.loads(json_text({"a": np.float32(1.5), "b": [np.int64(2)], "c": None})) == {"a": 1.5, "b": [2],
                                                                                          "c": None}
    for bad in (math.inf, -math.inf, math.nan, np.float64("inf")):
        with pytest.raises(ValueError, match=r"summary\.snr_dB\[1\] is not a finite number"):
            json_text({"summary": {"snr_dB": [1.0, bad]}})


def test_compare_with_the_noise_off_writes_null_with_reasons_and_no_infinite_difference(quiet_and_noisy, tmp_path,
                                                                                         capsys):
    a, b, quiet = quiet_and_noisy
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "cmp")]) == 0
    printed = capsys.readouterr().out
    doc = strict_load(tmp_path / "cmp" / "compare.json")           # was: bare Infinity
    rows = {r["metric"]: r for r in doc["table"]}
    for key in ("snr_at_10cd_m2_10ms_dB", "snr_at_10pct_full_well_dB"):
        assert rows[key]["B"] is None and rows[key]["B − A"] is None
        assert rows[key]["null_reasons"] == {"B": "unbounded (noise off)"}
        assert rows[key][""] == "not comparable: B unbounded (noise off)"     # was: "B better" by 274.8 dB
        assert doc["B"]["null_reasons"][key] == "unbounded (noise off)"
    assert rows["noise_equivalent_exposure_lux_s"]["B"] is None               # was 7.5e-8 lux·s: no noise, none
    md = (tmp_path / "cmp" / "compare.md").read_text()
    assert "unbounded (noise off)" in md and "inf" not in md.replace("info", "")
    assert "B better" not in "".join(line for line in md.splitlines() if "snr" in line)
    assert "unbounded (noise off)" in printed and " inf" not in printed
    # no read noise: the dynamic range is against the 8-bit ADC's quantisation noise, not 1e-9 e⁻ (260 dB)
    s = quiet.sensor
    quantisation_e = s.lsb_V / s.conversion_gain_V_per_e / math.sqrt(12)
    from workbench.sensor.snr import sensor_dynamic_range
    saturation_e = sensor_dynamic_range(s)["saturation_e"]                  # the full well, less half a code
    assert doc["B"]["summary"]["dynamic_range_dB"] == pytest.approx(20 * math.log10(saturation_e / quantisation_e))
    assert doc["B"]["summary"]["dynamic_range_dB"] < 70
    flat = [row for row in doc["B"]["noise"] if row["snr"] is None]       # a measurement that does not vary
    assert flat and all(row["snr_reason"] == ("unbounded (noise off)" if row["mean_e"] > 0 else
                                              "undefined (no signal, no noise)") for row in flat)


def test_metrics_terminal_summary_says_unbounded_in_words():
    from workbench.commands.metrics import _summary_lines
    text = _summary_lines({"summary": {"snr_at_10cd_m2_10ms_dB": None, "mtf50_cy_px": 0.25},
                           "null_reasons": {"snr_at_10cd_m2_10ms_dB": "unbounded (noise off)"}})
    import re
    assert re.search(r"snr_at_10cd_m2_10ms_dB +unbounded \(noise off\)", text) and "0.25" in text


def test_compare_verdict_never_calls_an_unbounded_difference():
    from workbench.metrics.study import compare_verdict
    assert compare_verdict("snr_at_10pct_full_well_dB", 28.8, None, why_b="unbounded (noise off)") == \
        "not comparable: B unbounded (noise off)"
    assert compare_verdict("snr_at_10pct_full_well_dB", None, None, why_a="unbounded (noise off)",
                           why_b="unbounded (noise off)") == "not comparable: A unbounded (noise off), B unbounded (noise off)"
    assert compare_verdict("mtf50_cy_px", 0.25, None) == ""


def test_measured_snr_of_a_region_that_does_not_vary_is_null_not_1e15():
    from workbench.metrics.bounds import measured_snr
    assert measured_snr(1000.0, 6e-13) is None and measured_snr(1000.0, 0.0) is None    # was SNR 1.6e15 (303.9 dB)
    assert measured_snr(1000.0, 10.0) == pytest.approx(100.0)


def test_characterize_refuses_a_swing_it_cannot_measure(quiet_and_noisy, tmp_path, capsys):
    """1 µV swing: 0.01 e⁻ of well; it reported QE −0.91 and dynamic range −39.5 dB with exit 0 (now
    the sensor refuses a well under one electron); 0.5 mV, 4.9 e⁻, is a sensor, but not one
    characterize can measure."""
    from workbench.sensor.emva import characterize
    p = load_project(quiet_and_noisy[0])
    with pytest.raises(ValueError, match="at least 1 electron"):
        p.sensor.updated(voltage_swing_V=1e-6)
    tiny = p.updated(sensor=p.sensor.updated(voltage_swing_V=5e-4))
    with pytest.raises(ParameterError, match=r"sensor\.voltage_swing_V.*4\.9 e⁻.*at least 100 e⁻"):
        characterize(tiny.sensor, size_px=32, n_levels=12, n_dark=3)
    with pytest.raises(ParameterError, match=r"sensor\.bit_depth: .*at least 6 bits"):       # was a LinAlgError, exit 3
        characterize(p.sensor.updated(bit_depth=1), size_px=32, n_levels=12, n_dark=3)
    path = save_project(tiny, tmp_path / "uv.json")
    assert main(["characterize", str(path), "--out", str(tmp_path / "ch")]) == 2
    err = capsys.readouterr().err
    assert "sensor.voltage_swing_V" in err and "raise voltage_swing_V" in err
    assert not (tmp_path / "ch" / "emva.json").exists()


def test_characterize_of_a_measurable_sensor_stays_physical(quiet_and_noisy):
    from workbench.sensor.emva import characterize
    r = characterize(load_project(quiet_and_noisy[0]).sensor, size_px=32, n_levels=12, n_dark=3)
    assert 0 < r["quantum_efficiency"] <= 1 and r["dynamic_range_dB"] > 0


@pytest.mark.parametrize("path", sorted(p for p in RESULTS.rglob("*.json")), ids=lambda p: p.name)
def test_committed_results_are_strict_json_that_json_text_rewrites(path):
    """The committed result folders (read-only) hold no NaN/Infinity, so the strict writer can merge
    the next run into them."""
    from workbench.files import json_text
    doc = strict_load(path)
    assert json.loads(json_text(doc)) == doc


def test_simulate_with_the_noise_off_reports_no_snr_and_says_why(tmp_path):
    p = load_project("paper_camera")
    p = p.updated(sensor=p.sensor.updated(rows=12, cols=16, pixel_pitch_um=80.0, noise_flag=0, read_noise_V=0.0))
    path = save_project(p, tmp_path / "tiny.json")
    assert main(["simulate", str(path), "--out", str(tmp_path / "sim")]) == 0
    report = strict_load(tmp_path / "sim" / "report.json")
    for ch in report["channels"].values():
        assert ch["snr_dB"] is None and ch["snr_reason"] == "unbounded (noise off)"
    sensor_range = report["sensor_dynamic_range"]
    assert sensor_range["dynamic_range_limit"] == "quantisation (no read noise)"
    assert 0 < sensor_range["dynamic_range_dB"] < 70


def test_a_refused_vary_value_names_its_section_and_field():
    """'read_noise_V: must be a valid number' named no section."""
    from workbench.metrics.study import with_fields
    p = load_project("paper_camera")
    with pytest.raises(ParameterError, match=r"^sensor\.read_noise_V: must be a valid number"):
        with_fields(p, {"sensor.read_noise_V": "abc"})
