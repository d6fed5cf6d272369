"""ISP editor: edits emit ('isp', changes); the colour matrix and its condition number follow the sensor."""
from __future__ import annotations

from workbench.gui.editors.isp import ISPEditor
from workbench.project import Project
from workbench.sensor.params import SENSOR_PRESETS


def test_isp_edit_emits_and_matrix_shows_condition(qtbot):
    editor = ISPEditor()
    qtbot.addWidget(editor)
    emitted = []
    editor.edited.connect(lambda *a: emitted.append(a))
    editor.set_project(Project())
    assert emitted == []
    assert editor.matrix.rowCount() == 3 and "condition number" in editor.fit_text.text()
    assert abs(float(editor.matrix.item(1, 1).text()) - editor.fit.matrix[1, 1]) < 1e-4
    combo = editor.form.fields["demosaic"].combo
    with qtbot.waitSignal(editor.edited) as sig:
        combo.setCurrentText("malvar2004")
        combo.activated.emit(combo.currentIndex())
    assert sig.args == ["isp", {"demosaic": "malvar2004"}]
    ic = editor.form.fields["illuminant_correction"].combo
    with qtbot.waitSignal(editor.edited) as sig:
        ic.setCurrentText("white_world")
        ic.activated.emit(ic.currentIndex())
    assert sig.args == ["isp", {"illuminant_correction": "white_world"}]


def test_single_colour_sensor_has_no_matrix(qtbot):
    editor = ISPEditor()
    qtbot.addWidget(editor)
    editor.set_project(Project(sensor=SENSOR_PRESETS["auto_rccc"]))
    assert editor.matrix.rowCount() == 0 and "no colour matrix" in editor.fit_text.text()
