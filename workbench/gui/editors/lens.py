"""Lens editor: the lens (library lens, or a lens file opened and added to the user's lens
library), its surface table (an edited lens is saved as ISETCam JSON in the user's lens library,
workbench.optics.lens.io.user_lens_dir, and named in optics.lens_file), paraxial read-outs, the
optics parameters with the level of detail (and what the automatic selector picks, and why), and
the layout / spot / ray-fan / PSF / MTF / distortion / relative-illumination charts, computed and
drawn in the window's side process when seen (workbench.optics.lens.report.draw_chart)."""
from __future__ import annotations

import functools
import json
import math
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (QComboBox, QFileDialog, QHBoxLayout, QLabel, QLineEdit,
                               QPushButton, QScrollArea, QSplitter, QTableWidget, QTableWidgetItem,
                               QTabWidget, QVBoxLayout, QWidget)
from superqt.utils import create_worker

from workbench.errors import InvalidValueError
from workbench.gui.forms import ParamsForm
from workbench.gui.mplcanvas import BackgroundChart
from workbench.optics.formation.lens_setup import prepare_lens
from workbench.optics.lens.io import (LENS_DIR, available_lenses, lens_from_json, lens_to_json, library_lens_path,
                                      load_lens, save_lens, user_lens_dir)
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial
from workbench.optics.lens.report import CHARTS, LENS_ERRORS, draw_chart, draw_no_lens
from workbench.optics.params import OpticsParams, fov_deg

NO_LENS = "(no lens: first-order optics)"
COLUMNS = ("radius (mm)", "thickness (mm)", "material", "semi-aperture (mm)", "stop")


def select_for_project(project) -> tuple[str, dict, str]:
    """(chosen level, the selector's report, a note on the scene it judged) for the project."""
    from workbench.optics.formation.selector import select_level
    from workbench.stages.geometry import project_geometry
    from workbench.stages.scene import chart_scene
    note = ""
    if project.scene.kind == "city":
        project = project.updated(scene=project.scene.updated(kind="slanted_edge"))
        note = "judged on a slanted edge at the scene distance (a city frame is rendered, not drawn)"
    camera = project_geometry(project)
    level, report = select_level(chart_scene(project.scene, camera), project.optics, camera=camera)
    return level, report, note


def _material_text(entry: dict) -> str:
    if entry.get("is_stop") and "glass" not in entry:
        return "stop"
    glass = entry.get("glass", entry.get("ior"))
    return glass if isinstance(glass, str) else json.dumps(glass)


def _material_value(text: str):
    text = text.strip()
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


class LensEditor(QWidget):
    """edited("optics", {field: value}); chart_ready(name) when a chart of the shown lens is drawn
    (only the visible chart is built, on a worker thread); selection_ready(dict) when the automatic
    selector has answered."""

    edited = Signal(str, dict)
    chart_ready = Signal(str)
    selection_ready = Signal(dict)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._project = None
        self._lens_doc: dict | None = None         # the shown prescription as lens JSON
        self._lens: Lens | None = None             # the prescription (file or edited)
        self._edited = False
        self._select_worker = None
        self._select_pending = False

        self.lens_choice = QComboBox(self)
        self.lens_choice.activated.connect(self._lens_chosen)
        open_button = QPushButton("Open lens file…", self)
        open_button.setToolTip("ISETCam JSON, PBRT .dat or Zemax .zmx; it is added to your lens library")
        open_button.clicked.connect(self._open_dialog)
        top = QHBoxLayout()
        top.addWidget(QLabel("Lens", self))
        top.addWidget(self.lens_choice, 1)
        top.addWidget(open_button)

        self.table = QTableWidget(0, len(COLUMNS), self)
        self.table.setHorizontalHeaderLabels(COLUMNS)
        self.table.setToolTip("surfaces from object to image; material: a catalogue glass, an index, 'n/V', "
                              "or a JSON table; the stop has radius 0")
        self.table.cellChanged.connect(self._cell_changed)
        self.table_status = QLabel(self)
        self.table_status.setWordWrap(True)
        self.insert_button = QPushButton("Insert surface", self)
        self.insert_button.setToolTip("a flat surface after the selected one, with no optical effect until edited")
        self.insert_button.clicked.connect(self.insert_surface)
        self.delete_button = QPushButton("Delete surface", self)
        self.delete_button.clicked.connect(self.delete_surface)
        self.save_name = QLineEdit(self)
        self.save_name.setPlaceholderText("name of the edited lens")
        self.save_button = QPushButton("Save edited lens and use it", self)
        self.save_button.clicked.connect(self.save_edited_lens)
        save_row = QHBoxLayout()
        save_row.addWidget(self.save_name, 1)
        save_row.addWidget(self.save_button)

        self.readouts = QLabel(self)
        self.readouts.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.readouts.setWordWrap(True)
        self.form = ParamsForm(OpticsParams, self, exclude=("lens_file",))
        self.form.edited.connect(lambda changes: self.edited.emit("optics", changes))
        self.selector_text = QLabel("level of detail: press “Ask the selector” to see what 'auto' picks", self)
        self.selector_text.setWordWrap(True)
        self.select_button = QPushButton("Ask the selector", self)
        self.select_button.clicked.connect(self.run_selector)

        left = QWidget(self)
        lv = QVBoxLayout(left)
        lv.addLayout(top)
        lv.addWidget(self.table, 1)
        rows = QHBoxLayout()
        rows.addWidget(self.insert_button)
        rows.addWidget(self.delete_button)
        rows.addStretch(1)
        lv.addLayout(rows)
        lv.addWidget(self.table_status)
        lv.addLayout(save_row)
        lv.addWidget(self.readouts)
        sel = QHBoxLayout()
        sel.addWidget(self.selector_text, 1)
        sel.addWidget(self.select_button)
        lv.addLayout(sel)
        scroll = QScrollArea(self)
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.form)
        lv.addWidget(scroll, 1)

        self.charts = QTabWidget(self)
        self.chart_views: dict[str, BackgroundChart] = {}
        for name in CHARTS:
            view = BackgroundChart(f"the {name.replace('_', ' ')} chart of the lens", self)
            view.drawn.connect(lambda name=name: self.chart_ready.emit(name))
            self.chart_views[name] = view
            self.charts.addTab(view, name.replace("_", " "))
        split = QSplitter(Qt.Orientation.Vertical, self)      # the charts under the table: one column
        split.addWidget(left)
        split.addWidget(self.charts)
        split.setStretchFactor(1, 1)
        lay = QVBoxLayout(self)
        lay.addWidget(split)
        self._fill_choices(None)

    # ------------------------------------------------------------------------------ project
    def set_project(self, project) -> None:
        """Show the project's lens and optics; emits nothing."""
        old = self._project
        self._project = project
        self.form.set_params(project.optics)
        if old is None or old.optics.lens_file != project.optics.lens_file:
            self._fill_choices(project.optics.lens_file)
            try:
                self._show_lens(load_lens(project.optics.lens_file) if project.optics.lens_file else None)
            except LENS_ERRORS as exc:
                self._show_lens(None)
                self.table_status.setText(f"cannot read lens {project.optics.lens_file}: {exc}")
        elif old.optics != project.optics or old.sensor.sensor_size_m != project.sensor.sensor_size_m:
            self._lens_changed()
        if project.optics.model == "auto" and (old is None or old.optics != project.optics
                                               or old.scene != project.scene or old.sensor != project.sensor):
            self.run_selector()
        elif old is None or old.optics.model != project.optics.model:
            self.selector_text.setText(f"level of detail: '{project.optics.model}' — “Ask the selector” "
                                       "shows what 'auto' would pick, and why")

    def _fill_choices(self, lens_file: str | None) -> None:
        self.lens_choice.blockSignals(True)
        self.lens_choice.clear()
        self.lens_choice.addItem(NO_LENS, None)
        for name in available_lenses():
            path = library_lens_path(name)
            mine = path.parent != LENS_DIR
            self.lens_choice.addItem(f"{name} (yours)" if mine else name, path.name)
        if lens_file is not None:
            index = self.lens_choice.findData(Path(lens_file).name)
            self.lens_choice.setCurrentIndex(max(index, 0))
        self.lens_choice.blockSignals(False)

    def _lens_chosen(self, index: int) -> None:
        lens_file = self.lens_choice.itemData(index)
        if self._project is not None and lens_file != self._project.optics.lens_file:
            self.edited.emit("optics", {"lens_file": lens_file})

    def _open_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open lens file", str(Path.home()),
                                              "Lens files (*.json *.dat *.zmx)")
        if path:
            self.import_lens(path)

    def import_lens(self, path: str | Path) -> bool:
        """Read a lens file, save it as ISETCam JSON in the user's lens library and use it."""
        try:
            lens = load_lens(Path(path))
        except LENS_ERRORS as exc:
            self.table_status.setText(f"cannot open {path}: {exc}")
            return False
        return self._save_and_use(lens, lens.name or Path(path).stem)

    # ------------------------------------------------------------------------------ the table
    def _show_lens(self, lens: Lens | None) -> None:
        self._lens = lens
        self._edited = False
        self._lens_doc = lens_to_json(lens) if lens is not None else None
        self._fill_table()
        self.table_status.setText("" if lens is not None else "no lens: the optics use the first-order "
                                                               "focal length and f-number below")
        self.save_name.setText(f"{lens.name}-edited" if lens is not None else "")
        self.save_button.setEnabled(False)
        self._lens_changed()

    def _fill_table(self) -> None:
        self.table.blockSignals(True)
        surfaces = self._lens_doc["surfaces"] if self._lens_doc else []
        self.table.setRowCount(len(surfaces))
        for i, s in enumerate(surfaces):
            values = (f"{s['radius']:.6g}", f"{s['thickness']:.6g}", _material_text(s),
                      f"{s['semi_aperture']:.6g}", "stop" if s.get("is_stop") and "glass" not in s else "")
            for j, v in enumerate(values):
                item = QTableWidgetItem(v)
                if j == 4:
                    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                self.table.setItem(i, j, item)
        self.table.resizeColumnsToContents()
        self.table.blockSignals(False)
        for b in (self.insert_button, self.delete_button):
            b.setEnabled(bool(surfaces))

    def _try_doc(self, doc: dict, where: str) -> bool:
        """Use an edited lens document if it makes a valid lens; else say why (in `where`)."""
        try:
            lens = lens_from_json(doc, default_name=self._lens.name)
            paraxial(lens)
        except LENS_ERRORS as exc:
            self.table_status.setText(f"{where}: {exc}")
            self.save_button.setEnabled(False)
            return False
        self._lens_doc, self._lens, self._edited = doc, lens, True
        self.table_status.setText("edited: save the lens to use it in the simulation")
        self.save_button.setEnabled(True)
        self._lens_changed()
        return True

    def _cell_changed(self, row: int, col: int) -> None:
        doc = json.loads(json.dumps(self._lens_doc))
        entry = doc["surfaces"][row]
        item = self.table.item(row, col)
        where = f"surface {row}, {COLUMNS[col]}"
        try:
            if col == 2:
                if entry.get("is_stop") and "glass" not in entry:
                    raise InvalidValueError("the stop's material is the medium before it; edit that surface")
                entry["glass"] = _material_value(item.text())
            else:
                entry[("radius", "thickness", None, "semi_aperture")[col]] = float(item.text())
        except ValueError as exc:
            ok = False
            self.table_status.setText(f"{where}: {exc}")
        else:
            ok = self._try_doc(doc, where)
        item.setBackground(QColor(0, 0, 0, 0) if ok else QColor("#ffd6d6"))

    def insert_surface(self) -> bool:
        """Insert a flat, optically neutral surface after the selected one (at the next vertex, in
        the same medium); edit it into what you need."""
        row = max(self.table.currentRow(), 0)
        doc = json.loads(json.dumps(self._lens_doc))
        here = doc["surfaces"][row]
        after = doc["surfaces"][min(row + 1, len(doc["surfaces"]) - 1)]
        medium = self._lens.surfaces[row].material.to_json()
        doc["surfaces"].insert(row + 1, {"radius": 0.0, "thickness": 0.0, "ior": 1.0, "glass": medium,
                                         "semi_aperture": max(here["semi_aperture"], after["semi_aperture"]),
                                         "is_stop": False})
        if self._try_doc(doc, f"insert after surface {row}"):
            self._fill_table()
            self.table.setCurrentCell(row + 1, 0)
            return True
        return False

    def delete_surface(self) -> bool:
        """Delete the selected surface (not the stop); its thickness is added to the one before."""
        row = self.table.currentRow()
        doc = json.loads(json.dumps(self._lens_doc))
        if row < 0 or row >= len(doc["surfaces"]):
            return False
        entry = doc["surfaces"][row]
        if entry.get("is_stop") and "glass" not in entry:
            self.table_status.setText("the aperture stop cannot be deleted")
            return False
        if row > 0:
            doc["surfaces"][row - 1]["thickness"] += entry["thickness"]
        del doc["surfaces"][row]
        if self._try_doc(doc, f"delete surface {row}"):
            self._fill_table()
            return True
        return False

    def save_edited_lens(self) -> bool:
        """Save the edited prescription in the user's lens library and set optics.lens_file to it."""
        if self._lens is None or not self._edited:
            return False
        return self._save_and_use(self._lens, self.save_name.text().strip())

    def _save_and_use(self, lens: Lens, name: str) -> bool:
        name = name.replace("/", "-").replace("\\", "-").strip(". ")
        if not name:
            self.table_status.setText("give the lens a name")
            return False
        if (LENS_DIR / f"{name}.json").exists() or any((LENS_DIR / f"{name}{e}").exists() for e in (".dat", ".zmx")):
            self.table_status.setText(f"'{name}' is a shipped lens; choose another name")
            return False
        try:
            save_lens(lens, user_lens_dir() / f"{name}.json")
        except OSError as exc:
            self.table_status.setText(f"cannot save the lens: {exc}")
            return False
        self._edited = False
        self.save_button.setEnabled(False)
        self.table_status.setText(f"saved {user_lens_dir() / (name + '.json')}")
        self._fill_choices(f"{name}.json")
        self.edited.emit("optics", {"lens_file": f"{name}.json"})
        return True

    # ------------------------------------------------------------------------------ read-outs
    def used_lens(self) -> Lens | None:
        """The shown prescription as the simulation uses it (scaled if asked, stopped to f/N)."""
        if self._lens is None or self._project is None:
            return self._lens
        o = self._project.optics
        return prepare_lens(self._lens, o.focal_length_mm if o.scale_lens_to_focal_length else None, o.f_number)

    def _sensor_mm(self) -> tuple[float, float, float]:
        h_m, w_m = self._project.sensor.sensor_size_m
        return w_m * 1e3, h_m * 1e3, math.hypot(w_m, h_m) * 1e3

    def _update_readouts(self) -> None:
        if self._project is None:
            return
        w, h, d = self._sensor_mm()
        lens = self.used_lens()
        self._show_focal_length_in_force(lens)
        if lens is None:
            f = self._project.optics.focal_length_mm
            self.readouts.setText(
                f"<b>first-order optics</b>: EFL {f:.4g} mm, f/{self._project.optics.f_number:.3g}; "
                f"FOV {fov_deg(f, w):.2f}° × {fov_deg(f, h):.2f}° (diagonal {fov_deg(f, d):.2f}°)")
            return
        try:
            p = paraxial(lens)
        except LENS_ERRORS as exc:
            self.readouts.setText(f"paraxial data unavailable: {exc}")
            return
        self.readouts.setText(
            f"<b>{lens.name}</b> as used (stop set for f/{self._project.optics.f_number:g}"
            f"{', scaled to the focal length' if self._project.optics.scale_lens_to_focal_length else ''}):<br>"
            f"EFL {p.efl_mm:.4g} mm &nbsp; BFL {p.bfl_mm:.4g} mm &nbsp; f/{p.f_number:.3g} &nbsp; "
            f"total track {p.total_track_mm:.4g} mm<br>"
            f"entrance pupil Ø {p.epd_mm:.4g} mm at {p.entrance_pupil_mm:.4g} mm behind the first vertex; "
            f"exit pupil Ø {p.exit_pupil_diameter_mm:.4g} mm at {p.exit_pupil_mm:.4g} mm from the last vertex<br>"
            f"FOV (paraxial) {p.fov_deg(w):.2f}° × {p.fov_deg(h):.2f}° (diagonal {p.fov_deg(d):.2f}°) "
            f"on the {w:.3g} × {h:.3g} mm sensor")

    def _show_focal_length_in_force(self, lens: Lens | None) -> None:
        """With a lens file that is not scaled, the prescription sets the focal length: the field
        shows its EFL, read-only, instead of the project's unused first-order value."""
        o = self._project.optics
        efl = None
        if lens is not None and not o.scale_lens_to_focal_length:
            try:
                efl = paraxial(lens).efl_mm
            except LENS_ERRORS:
                efl = None
        self.form.set_override("focal_length_mm", None if efl is None else f"{efl:.6g}",
                               f"set by the lens {lens.name if lens else ''} (its effective focal length); "
                               "tick 'scale lens to focal length' to choose the focal length here")

    # ------------------------------------------------------------------------------ background
    def _lens_changed(self) -> None:
        self._update_readouts()
        self._set_charts()

    def _set_charts(self) -> None:
        """Every chart of the shown lens, each computed and drawn in the side process when it is seen."""
        lens = self.used_lens()
        if lens is None:
            for view in self.chart_views.values():
                view.set_draw(draw_no_lens)
            return
        try:
            half_diagonal_deg = paraxial(lens).fov_deg(self._sensor_mm()[2]) / 2 if self._project else 30.0
        except LENS_ERRORS:
            half_diagonal_deg = 30.0
        for name, view in self.chart_views.items():
            view.set_draw(functools.partial(draw_chart, name=name, lens=lens, field_limit_deg=half_diagonal_deg),
                          f"computing the {name.replace('_', ' ')} chart…")

    def run_selector(self) -> None:
        """Ask the automatic level-of-detail selector (on a worker) which optics level it picks."""
        if self._project is None:
            return
        if self._select_worker is not None:
            self._select_pending = True
            return
        self._select_pending = False
        self.select_button.setEnabled(False)
        self.selector_text.setText("the selector is comparing the levels on a probe…")
        self._select_worker = create_worker(select_for_project, self._project, _start_thread=False,
                                            _ignore_errors=True)
        self._select_worker.returned.connect(self._selector_returned)
        self._select_worker.errored.connect(self._selector_errored)
        self._select_worker.finished.connect(self._selector_finished)
        self._select_worker.start()

    def _selector_returned(self, result) -> None:
        level, report, note = result
        rows = "; ".join(f"{r['level']} {r['time_s'] * 1e3:.0f} ms" + (f" ✗ {r['why_not']}" if r.get("why_not") else "")
                         for r in report["levels"])
        self.selector_text.setText(f"<b>auto → '{level}'</b> (current: '{self._project.optics.model}'). "
                                   f"{report['why']}. Full model: {report['reference_why']}."
                                   f"{' ' + note + '.' if note else ''}<br><small>{rows}</small>")
        self.selection_ready.emit({"level": level, "report": report, "note": note})

    def _selector_errored(self, exc: Exception) -> None:
        self.selector_text.setText(f"selector failed: {exc}")

    def _selector_finished(self) -> None:
        self._select_worker = None
        self.select_button.setEnabled(True)
        if self._select_pending:
            self.run_selector()
