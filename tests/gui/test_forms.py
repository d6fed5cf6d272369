"""The schema-driven form: a widget per field of every project section, exact round trips,
refused values highlighted with the ParameterError text and never emitted."""
from __future__ import annotations

import pytest
from PySide6.QtCore import Qt

from workbench.gui.forms import JsonField, NestedField, NumberField, OptionalField, ParamsForm, label_and_unit
from workbench.project import Project
from workbench.sensor.params import SENSOR_PRESETS, SensorParams

SECTIONS = ["scene", "city", "pose", "optics", "sensor", "isp", "render", "experiment"]


def section_class(name):
    from workbench.gui.forms import _split_optional
    return _split_optional(Project.model_fields[name].annotation)[0]


def shown(widget):
    return widget.value() if not isinstance(widget, NestedField) else widget.form.params().model_dump()


@pytest.mark.parametrize("section", SECTIONS)
def test_form_has_a_widget_per_field_and_round_trips(qtbot, section):
    cls = section_class(section)
    form = ParamsForm(cls)
    qtbot.addWidget(form)
    assert set(form.fields) == set(cls.model_fields)
    params = cls()
    form.set_params(params)
    for name, widget in form.fields.items():
        value = getattr(params, name)
        expected = value.model_dump() if hasattr(value, "model_dump") else value
        got = shown(widget)
        assert cls.model_validate(params.model_dump() | {name: got}) == params, name
        assert got == expected or list(got) == list(expected), name


def test_round_trip_of_every_preset_and_no_emit_on_unchanged_commit(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    emitted = []
    form.edited.connect(emitted.append)
    for preset in SENSOR_PRESETS.values():
        form.set_params(preset)
        values = {n: w.value() for n, w in form.fields.items()}
        assert SensorParams.model_validate(values) == preset
        for name in form.fields:
            form._commit(name)
    assert emitted == []
    assert form.errors == {}


def test_labels_carry_units_and_tooltips_descriptions_and_ranges(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    assert label_and_unit("conversion_gain_uV_per_e") == ("conversion gain", "µV/e⁻")
    assert form.labels["pixel_pitch_um"].text() == "pixel pitch (µm)"
    tip = form.fields["fill_factor"].toolTip()
    assert "photosensitive fraction" in tip and "0 < x ≤ 1" in tip


def _type(qtbot, widget, text):
    edit = widget.inner.edit if isinstance(widget, OptionalField) else widget.edit
    edit.selectAll()
    qtbot.keyClicks(edit, text)
    qtbot.keyClick(edit, Qt.Key.Key_Return)


def test_valid_edit_emits_one_change(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    with qtbot.waitSignal(form.edited) as sig:
        _type(qtbot, form.fields["fill_factor"], "0.5")
    assert sig.args == [{"fill_factor": 0.5}]
    assert form.params().fill_factor == 0.5


@pytest.mark.parametrize("field, text, fragment", [
    ("fill_factor", "2", "fill_factor"),            # out of range
    ("rows", "abc", "rows"),                         # not a number
    ("rows", "2.5", "whole number"),                 # not an integer
    ("analog_offset_V", "5", "voltage_swing_V"),     # cross-field check of the model
])
def test_invalid_input_is_refused_highlighted_and_not_emitted(qtbot, field, text, fragment):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    emitted = []
    form.edited.connect(emitted.append)
    before = form.params()
    _type(qtbot, form.fields[field], text)
    assert emitted == []
    assert form.params() == before
    assert field in form.errors and fragment in form.errors[field]
    assert "background-color" in form.fields[field].styleSheet()
    assert form.errors[field] in form.fields[field].toolTip()
    _type(qtbot, form.fields[field], str(getattr(before, field)))     # a good value clears the mark
    assert field not in form.errors and form.fields[field].styleSheet() == ""


def test_optional_and_json_fields(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    exposure = form.fields["exposure_s"]
    assert isinstance(exposure, OptionalField) and isinstance(exposure.inner, JsonField)
    assert isinstance(form.fields["rows"], NumberField)
    with qtbot.waitSignal(form.edited) as sig:
        exposure.enabled.setChecked(True)
        _type(qtbot, exposure, "0.01")
    assert sig.args == [{"exposure_s": 0.01}]
    with qtbot.waitSignal(form.edited) as sig:
        exposure.enabled.setChecked(False)
    assert sig.args == [{"exposure_s": None}]


def test_nested_section_emits_the_whole_sub_model(qtbot):
    from workbench.optics.params import OpticsParams
    form = ParamsForm(OpticsParams)
    qtbot.addWidget(form)
    sub = form.fields["budget"].form
    with qtbot.waitSignal(form.edited) as sig:
        _type(qtbot, sub.fields["max_rel_rms_error"], "0.05")
    assert sig.args[0]["budget"]["max_rel_rms_error"] == 0.05
    assert form.params().budget.max_rel_rms_error == 0.05


def test_fraction_slider_commits_on_release_and_keeps_text_exact(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    field = form.fields["fill_factor"]
    assert field.slider is not None and form.fields["pixel_pitch_um"].slider is None
    form.set_params(SensorParams(fill_factor=0.123456))
    assert field.edit.text() == "0.123456"
    with qtbot.waitSignal(form.edited) as sig:
        field.slider.setValue(0.5)
        field.slider.sliderMoved.emit(0.5)
        field.slider.sliderReleased.emit()
    assert sig.args == [{"fill_factor": 0.5}]


def test_only_unitless_fractions_get_sliders(qtbot):
    form = ParamsForm(SensorParams)
    qtbot.addWidget(form)
    with_slider = {n for n, w in form.fields.items() if getattr(w, "slider", None) is not None}
    assert with_slider == {"fill_factor", "auto_exposure_level"}
