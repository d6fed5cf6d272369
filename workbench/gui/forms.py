"""One form generator for every parameter section, driven by the pydantic schema of a Params model.

`ParamsForm(SensorParams)` builds one row per field: a widget chosen from the field's type
(number → line edit (plus a slider for fractions), bool → check box, Literal → combo box, `X | None` → check box + value,
nested Params → collapsible sub-form, tuples/lists/unions → a JSON line edit), a label carrying
the unit read from the field-name suffix (`pixel_pitch_um` → "pixel pitch (µm)"), and a tooltip
holding the field's `description` and its allowed range (from ge/le/gt/lt). Every change is
validated against the whole model at once; a refused value keeps the field highlighted with the
ParameterError text and emits nothing. An accepted one emits `edited({field: value})`.

Undo in a field: Ctrl+Z (and redo) belong to the project, not to the text box. A field whose
text was edited but not yet committed gets its committed value back; otherwise the key goes on
to the window's Edit ▸ Undo, which undoes the last edit of the project (and the form then shows
that project's value).
"""
from __future__ import annotations

import json
import types
import typing
from typing import Any, Literal

from pydantic import BaseModel, ValidationError
from PySide6.QtCore import QEvent, Qt, Signal
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import (QCheckBox, QComboBox, QFormLayout, QHBoxLayout, QLabel, QLineEdit,
                               QVBoxLayout, QWidget)
from superqt import QCollapsible, QDoubleSlider

from workbench.errors import InvalidValueError, ParameterError, WorkbenchError
from workbench.params import Params

# Unit suffixes of field names (longest first) → the unit shown in the label.
UNIT_SUFFIXES = (
    ("_uV_per_e", "µV/e⁻"), ("_V_per_s", "V/s"), ("_e_per_s", "e⁻/s"), ("_cd_m2", "cd/m²"),
    ("_pct", "%"), ("_deg", "°"), ("_lux", "lx"), ("_nm", "nm"), ("_um", "µm"), ("_mm", "mm"),
    ("_m", "m"), ("_s", "s"), ("_V", "V"), ("_h", "h"),
)
INVALID_STYLE = "background-color: #ffd6d6; border: 1px solid #c0392b;"


def label_and_unit(name: str) -> tuple[str, str]:
    """('pixel pitch', 'µm') for 'pixel_pitch_um'; the unit is '' when the name carries none."""
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)].replace("_", " "), unit
    return name.replace("_", " "), ""


def range_text(field) -> str:
    """The allowed range from the field's ge/gt/le/lt constraints, e.g. '0 < x ≤ 1' ('' if none)."""
    lo = hi = ""
    for m in field.metadata:
        for attr, sym in (("ge", "≤"), ("gt", "<")):
            if getattr(m, attr, None) is not None:
                lo = f"{getattr(m, attr):g} {sym} "
        for attr, sym in (("le", "≤"), ("lt", "<")):
            if getattr(m, attr, None) is not None:
                hi = f" {sym} {getattr(m, attr):g}"
    return f"{lo}x{hi}" if lo or hi else ""


def refusal(exc: Exception, field: str, given: object) -> ParameterError:
    """A refused edit as a ParameterError naming the field (model-level checks name it too)."""
    if isinstance(exc, ParameterError):
        return exc
    if isinstance(exc, ValidationError):
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or field
        msg = err["msg"].removeprefix("Value error, ")
        return ParameterError(loc if loc.startswith(field) else field, given, msg)
    return ParameterError(field, given, str(exc))


def _split_optional(annotation) -> tuple[Any, bool]:
    """(inner type, optional?) of `X | None`; a union of several non-None types stays whole."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in args:
        rest = tuple(a for a in args if a is not type(None))
        return (rest[0] if len(rest) == 1 else typing.Union[rest]), True
    return annotation, False


# ------------------------------------------------------------------------------- field widgets
class _FieldWidget(QWidget):
    """A widget holding one field's value; `committed` fires when the user finishes an edit."""

    committed = Signal()

    def value(self):
        raise NotImplementedError

    def set_value(self, value) -> None:
        raise NotImplementedError


def finite_bounds(field) -> tuple[float, float] | None:
    """(low, high) when the field has both a lower (ge/gt) and an upper (le/lt) bound."""
    lo = hi = None
    for m in field.metadata:
        lo = next((getattr(m, a) for a in ("ge", "gt") if getattr(m, a, None) is not None), lo)
        hi = next((getattr(m, a) for a in ("le", "lt") if getattr(m, a, None) is not None), hi)
    return None if lo is None or hi is None else (float(lo), float(hi))


class NumberField(_FieldWidget):
    """int or float in a line edit (any magnitude, shown with 6 significant digits). A fraction
    (a unitless float bounded within a span of 1, e.g. 0 < x ≤ 1) also gets a slider; the text
    stays exact and dragging commits when the slider is released."""

    def __init__(self, kind: type, bounds: tuple[float, float] | None = None, parent=None):
        super().__init__(parent)
        self.kind = kind
        self.edit = QLineEdit(self)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.edit, 1)
        self.edit.editingFinished.connect(self.committed)
        self.slider = None
        if kind is float and bounds is not None and bounds[1] - bounds[0] <= 1.0:
            self.slider = QDoubleSlider(Qt.Orientation.Horizontal, self)
            self.slider.setRange(*bounds)
            self.slider.sliderMoved.connect(lambda v: self.edit.setText(f"{v:.4g}"))
            self.slider.sliderReleased.connect(self.committed)
            lay.addWidget(self.slider, 1)

    def value(self):
        text = self.edit.text().strip()
        if self.kind is int:
            number = float(text)
            if number != int(number):
                raise InvalidValueError(f"'{text}' is not a whole number")
            return int(number)
        return float(text)

    def set_value(self, value) -> None:
        self.edit.setText(str(value) if self.kind is int else f"{value:.6g}")
        if self.slider is not None:
            self.slider.blockSignals(True)
            self.slider.setValue(float(value))
            self.slider.blockSignals(False)


class TextField(_FieldWidget):
    """A string; with `choices`, an editable combo box listing them."""

    def __init__(self, choices: list[str] | None = None, parent=None):
        super().__init__(parent)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        if choices:
            self.combo = QComboBox(self)
            self.combo.setEditable(True)
            self.combo.addItems(choices)
            self.combo.activated.connect(lambda _i: self.committed.emit())
            self.combo.lineEdit().editingFinished.connect(self.committed)
            self.edit = self.combo.lineEdit()
            lay.addWidget(self.combo)
        else:
            self.combo = None
            self.edit = QLineEdit(self)
            self.edit.editingFinished.connect(self.committed)
            lay.addWidget(self.edit)

    def value(self):
        return self.edit.text().strip()

    def set_value(self, value) -> None:
        self.edit.setText(str(value))


class JsonField(_FieldWidget):
    """Tuples, lists and unions as JSON text; a bare '1, 2' is read as the list [1, 2]."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.edit = QLineEdit(self)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.edit)
        self.edit.editingFinished.connect(self.committed)

    def value(self):
        text = self.edit.text().strip()
        try:
            return json.loads(text)
        except json.JSONDecodeError:
            try:
                return json.loads(f"[{text}]")
            except json.JSONDecodeError:
                raise InvalidValueError(f"'{text}' is not a number, a list like 1, 2, 3 or JSON") from None

    def set_value(self, value) -> None:
        self.edit.setText(json.dumps(value))


class BoolField(_FieldWidget):
    def __init__(self, parent=None):
        super().__init__(parent)
        self.check = QCheckBox(self)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.check)
        self.check.toggled.connect(lambda _b: self.committed.emit())

    def value(self):
        return self.check.isChecked()

    def set_value(self, value) -> None:
        self.check.setChecked(bool(value))


class ChoiceField(_FieldWidget):
    """A Literal (or enum) field: a combo box of its allowed values."""

    def __init__(self, values: list, parent=None):
        super().__init__(parent)
        self.values = list(values)
        self.combo = QComboBox(self)
        for v in self.values:
            self.combo.addItem(str(getattr(v, "value", v)))
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.combo)
        self.combo.activated.connect(lambda _i: self.committed.emit())

    def value(self):
        return self.values[self.combo.currentIndex()]

    def set_value(self, value) -> None:
        self.combo.setCurrentIndex(self.values.index(value))


class OptionalField(_FieldWidget):
    """`X | None`: a check box (set / None) in front of the value widget."""

    def __init__(self, inner: _FieldWidget, parent=None):
        super().__init__(parent)
        self.inner = inner
        self.enabled = QCheckBox(self)
        self.enabled.setToolTip("unchecked = None")
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.enabled)
        lay.addWidget(inner, 1)
        inner.committed.connect(self.committed)
        self.enabled.toggled.connect(self._toggled)
        self._last = None

    def _toggled(self, on: bool) -> None:
        self.inner.setEnabled(on)
        if on and self._last is not None and isinstance(self.inner, (NumberField, TextField, JsonField)) \
                and not self.inner.edit.text():
            self.inner.set_value(self._last)
        self.committed.emit()

    def value(self):
        return self.inner.value() if self.enabled.isChecked() else None

    def set_value(self, value) -> None:
        self.enabled.blockSignals(True)
        self.enabled.setChecked(value is not None)
        self.enabled.blockSignals(False)
        self.inner.setEnabled(value is not None)
        if value is not None:
            self._last = value
            self.inner.set_value(value)


class NestedField(_FieldWidget):
    """A nested Params section as a collapsible sub-form; its value is the sub-model's dict."""

    def __init__(self, model_cls: type[Params], title: str, parent=None):
        super().__init__(parent)
        self.form = ParamsForm(model_cls, self)
        box = QCollapsible(title, self)
        box.addWidget(self.form)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(box)
        self.form.edited.connect(lambda _c: self.committed.emit())

    def value(self):
        return self.form.params().model_dump()

    def set_value(self, value) -> None:
        self.form.set_params(value)


def widget_for(annotation, name: str, choices: dict[str, list[str]] | None = None,
               bounds: tuple[float, float] | None = None) -> _FieldWidget:
    """The field widget for a type annotation (see the module docstring)."""
    inner, optional = _split_optional(annotation)
    if optional:
        return OptionalField(widget_for(inner, name, choices, bounds))
    origin = typing.get_origin(inner)
    if origin is Literal:
        return ChoiceField(list(typing.get_args(inner)))
    if isinstance(inner, type):
        if issubclass(inner, Params):
            return NestedField(inner, name.replace("_", " "))
        if issubclass(inner, bool):
            return BoolField()
        if issubclass(inner, (int, float)):
            return NumberField(int if issubclass(inner, int) else float, bounds)
        if issubclass(inner, str):
            return TextField((choices or {}).get(name))
        if hasattr(inner, "__members__"):          # enum
            return ChoiceField(list(inner))
    return JsonField()


# ------------------------------------------------------------------------------------ the form
class ParamsForm(QWidget):
    """A form over one Params model; `edited` = {field: new value}, already validated."""

    edited = Signal(dict)

    def __init__(self, model_cls: type[Params], parent=None, *, exclude: tuple[str, ...] = (),
                 choices: dict[str, list[str]] | None = None):
        super().__init__(parent)
        self.model_cls = model_cls
        self._params: BaseModel = model_cls()
        self.fields: dict[str, _FieldWidget] = {}
        self.labels: dict[str, QLabel] = {}
        self.errors: dict[str, str] = {}
        self._base_tips: dict[str, str] = {}
        self._overrides: dict[str, tuple[str, str]] = {}
        layout = QFormLayout(self)
        layout.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.ExpandingFieldsGrow)
        for name, info in model_cls.model_fields.items():
            if name in exclude:
                continue
            text, unit = label_and_unit(name)
            widget = widget_for(info.annotation, name, choices, None if unit else finite_bounds(info))
            label = QLabel(f"{text} ({unit})" if unit else text, self)
            tip = "\n".join(t for t in (info.description or "", ("allowed: " + range_text(info))
                                        if range_text(info) else "") if t)
            widget.setToolTip(tip)
            label.setToolTip(tip)
            widget.setObjectName(name)
            widget.committed.connect(lambda n=name: self._commit(n))
            self._base_tips[name] = tip
            self.fields[name] = widget
            self.labels[name] = label
            layout.addRow(label, widget)
            for edit in widget.findChildren(QLineEdit):
                if self._owner(edit) is self:               # a sub-form's text boxes are its own
                    edit.installEventFilter(self)
                    edit.setProperty("field", name)
        self.set_params(self._params)

    @staticmethod
    def _owner(widget):
        """The nearest ParamsForm holding `widget`."""
        parent = widget.parent()
        while parent is not None and not isinstance(parent, ParamsForm):
            parent = parent.parent()
        return parent

    def eventFilter(self, obj, event) -> bool:
        """Undo/redo keys in a field's text box: revert uncommitted text, else leave the key to the
        window's project undo (module docstring)."""
        if event.type() == QEvent.Type.ShortcutOverride and (
                event.matches(QKeySequence.StandardKey.Undo) or event.matches(QKeySequence.StandardKey.Redo)):
            name = obj.property("field")
            if obj.isModified() and name in self.fields:
                self._show(name)
                event.accept()
            else:
                event.ignore()               # not taken by the text box: the window's shortcut fires
            return True
        return super().eventFilter(obj, event)

    def _show(self, name: str) -> None:
        """Show the committed value of one field again (its text no longer counts as modified), or
        its override (set_override)."""
        widget = self.fields[name]
        value = getattr(self._params, name)
        widget.blockSignals(True)
        widget.set_value(value.model_dump() if isinstance(widget, NestedField) else value)
        widget.blockSignals(False)
        for edit in widget.findChildren(QLineEdit):
            edit.setModified(False)
        self._mark(name, None)
        if name in self._overrides:
            text, why = self._overrides[name]
            widget.edit.setText(text)
            widget.setToolTip(f"{why}\n\n{self._base_tips[name]}")
        widget.setEnabled(name not in self._overrides)

    def set_override(self, name: str, text: str | None, why: str = "") -> None:
        """Show `text` in a field instead of its value, read-only, with `why` as its tooltip (the
        value in force comes from elsewhere, e.g. a lens file's focal length); None gives the
        field back its value and editing."""
        if text is None:
            self._overrides.pop(name, None)
        else:
            self._overrides[name] = (text, why)
        self._show(name)

    def params(self) -> BaseModel:
        """The model the form currently shows (the last accepted values)."""
        return self._params

    def set_params(self, params: BaseModel | dict) -> None:
        """Show `params` (a model or its dict); emits nothing and clears every error mark."""
        if isinstance(params, dict):
            params = self.model_cls.model_validate(params)
        self._params = params
        for name in self.fields:
            self._show(name)

    def _mark(self, name: str, message: str | None) -> None:
        widget = self.fields[name]
        if message is None:
            self.errors.pop(name, None)
            widget.setStyleSheet("")
            widget.setToolTip(self._base_tips[name])
        else:
            self.errors[name] = message
            widget.setStyleSheet(INVALID_STYLE)
            widget.setToolTip(f"{message}\n\n{self._base_tips[name]}")

    def _commit(self, name: str) -> None:
        widget = self.fields[name]
        try:
            value = widget.value()
        except (ValueError, TypeError) as exc:
            given = widget.edit.text() if hasattr(widget, "edit") else None
            self._mark(name, str(ParameterError(name, given, str(exc))))
            return
        old = getattr(self._params, name)
        old = old.model_dump() if isinstance(old, BaseModel) else old
        try:
            new_params = self._params.updated(**{name: value})
        except (ValidationError, WorkbenchError, ValueError) as exc:
            self._mark(name, str(refusal(exc, name, value)))
            return
        self._mark(name, None)
        for edit in widget.findChildren(QLineEdit):
            edit.setModified(False)
        new = getattr(new_params, name)
        new = new.model_dump() if isinstance(new, BaseModel) else new
        self._params = new_params
        if new != old:
            self.edited.emit({name: new})
