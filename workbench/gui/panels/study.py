"""Design-study panel: the grid `workbench study` runs (SECTION.FIELD=V1,V2,… per line, every
combination), started from the current design on a worker thread with progress and Cancel, into a
folder that a later run of the same grid resumes; its table and the Pareto chart of two chosen
metrics update as each design is measured (workbench.metrics.study)."""
from __future__ import annotations

import time

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QComboBox, QHBoxLayout, QLabel, QLineEdit, QPlainTextEdit, QProgressBar,
                               QPushButton, QSplitter, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget)
from superqt.utils import create_worker

from workbench.errors import WorkbenchError
from workbench.gui.mplcanvas import ChartImage, render_rgba
from workbench.jobs import CancelToken, JobCancelled
from workbench.metrics.grid_checks import BLURRING_GRID, check_grid, default_grid
from workbench.metrics.study import HIGHER_IS_BETTER, parse_vary



def study_with_charts(project, vary, out, x, y, token, chart_px):
    """run_study, yielding (Progress, table rows, Pareto RGBA) after each design: a worker's job."""
    from workbench.metrics.charts import draw_pareto
    from workbench.metrics.study import run_study, study_sigma, table_rows
    job = run_study(project, vary, out, x=x, y=y, cancel=token)
    while True:
        try:
            progress = next(job)
        except StopIteration as stop:
            doc = stop.value
            break
        designs = _study_designs(out)
        rows, sigma = table_rows(designs), study_sigma(designs, x, y)
        rgba = render_rgba(lambda fig: draw_pareto(fig.add_subplot(), rows, x, y, HIGHER_IS_BETTER[x],
                                                   HIGHER_IS_BETTER[y], fields=list(vary), sigma=sigma), *chart_px)
        yield progress, rows, rgba
    return doc


def _study_designs(out) -> list[dict]:
    from workbench.datasets.files import read_json_object
    path = out / "study.json"
    if not path.exists():
        return []
    return read_json_object(path, "study file", "").get("designs", [])


class StudyPanel(QWidget):
    """finished(dict study document) / failed(str) / cancelled() when a run ends."""

    edited = Signal(str, dict)          # the editor protocol; this panel edits nothing
    finished = Signal(dict)
    failed = Signal(str)
    cancelled = Signal()

    def __init__(self, parent=None):
        super().__init__(parent)
        self._project = None
        self._worker = None
        self._token: CancelToken | None = None
        self.grid = QPlainTextEdit(BLURRING_GRID, self)
        self.grid.setToolTip("one SECTION.FIELD=V1,V2,… per line (as in the project file); every combination runs")
        self.grid.setMaximumHeight(80)
        metrics = sorted(k for k in HIGHER_IS_BETTER if k != "map")
        self.x = QComboBox(self)
        self.x.addItems(metrics)
        self.x.setCurrentText("mtf50_lp_mm")
        self.y = QComboBox(self)
        self.y.addItems(metrics)
        self.y.setCurrentText("snr_at_10cd_m2_10ms_dB")
        self.folder = QLineEdit(self)
        self.folder.setToolTip("the study's folder: study.json/.csv/.md and pareto.png; the same grid resumes there")
        self.run_button = QPushButton("Run study", self)
        self.run_button.clicked.connect(self.run)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.cancel)
        self.progress = QProgressBar(self)
        self.status = QLabel("set the grid, then Run study (the current design is the starting point)", self)
        self.status.setWordWrap(True)
        self.notes = QLabel(self)                  # what the optics level ignores of the grid (grid_checks)
        self.notes.setWordWrap(True)
        self.notes.setVisible(False)
        self.table = QTableWidget(0, 0, self)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.chart = ChartImage("the Pareto chart of the two metrics appears as designs are measured", self)

        axes = QHBoxLayout()
        for text, w in (("x", self.x), ("y", self.y)):
            axes.addWidget(QLabel(text, self))
            axes.addWidget(w, 1)
        folder = QHBoxLayout()
        folder.addWidget(QLabel("folder", self))
        folder.addWidget(self.folder, 1)
        run_row = QHBoxLayout()
        run_row.addWidget(self.run_button)
        run_row.addWidget(self.cancel_button)
        run_row.addWidget(self.progress, 1)
        split = QSplitter(Qt.Orientation.Vertical, self)
        split.addWidget(self.chart)
        split.addWidget(self.table)
        lay = QVBoxLayout(self)
        lay.addWidget(QLabel("grid (one field per line)", self))
        lay.addWidget(self.grid)
        lay.addWidget(self.notes)
        lay.addLayout(axes)
        lay.addLayout(folder)
        lay.addLayout(run_row)
        lay.addWidget(self.status)
        lay.addWidget(split, 1)
        self._update_buttons()

    def set_project(self, project) -> None:
        """The design a study starts from; a grid the user has not edited follows its optics level
        (metrics.grid_checks.default_grid)."""
        if self.grid.toPlainText() in {default_grid(p) for p in (project, self._project) if p is not None} \
                | {BLURRING_GRID}:
            self.grid.setPlainText(default_grid(project))
        self._project = project
        if not self.folder.text():
            from workbench.gui.paths import data_dir
            self.folder.setText(str(data_dir() / "studies" / f"{project.name}-{time.strftime('%Y%m%d-%H%M%S')}"))
        self._update_buttons()

    def _update_buttons(self) -> None:
        running = self._worker is not None
        self.run_button.setEnabled(not running and self._project is not None)
        self.cancel_button.setEnabled(running)

    def run(self) -> None:
        """Start the grid on a worker thread (a folder holding this grid resumes)."""
        from pathlib import Path
        if self._worker is not None or self._project is None:
            return
        try:
            lines = [ln.strip() for ln in self.grid.toPlainText().splitlines() if ln.strip()]
            vary = parse_vary(lines)
            notes = check_grid(self._project, vary)
        except WorkbenchError as exc:
            self.status.setText(str(exc))
            return
        self.notes.setText("\n".join(f"note: {n}" for n in notes))
        self.notes.setVisible(bool(notes))
        self._token = CancelToken()
        self._worker = create_worker(study_with_charts, self._project, vary, Path(self.folder.text()),
                                     self.x.currentText(), self.y.currentText(), self._token, self.chart.size_px(),
                                     _start_thread=False, _ignore_errors=True)
        self._worker.yielded.connect(self._step)
        self._worker.returned.connect(self._returned)
        self._worker.errored.connect(self._errored)
        self._worker.finished.connect(self._finished)
        self.status.setText("starting…")
        self._worker.start()
        self._update_buttons()

    def cancel(self) -> None:
        if self._token is not None:
            self._token.cancel()

    def _step(self, item) -> None:
        progress, rows, rgba = item
        self.progress.setRange(0, int(progress.total))
        self.progress.setValue(int(progress.done))
        self.status.setText(progress.message)
        self._fill(rows)
        self.chart.show_rgba(rgba)

    def _fill(self, rows: list[dict]) -> None:
        cols = list(rows[0]) if rows else []
        self.table.setColumnCount(len(cols))
        self.table.setHorizontalHeaderLabels(cols)
        self.table.setRowCount(len(rows))
        for i, row in enumerate(rows):
            for j, c in enumerate(cols):
                v = row[c]
                self.table.setItem(i, j, QTableWidgetItem(f"{v:.4g}" if isinstance(v, float) else str(v)))

    def _returned(self, doc: dict) -> None:
        seconds = sum(d["seconds"] for d in doc["designs"])
        self.status.setText(f"{len(doc['designs'])} designs measured; machine time {seconds:.1f} s; "
                            f"folder {self.folder.text()}")
        self.finished.emit(doc)

    def _errored(self, exc: Exception) -> None:
        if isinstance(exc, JobCancelled):
            self.status.setText("study cancelled: the designs measured so far are kept; Run study resumes")
            self.cancelled.emit()
        else:
            self.status.setText(f"study failed: {exc}")
            self.failed.emit(str(exc))

    def _finished(self) -> None:
        self._worker, self._token = None, None
        self._update_buttons()

    def shutdown(self) -> None:
        """The window is closing: stop after the design being measured."""
        self.cancel()
