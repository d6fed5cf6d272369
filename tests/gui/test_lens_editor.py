"""Lens editor: choosing, opening and editing a lens emit ('optics', changes); an edited lens is
saved as ISETCam JSON in the user's lens library and named in optics.lens_file; read-outs,
charts (worker thread) and the selector's choice are shown."""
from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtGui import QColor

from workbench.gui.editors.lens import LensEditor
from workbench.optics.lens import load_lens, save_lens
from workbench.optics.lens.paraxial import paraxial
from workbench.optics.params import OpticsParams
from workbench.project import Project


@pytest.fixture
def user_lenses(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_LENS_DIR", str(tmp_path / "lenses"))
    return tmp_path / "lenses"


def make_editor(qtbot, project):
    editor = LensEditor()
    qtbot.addWidget(editor)
    editor.resize(1100, 750)
    editor.show()
    qtbot.waitExposed(editor)
    emitted = []
    editor.edited.connect(lambda *a: emitted.append(a))
    editor.set_project(project)
    return editor, emitted


def with_lens(name="dgauss.50mm.json"):
    p = Project()
    return p.updated(optics=p.optics.updated(lens_file=name, model="psf_grid"))


def test_no_lens_shows_first_order_and_choosing_a_lens_emits(qtbot, user_lenses):
    editor, emitted = make_editor(qtbot, Project())
    assert emitted == [] and editor.table.rowCount() == 0
    assert "first-order" in editor.readouts.text() and "44.00°" in editor.readouts.text()
    index = editor.lens_choice.findData("dgauss.50mm.json")
    editor.lens_choice.setCurrentIndex(index)
    editor.lens_choice.activated.emit(index)
    assert emitted == [("optics", {"lens_file": "dgauss.50mm.json"})]


def test_lens_table_readouts_and_charts(qtbot, grab, user_lenses):
    project = with_lens()
    editor = LensEditor()
    qtbot.addWidget(editor)
    editor.resize(1100, 750)
    editor.show()
    qtbot.waitExposed(editor)
    emitted = []
    editor.edited.connect(lambda *a: emitted.append(a))
    with qtbot.waitSignal(editor.chart_ready, timeout=120_000) as sig:
        editor.set_project(project)
    assert sig.args == ["layout"]
    lens = load_lens("dgauss.50mm")
    assert editor.table.rowCount() == len(lens.surfaces)
    efl = paraxial(editor.used_lens()).efl_mm
    assert f"EFL {efl:.4g} mm" in editor.readouts.text() and "f/4" in editor.readouts.text()
    assert emitted == []
    with qtbot.waitSignal(editor.chart_ready, timeout=120_000) as sig:
        editor.charts.setCurrentWidget(editor.chart_views["mtf"])
    assert sig.args == ["mtf"]
    for tab in ("mtf", "layout"):
        editor.charts.setCurrentWidget(editor.chart_views[tab])
        qtbot.waitUntil(editor.chart_views[tab].is_current, timeout=120_000)
        assert len(np.unique(grab(editor.chart_views[tab]).reshape(-1, 3), axis=0)) > 20, tab


def test_edited_lens_is_saved_to_the_library_and_used(qtbot, user_lenses):
    editor, emitted = make_editor(qtbot, with_lens())
    old = editor.table.item(1, 1).text()
    editor.table.item(1, 3).setText("-1")                     # a negative semi-aperture is refused
    assert "surface 1" in editor.table_status.text() and not editor.save_button.isEnabled()
    assert editor.table.item(1, 3).background().color() == QColor("#ffd6d6")
    editor.table.item(1, 3).setText(editor._lens_doc["surfaces"][1]["semi_aperture"].__format__(".6g"))
    editor.table.item(1, 1).setText(str(float(old) + 0.5))
    assert editor.save_button.isEnabled() and emitted == []
    editor.save_name.setText("my-gauss")
    assert editor.save_edited_lens()
    assert emitted == [("optics", {"lens_file": "my-gauss.json"})]
    assert (user_lenses / "my-gauss.json").is_file()
    saved = load_lens(OpticsParams(lens_file="my-gauss.json").lens_file)
    assert saved.surfaces[1].thickness_mm == pytest.approx(float(old) + 0.5)
    editor.save_name.setText("dgauss.50mm")                   # shipped names are not overwritten
    editor._edited = True
    assert not editor.save_edited_lens()


def test_open_a_pbrt_lens_file(qtbot, user_lenses, tmp_path):
    editor, emitted = make_editor(qtbot, Project())
    save_lens(load_lens("wide.22mm"), tmp_path / "wide-copy.dat")
    assert editor.import_lens(tmp_path / "wide-copy.dat")
    assert emitted[-1][0] == "optics" and (user_lenses / emitted[-1][1]["lens_file"]).is_file()
    assert not editor.import_lens(tmp_path / "missing.zmx")


def test_optics_form_and_the_selector_runs_for_auto(qtbot, user_lenses):
    project = Project()
    editor, emitted = make_editor(qtbot, project)
    assert "Ask the selector" in editor.selector_text.text()
    combo = editor.form.fields["off_axis"].combo
    combo.setCurrentText("none")
    combo.activated.emit(combo.currentIndex())
    assert emitted == [("optics", {"off_axis": "none"})]
    with qtbot.waitSignal(editor.selection_ready, timeout=120_000) as sig:
        editor.set_project(project.updated(optics=project.optics.updated(model="auto")))
    level = sig.args[0]["level"]
    assert level in ("pinhole", "diffraction_limited", "thin_lens")
    assert f"auto → '{level}'" in editor.selector_text.text() and "budget" in editor.selector_text.text()


def test_insert_and_delete_surfaces(qtbot, user_lenses):
    editor, emitted = make_editor(qtbot, with_lens())
    before = editor.used_lens()
    n = editor.table.rowCount()
    editor.table.setCurrentCell(2, 0)
    assert editor.insert_surface()
    assert editor.table.rowCount() == n + 1 and editor.save_button.isEnabled()
    p0, p1 = paraxial(before), paraxial(editor.used_lens())
    assert p1.efl_mm == pytest.approx(p0.efl_mm, rel=1e-9)          # the new surface is neutral
    assert p1.bfl_mm == pytest.approx(p0.bfl_mm, rel=1e-9)
    assert editor.delete_surface() is True and editor.table.rowCount() == n   # the new one again
    stop = next(i for i in range(n) if editor.table.item(i, 4).text() == "stop")
    editor.table.setCurrentCell(stop, 0)
    assert not editor.delete_surface() and "stop" in editor.table_status.text()
    assert emitted == []


def test_a_lens_file_sets_the_focal_length_field_it_shows(qtbot, user_lenses):
    """With a lens file the simulation uses the prescription's focal length, so the field shows
    that one, read-only; scaling the lens (or no lens) hands the field back to the user."""
    editor, _ = make_editor(qtbot, with_lens())
    field = editor.form.fields["focal_length_mm"]
    efl = paraxial(editor.used_lens()).efl_mm
    assert float(field.edit.text()) == pytest.approx(efl, rel=1e-5) and not field.isEnabled()
    assert "dgauss" in field.toolTip() and abs(efl - 2.3761) > 10
    scaled = with_lens()
    editor.set_project(scaled.updated(optics=scaled.optics.updated(scale_lens_to_focal_length=True)))
    assert field.isEnabled() and float(field.edit.text()) == pytest.approx(2.3761)
    editor.set_project(Project())
    assert field.isEnabled() and float(field.edit.text()) == pytest.approx(2.3761)
