"""The main window: preview panes in the centre, movable docks (3-D city, editors, panels) whose
layout is remembered between runs, File/Edit/View/Run menus, and a status bar with the stage
timings and the optics level (with the automatic selector's reason)."""
from __future__ import annotations

import importlib
import time
from pathlib import Path

from pydantic import ValidationError
from PySide6.QtCore import QSettings, Qt, QTimer
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QDockWidget, QFileDialog, QLabel, QMainWindow, QMessageBox, QTabWidget,
                               QProgressBar, QPushButton, QTabBar)

from workbench.errors import InputFileError
from workbench.gui.document import LOAD_ERRORS, Document, sample_projects, scan_autosaves, set_aside
from workbench.gui.live import LiveRunner
from workbench.gui.paths import settings_file
from workbench.gui.previews import PreviewPanes
from workbench.project import Project

MAX_RECENT = 8
# (dock title, module, class) of the editors and panels; each is a QWidget(parent=None) with
# set_project(project) and a signal edited(section, {field: value}); one that runs long jobs also
# has shutdown(), which the window calls when it closes (a docked widget gets no closeEvent).
EDITORS = (("Lens", "workbench.gui.editors.lens", "LensEditor"),
           ("Sensor", "workbench.gui.editors.sensor", "SensorEditor"),
           ("ISP", "workbench.gui.editors.isp", "ISPEditor"),
           ("Exposure sweep", "workbench.gui.panels.sweep", "SweepPanel"),
           ("Experiments", "workbench.gui.panels.experiments", "ExperimentsPanel"),
           ("Metrics", "workbench.gui.panels.metrics", "MetricsPanel"),
           ("Design study", "workbench.gui.panels.study", "StudyPanel"))
# Docks that share one place as tabs: every panel in one column beside the previews, so the four
# panes keep most of the window (1280×800 included) and each panel has the column's full height.
DOCK_TABS = (("3-D city", "Lens", "Sensor", "ISP", "Metrics", "Design study", "Exposure sweep", "Experiments"),)
DOCK_FRACTION = 0.36          # of the window's width, on first run
DOCK_TAB_POSITION = "East"    # the column's tabs stand upright at the window's edge: eight names side by
                              # side in a 460-px column were cut to "Le…", "Me…" at 1280 px
PROGRESS_REPAINT_S = 0.1          # the status bar's progress is shown at most this often
PROGRESS_DELAY_MS = 300           # a run shows its progress bar and Cancel once it has run this long
LAYOUT_KEY = "window/state-v2"     # v1 was the older two-group layout; it is not restored


def _load_editor(module: str, cls: str):
    try:
        return getattr(importlib.import_module(module), cls)
    except ModuleNotFoundError as exc:
        if exc.name and module.startswith(exc.name):
            return None
        raise


def format_stage_times(times_s: dict[str, float], recomputed: list[str]) -> str:
    """'scene 0.12 s · optics* 0.03 s …' — a star marks the stages this run recomputed."""
    parts = []
    for stage, t in times_s.items():
        mark = "*" if stage in recomputed else ""
        parts.append(f"{stage}{mark} {t * 1e3:.0f} ms" if t < 1 else f"{stage}{mark} {t:.2f} s")
    return " · ".join(parts)


def _against(bar, dock, slack: int = 2) -> bool:
    """Whether a tab bar's rectangle adjoins a dock's on one side and lies within its extent."""
    along_x = bar.left() >= dock.left() - slack and bar.right() <= dock.right() + slack
    along_y = bar.top() >= dock.top() - slack and bar.bottom() <= dock.bottom() + slack
    return ((along_x and (abs(bar.top() - dock.bottom() - 1) <= slack or abs(dock.top() - bar.bottom() - 1) <= slack))
            or (along_y and (abs(bar.left() - dock.right() - 1) <= slack or abs(dock.left() - bar.right() - 1) <= slack)))


class MainWindow(QMainWindow):
    def __init__(self, document: Document | None = None, settings: QSettings | None = None,
                 with_city_view: bool = True):
        super().__init__()
        self.setObjectName("workbench-main")
        self.document = document or Document(parent=self)
        self.settings = settings or QSettings(str(settings_file()), QSettings.Format.IniFormat)
        self.live = LiveRunner(self)
        self.previews = PreviewPanes()
        self.setCentralWidget(self.previews)
        self.setTabPosition(Qt.DockWidgetArea.AllDockWidgetAreas, getattr(QTabWidget.TabPosition, DOCK_TAB_POSITION))
        self.docks: dict[str, QDockWidget] = {}
        self.editors: dict[str, object] = {}
        self.city_view = None
        if with_city_view:
            from workbench.gui.city_view import CityView
            self.city_view = CityView(self.document)
            self._add_dock("3-D city", self.city_view, Qt.DockWidgetArea.RightDockWidgetArea)
        for title, module, cls in EDITORS:
            editor_cls = _load_editor(module, cls)
            if editor_cls is None:
                continue
            editor = editor_cls(parent=None)
            editor.edited.connect(self.apply_edit)
            self.editors[title] = editor
            dock = self._add_dock(title, editor, Qt.DockWidgetArea.RightDockWidgetArea)
            if hasattr(editor, "set_on_screen"):      # panels that work only while they are seen
                dock.visibilityChanged.connect(editor.set_on_screen)
        for group in DOCK_TABS:
            present = [self.docks[t] for t in group if t in self.docks]
            if present:
                present[0].raise_()
        self._build_status_bar()
        self._build_menus()
        self.document.projectChanged.connect(self._project_changed)
        self.document.dirtyChanged.connect(self._update_title)
        self.document.pathChanged.connect(self._update_title)
        self.live.frameReady.connect(self._frame_ready)
        self.live.readoutsReady.connect(self._readouts_ready)
        self.live.progress.connect(self._progress)
        self.live.failed.connect(self._run_failed)
        self.live.busyChanged.connect(self._busy_changed)
        self.previews.inspected.connect(self._show_inspected)
        self.error_box: QMessageBox | None = None
        self.resize(1280, 860)
        self._restore_layout()
        self._project_changed(self.document.project)
        self._update_title()

    # -- layout ----------------------------------------------------------------------------
    def _add_dock(self, title: str, widget, area) -> QDockWidget:
        """A movable, floatable dock holding the widget itself. Editors scroll their own forms: a
        dock-wide scroll area around an editor that has one inside recursed in Qt's layout until
        the stack overflowed (a segfault on the Sensor dock's 'QE curves' tab)."""
        dock = QDockWidget(title, self)
        dock.setObjectName(f"dock-{title}")
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable
                         | QDockWidget.DockWidgetFeature.DockWidgetClosable)
        group = next((g for g in DOCK_TABS if title in g), ())
        first = next((self.docks[t] for t in group if t in self.docks), None)
        if first is not None:
            self.tabifyDockWidget(first, dock)     # straight into its tab group (no split first)
        else:
            self.addDockWidget(area, dock)
        self.docks[title] = dock
        return dock

    def _restore_layout(self) -> None:
        geometry = self.settings.value("window/geometry")
        state = self.settings.value(LAYOUT_KEY)
        if geometry is not None:
            self.restoreGeometry(geometry)
        if state is not None:
            self.restoreState(state)
        else:                      # sizes apply once the window is laid out
            QTimer.singleShot(0, self._default_layout)

    def hide_stale_tab_bars(self) -> None:
        """Qt 6.12 leaves an earlier tab bar of a tabbed dock group visible over other docks when
        several groups are built; hide every main-window tab bar not sitting against a shown dock
        (beside it, the side DOCK_TAB_POSITION puts it), and show every live one's names whole."""
        live = [d.geometry() for d in self.docks.values() if d.isVisible() and not d.isFloating()]
        for bar in self.findChildren(QTabBar):
            if bar.parent() is self and bar.isVisible():
                bar.setElideMode(Qt.TextElideMode.ElideNone)
                if not any(_against(bar.geometry(), d) for d in live):
                    bar.hide()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        QTimer.singleShot(0, self.hide_stale_tab_bars)

    def _default_layout(self) -> None:
        """First run: the previews get most of the room, the panels one column beside them, with
        the 3-D city in front for a city project and the sensor editor otherwise."""
        docks = list(self.docks.values())
        if docks:
            self.resizeDocks(docks[:1], [int(DOCK_FRACTION * self.width())], Qt.Orientation.Horizontal)
        front = "3-D city" if self.document.project.scene.kind == "city" else "Sensor"
        if front in self.docks:
            self.docks[front].raise_()
        QTimer.singleShot(0, self.hide_stale_tab_bars)

    def save_layout(self) -> None:
        self.settings.setValue("window/geometry", self.saveGeometry())
        self.settings.setValue(LAYOUT_KEY, self.saveState())
        self.settings.sync()

    def _build_status_bar(self) -> None:
        bar = self.statusBar()
        self.optics_label = QLabel("optics: —")
        self.times_label = QLabel("")
        self.progress_bar = QProgressBar()
        self._progress_shown_at = -PROGRESS_REPAINT_S
        self.progress_bar.setMaximumWidth(160)
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setVisible(False)
        self._progress_delay = QTimer(self)
        self._progress_delay.setSingleShot(True)
        self._progress_delay.setInterval(PROGRESS_DELAY_MS)
        self._progress_delay.timeout.connect(self._show_progress)
        self._last_progress: tuple[str, float] | None = None
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("stop the running simulation")
        self.cancel_button.clicked.connect(self.cancel_run)
        self.cancel_button.setVisible(False)
        bar.addPermanentWidget(self.times_label)
        bar.addPermanentWidget(self.optics_label)
        bar.addPermanentWidget(self.progress_bar)
        bar.addPermanentWidget(self.cancel_button)

    def _build_menus(self) -> None:
        m = self.menuBar().addMenu("&File")
        new_menu = m.addMenu("&New from sample")
        for name in sample_projects():
            new_menu.addAction(name, lambda n=name: self.new_from_sample(n))
        self._action(m, "&Open…", QKeySequence.StandardKey.Open, self.open_dialog)
        self.recent_menu = m.addMenu("Open &recent")
        self._action(m, "&Save", QKeySequence.StandardKey.Save, self.save)
        self._action(m, "Save &as…", QKeySequence.StandardKey.SaveAs, self.save_as_dialog)
        m.addSeparator()
        self._action(m, "&Quit", QKeySequence.StandardKey.Quit, self.close)
        self._refresh_recent_menu()
        e = self.menuBar().addMenu("&Edit")
        undo = self.document.undo_stack.createUndoAction(self, "&Undo")
        undo.setShortcut(QKeySequence.StandardKey.Undo)
        redo = self.document.undo_stack.createRedoAction(self, "&Redo")
        redo.setShortcut(QKeySequence.StandardKey.Redo)
        e.addAction(undo)
        e.addAction(redo)
        v = self.menuBar().addMenu("&View")
        self._action(v, "&Fit images", QKeySequence("Ctrl+0"), self.previews.fit)
        self._action(v, "&Actual pixels (1:1)", QKeySequence("Ctrl+1"), self.previews.actual_size)
        self._action(v, "Zoom &in", QKeySequence.StandardKey.ZoomIn, lambda: self.previews.zoom(2 ** 0.5))
        self._action(v, "Zoom &out", QKeySequence.StandardKey.ZoomOut, lambda: self.previews.zoom(2 ** -0.5))
        v.addSeparator()
        for dock in self.docks.values():
            v.addAction(dock.toggleViewAction())
        clip = QAction("Highlight &clipped pixels", self, checkable=True)
        clip.toggled.connect(self.previews.highlight_clipped.setChecked)
        self.previews.highlight_clipped.toggled.connect(clip.setChecked)
        v.addAction(clip)
        r = self.menuBar().addMenu("&Run")
        self._action(r, "&Re-run", QKeySequence("F5"), lambda: self.live.submit(self.document.project))
        self._action(r, "&Cancel", QKeySequence("Esc"), self.cancel_run)

    def _action(self, menu, text, shortcut, slot) -> QAction:
        act = QAction(text, self)
        act.setShortcut(shortcut)
        act.triggered.connect(slot)
        menu.addAction(act)
        return act

    # -- document → views ------------------------------------------------------------------
    def _update_title(self, *_changed) -> None:
        self.setWindowTitle(f"{self.document.display_name}[*] — Camera Workbench")
        self.setWindowModified(self.document.dirty)

    def _project_changed(self, project: Project) -> None:
        self.previews.hold_histograms(True)      # now, not when the run's busy signal arrives: a
        self.live.submit(project)                # histogram timer due meanwhile took the GUI thread ~12 ms
        for editor in self.editors.values():     # while the worker runs (they took ~4 ms of an edit)
            editor.set_project(project)
        if self.city_view is not None:
            self.city_view.set_project(project)
        self._update_title()

    def apply_edit(self, section: str, changes: dict) -> bool:
        """An editor's edit → one undoable document edit; a refused value shows why."""
        try:
            self.document.edit(section, changes)
        except (ValidationError, ValueError) as exc:
            self.show_error("That value is not allowed", str(exc))
            for editor in self.editors.values():
                editor.set_project(self.document.project)
            return False
        return True

    def _frame_ready(self, frame) -> None:
        if frame.project is not self.document.project and frame.project != self.document.project:
            return                        # a result for a project we have since left
        self.previews.show_frame(frame)
        self.times_label.setText(format_stage_times(frame.stage_times_s, frame.recomputed)
                                 + (" (preview)" if frame.preview else ""))
        self.optics_label.setText(f"optics: {frame.optics_level}")
        self.optics_label.setToolTip(frame.optics_reason or "the project's optics level")
        sweep = self.editors.get("Exposure sweep")
        if sweep is not None and not frame.preview and "signal" in frame.recomputed:
            sweep.set_frame(frame.project, frame.signal_rate_e_per_s, frame.colour_wavelengths_nm)
        metrics = self.editors.get("Metrics")
        if metrics is not None and not frame.preview and frame.readouts is not None:
            metrics.set_frame(frame)             # else with its read-outs (_readouts_ready)

    def _readouts_ready(self, frame, readouts: dict) -> None:
        frame.readouts = readouts
        metrics = self.editors.get("Metrics")
        if metrics is not None and frame is self.previews.frame:
            metrics.set_frame(frame)

    def _show_inspected(self, text: str) -> None:
        self.statusBar().showMessage(text, 4000)

    def _progress(self, stage: str, fraction: float) -> None:
        """Show a stage's progress, at most every PROGRESS_REPAINT_S: QProgressBar.setValue repaints
        at once (~9 ms each under Xvfb: 183 calls held the GUI thread 1.7 s in `bench gui`). Until
        the bar is shown (a run longer than PROGRESS_DELAY_MS) the report is only kept."""
        self._last_progress = (stage, fraction)
        now = time.monotonic()
        if not self.progress_bar.isVisibleTo(self) or now - self._progress_shown_at < PROGRESS_REPAINT_S:
            return
        self._progress_shown_at = now
        self.progress_bar.setFormat(f"{stage} %p%")
        self.progress_bar.setValue(round(100 * fraction))

    def cancel_run(self) -> None:
        """Run ▸ Cancel: stop the running simulation and say so (the panes keep the last frame)."""
        was_busy = self.live.busy
        self.live.cancel()
        self.statusBar().showMessage("simulation cancelled: the panes show the last finished frame"
                                     if was_busy else "nothing to cancel: no simulation is running", 8000)

    def _busy_changed(self, busy: bool) -> None:
        """A run started or ended. Its progress bar and Cancel appear only once it has run for
        PROGRESS_DELAY_MS: an edit that takes tens of ms would otherwise repaint the status bar
        twice."""
        self.previews.hold_histograms(busy)
        if busy:
            self._last_progress = None
            self._progress_delay.start()
        else:
            self._progress_delay.stop()
            self.progress_bar.setVisible(False)
            self.cancel_button.setVisible(False)

    def _show_progress(self) -> None:
        if not self.live.busy:
            return
        self._progress_shown_at = -PROGRESS_REPAINT_S       # the run's last report, at once
        self.progress_bar.setValue(0)
        self.progress_bar.setVisible(True)
        self.cancel_button.setVisible(True)
        if self._last_progress is not None:
            self._progress(*self._last_progress)

    def _run_failed(self, message: str) -> None:
        self.statusBar().showMessage(f"simulation failed: {message}", 15000)

    # -- dialogs ---------------------------------------------------------------------------
    def show_error(self, title: str, text: str) -> QMessageBox:
        """A window-modal error box that does not block the event loop."""
        box = QMessageBox(QMessageBox.Icon.Critical, title, text, QMessageBox.StandardButton.Ok, self)
        box.setWindowModality(Qt.WindowModality.WindowModal)
        box.open()
        self.error_box = box
        return box

    def ask_save_changes(self) -> QMessageBox.StandardButton:
        """Save / Discard / Cancel for unsaved edits (tests replace this)."""
        return QMessageBox.question(
            self, "Unsaved changes", f"Save the changes to {self.document.display_name}?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard
            | QMessageBox.StandardButton.Cancel, QMessageBox.StandardButton.Save)

    def ask_recover(self, autosave_file: Path) -> bool:
        """Yes/No: recover the edits of a session that ended without saving (tests replace this)."""
        answer = QMessageBox.question(self, "Recover unsaved edits", "A previous session ended without "
                                      f"saving. Recover its edits?\n({autosave_file})")
        return answer == QMessageBox.StandardButton.Yes

    def may_discard(self) -> bool:
        """True when the current project may be replaced (saved, discarded, or not dirty)."""
        if not self.document.dirty:
            return True
        answer = self.ask_save_changes()
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        return answer == QMessageBox.StandardButton.Discard

    # -- file actions ----------------------------------------------------------------------
    def new_from_sample(self, name: str) -> None:
        if self.may_discard():
            self.document.new_from_sample(name)

    def open_path(self, path: str | Path) -> bool:
        """Open a project file; a malformed one shows an error and changes nothing."""
        if not self.may_discard():
            return False
        try:
            self.document.open(path)
        except LOAD_ERRORS as exc:
            self.show_error("Cannot open project", str(exc))
            return False
        self._add_recent(Path(path))
        return True

    def open_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open project", str(self._dialog_dir()),
                                              "Workbench projects (*.cwproj *.json);;All files (*)")
        if path:
            self.open_path(path)

    def save(self) -> bool:
        if self.document.path is None:
            return self.save_as_dialog()
        return self.save_to(self.document.path)

    def save_to(self, path: str | Path) -> bool:
        try:
            self.document.save(path)
        except OSError as exc:
            self.show_error("Cannot save project", f"{path}: {exc}")
            return False
        self._add_recent(Path(path))
        return True

    def save_as_dialog(self) -> bool:
        path, _ = QFileDialog.getSaveFileName(self, "Save project as",
                                              str(self._dialog_dir() / f"{self.document.project.name}.json"),
                                              "Workbench projects (*.cwproj *.json)")
        return self.save_to(path) if path else False

    def _dialog_dir(self) -> Path:
        return self.document.path.parent if self.document.path else Path.cwd()

    def recent_files(self) -> list[str]:
        value = self.settings.value("recent/files") or []
        return [value] if isinstance(value, str) else list(value)

    def _add_recent(self, path: Path) -> None:
        files = [str(path.resolve())] + [f for f in self.recent_files() if f != str(path.resolve())]
        self.settings.setValue("recent/files", files[:MAX_RECENT])
        self._refresh_recent_menu()

    def _refresh_recent_menu(self) -> None:
        self.recent_menu.clear()
        for f in self.recent_files():
            self.recent_menu.addAction(f, lambda p=f: self.open_path(p))
        self.recent_menu.setEnabled(bool(self.recent_files()))

    def offer_recovery(self) -> None:
        """After a crash: move aside (with a message) every autosave that cannot be read, then
        offer the newest one left by a session that is gone."""
        found, unreadable = scan_autosaves()
        for path, why in unreadable:
            self.report_rejected_autosave(set_aside(path), InputFileError(path, why))
        if not found:
            return
        if not self.ask_recover(found[0]):
            found[0].unlink(missing_ok=True)
            return
        try:
            self.document.recover(found[0])
        except LOAD_ERRORS as exc:         # a damaged autosave, or one a later version wrote
            moved = set_aside(found[0])
            self.report_rejected_autosave(moved, exc)

    def report_rejected_autosave(self, moved: Path, error: Exception) -> None:
        """Say that an autosave could not be recovered, why, and where it now lies (tests replace this)."""
        QMessageBox.warning(self, "Unsaved edits could not be recovered",
                            f"The autosave of an earlier session cannot be recovered:\n{error}\n\n"
                            f"It was moved to {moved} and will not be offered again.")

    # -- closing ---------------------------------------------------------------------------
    def closeEvent(self, event) -> None:
        if not self.may_discard():
            event.ignore()
            return
        self.save_layout()
        for editor in self.editors.values():
            if hasattr(editor, "shutdown"):
                editor.shutdown()
        from workbench.gui import side_process
        side_process.shutdown()
        self.live.shutdown()
        if self.city_view is not None:
            self.city_view.close_view()
        self.document.close()
        event.accept()
