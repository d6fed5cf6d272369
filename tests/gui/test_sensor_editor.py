"""Sensor editor: edits and presets emit ('sensor', changes); set_project emits nothing; the CFA
tile, the QE chart and the EMVA 1288 plot draw real pixels."""
from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt

from workbench.gui.editors.sensor import SensorEditor
from workbench.project import Project
from workbench.sensor.params import SENSOR_PRESETS


def make_editor(shown):
    return shown(SensorEditor(), 700, 800)


def test_set_project_shows_values_and_emits_nothing(qtbot, shown):
    editor = make_editor(shown)
    emitted = []
    editor.edited.connect(lambda *a: emitted.append(a))
    project = Project(sensor=SENSOR_PRESETS["auto_rccc"])
    editor.set_project(project)
    assert emitted == []
    assert editor.form.fields["cols"].value() == 752
    assert editor.cfa.pattern == "RCCC"


def test_form_edit_and_preset_emit_sensor_changes(qtbot, shown):
    editor = make_editor(shown)
    editor.set_project(Project())
    with qtbot.waitSignal(editor.edited) as sig:
        combo = editor.form.fields["cfa_pattern"].combo
        combo.setCurrentText("RGGB")
        combo.activated.emit(combo.currentIndex())
    assert sig.args == ["sensor", {"cfa_pattern": "RGGB"}]
    assert editor.cfa.pattern == "RGGB"
    with qtbot.waitSignal(editor.edited) as sig:
        editor.apply_preset("auto_rggb")
    section, changes = sig.args
    assert section == "sensor"
    assert Project().sensor.updated(cfa_pattern="RGGB", **changes) == SENSOR_PRESETS["auto_rggb"]
    assert "cfa_pattern" not in changes          # already RGGB: only the differing fields


def test_cfa_tile_and_qe_chart_draw(qtbot, grab, shown):
    editor = make_editor(shown)
    editor.set_project(Project())
    tile = grab(editor.cfa)
    assert tile.reshape(-1, 3).std(axis=0).max() > 20
    editor.tabs.setCurrentIndex(1)
    qtbot.waitUntil(editor.qe_chart.is_current, timeout=20_000)
    chart = grab(editor.qe_chart)
    assert len(np.unique(chart.reshape(-1, 3), axis=0)) > 20


def test_emva_runs_in_background_and_plots(qtbot, grab, shown):
    editor = make_editor(shown)
    editor.set_project(Project())
    editor.tabs.setCurrentIndex(2)
    with qtbot.waitSignal(editor.emva_finished, timeout=60_000) as sig:
        qtbot.mouseClick(editor.emva_button, Qt.MouseButton.LeftButton)
        assert not editor.emva_button.isEnabled()
    result = sig.args[0]
    assert abs(result["conversion_gain_uV_per_e"] - 100.0) < 5.0
    text = editor.emva_status.text()
    assert "µV/e⁻" in text and f"(configured {Project().sensor.read_noise_e:.3g})" in text
    assert result["notes"] and "16-bit ADC" in text and "≥" not in text      # an 8-bit ADC hid it: measured finer
    assert result["read_noise_e"] == pytest.approx(Project().sensor.read_noise_e, rel=0.15)
    snr_axes = editor.emva_chart.figure().axes[1]
    assert min(min(line.get_xdata()) for line in snr_axes.lines) >= 1.0             # no point below 1 e⁻
    qtbot.waitUntil(lambda: editor.emva_button.isEnabled())
    qtbot.waitUntil(editor.emva_chart.is_current, timeout=20_000)
    assert len(np.unique(grab(editor.emva_chart).reshape(-1, 3), axis=0)) > 20


def test_a_hidden_qe_chart_is_built_when_it_is_seen(qtbot, grab, shown):
    """A CFA edit behind the 'Parameters' tab draws no chart; the QE tab then shows the new
    pattern's curves, drawn off the GUI thread."""
    editor = make_editor(shown)
    editor.set_project(Project())
    assert not editor.qe_chart.isVisible()
    editor.set_project(Project(sensor=SENSOR_PRESETS["auto_rccc"]))
    qtbot.wait(100)
    assert editor.qe_chart._worker is None and not editor.qe_chart.is_current()   # deferred, not drawn
    editor.tabs.setCurrentIndex(1)
    qtbot.waitUntil(editor.qe_chart.is_current, timeout=20_000)
    assert editor.qe_chart.figure().axes[0].get_title() == "RCCC: effective channel QE"
    assert len(np.unique(grab(editor.qe_chart).reshape(-1, 3), axis=0)) > 20


def test_the_summary_says_which_exposure_rule_the_project_and_its_experiments_use(shown):
    """Issue 32, item 10: the sample camera exposes its chart by its brightest pixel, its exposure
    experiments (and the detection data) by the paper's rule; the window says which."""
    from workbench.project import load_project
    editor = make_editor(shown)
    editor.set_project(load_project("paper_camera"))
    text = editor.summary.text()
    assert "Exposure: auto, brightest pixel at 90 % of the swing (at most 10 s)" in text, text
    assert "exposure experiments: mean signal at 40 % of the swing, × 2^EV" in text, text
    editor.set_project(load_project("city_detection_quick"))
    assert "Exposure: auto, mean signal at 40 % of the swing" in editor.summary.text()
    fixed = load_project("paper_camera")
    editor.set_project(fixed.updated(sensor=fixed.sensor.updated(exposure_s=0.002, ev_bias=-1.0)))
    assert "Exposure: fixed 2 ms, -1 EV" in editor.summary.text()
