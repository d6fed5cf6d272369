"""Exposure-bias sweep panel: EV range and step (saved as project.experiment.ev_biases), the sweep
job of workbench.experiments.ev_sweep on a worker thread with progress and Cancel, a thumbnail per
EV and a chart of mean level, clipped fraction and SNR against EV.

Results are replaced only when a sweep completes: a cancelled or failed sweep leaves the previous
complete results (or none) in place, never a partial set."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QSize, Qt, Signal
from PySide6.QtGui import QIcon, QImage, QPixmap
from PySide6.QtWidgets import (QDoubleSpinBox, QHBoxLayout, QLabel, QListView, QListWidget,
                               QListWidgetItem, QProgressBar, QPushButton, QSplitter, QVBoxLayout,
                               QWidget)
from superqt.utils import create_worker

from workbench.errors import WorkbenchError
from workbench.experiments.ev_sweep import EVPoint, draw_ev_sweep, ev_sweep_job, ev_values
from workbench.gui.mplcanvas import ChartImage, render_rgba
from workbench.jobs import CancelToken, JobCancelled


def rgb_pixmap(rgb: np.ndarray) -> QPixmap:
    """H×W×3 uint8 → QPixmap (copied, so the array may go away)."""
    rgb = np.ascontiguousarray(rgb)
    h, w, _ = rgb.shape
    return QPixmap.fromImage(QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy())


def _range_of(evs: list[float]) -> tuple[float, float, float]:
    """(start, stop, step) of an EV list; step 1 when it is not evenly spaced."""
    evs = sorted(evs)
    steps = np.diff(evs)
    step = float(steps[0]) if steps.size and np.allclose(steps, steps[0]) and steps[0] > 0 else 1.0
    return float(evs[0]), float(evs[-1]), step


def sweep_and_chart(project, signal_rate_e_per_s, wavelengths_nm, evs, token, chart_px: tuple[int, int]):
    """The sweep job, then its chart rasterised (RGBA) on the same worker thread:
    yields Progress, returns (points, chart)."""
    points = yield from ev_sweep_job(project, signal_rate_e_per_s, wavelengths_nm, evs, token)
    return points, render_rgba(lambda fig: draw_ev_sweep(fig, points), *chart_px)


class SweepPanel(QWidget):
    """edited("experiment", {"ev_biases": [...]}) when the range or step changes;
    sweep_finished(list[EVPoint]) / sweep_cancelled() / sweep_failed(str) when a run ends."""

    edited = Signal(str, dict)
    sweep_finished = Signal(list)
    sweep_cancelled = Signal()
    sweep_failed = Signal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._project = None
        self._frame: tuple[np.ndarray, np.ndarray] | None = None
        self._worker = None
        self._token: CancelToken | None = None
        self.results: list[EVPoint] = []

        self.start = self._spin(-16, 16, -4.0, "first EV")
        self.stop = self._spin(-16, 16, 4.0, "last EV")
        self.step = self._spin(0.25, 8, 1.0, "EV step")
        for spin in (self.start, self.stop, self.step):
            spin.editingFinished.connect(self._range_edited)
        self.run_button = QPushButton("Run sweep", self)
        self.run_button.clicked.connect(self.run)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.cancel)
        self.cancel_button.setEnabled(False)
        self.progress = QProgressBar(self)
        self.status = QLabel("no frame yet: the sweep runs on the current frame's pixel signal", self)
        self.status.setWordWrap(True)
        self.thumbnails = QListWidget(self)
        self.thumbnails.setViewMode(QListView.ViewMode.IconMode)
        self.thumbnails.setIconSize(QSize(128, 96))
        self.thumbnails.setFlow(QListView.Flow.LeftToRight)
        self.thumbnails.setWrapping(False)                  # one row, scrolled sideways
        self.thumbnails.setMovement(QListView.Movement.Static)
        self.thumbnails.setMinimumHeight(120)
        self.chart = ChartImage("Run the sweep: mean level, clipped fraction and SNR against EV appear here",
                                self)

        controls = QHBoxLayout()
        for text, spin in (("EV from", self.start), ("to", self.stop), ("step", self.step)):
            controls.addWidget(QLabel(text, self))
            controls.addWidget(spin)
        controls.addStretch(1)
        run_row = QHBoxLayout()
        run_row.addWidget(self.run_button)
        run_row.addWidget(self.cancel_button)
        run_row.addWidget(self.progress, 1)
        split = QSplitter(Qt.Orientation.Vertical, self)
        split.addWidget(self.thumbnails)
        split.addWidget(self.chart)
        lay = QVBoxLayout(self)
        lay.addLayout(controls)
        lay.addLayout(run_row)
        lay.addWidget(self.status)
        lay.addWidget(split, 1)
        self._update_buttons()

    def _spin(self, lo, hi, value, tip) -> QDoubleSpinBox:
        spin = QDoubleSpinBox(self)
        spin.setRange(lo, hi)
        spin.setSingleStep(0.5)
        spin.setDecimals(2)
        spin.setValue(value)
        spin.setToolTip(tip)
        return spin

    # -------------------------------------------------------------------------------- inputs
    def set_project(self, project) -> None:
        """Show the project's EV range; emits nothing."""
        self._project = project
        start, stop, step = _range_of(project.experiment.ev_biases)
        for spin, v in ((self.start, start), (self.stop, stop), (self.step, step)):
            spin.blockSignals(True)
            spin.setValue(v)
            spin.blockSignals(False)
        self._update_buttons()

    def set_frame(self, project, signal_rate_e_per_s: np.ndarray, wavelengths_nm: np.ndarray) -> None:
        """A new pixel-signal stage (e⁻/s per pixel) and its wavelengths: the input of the next sweep."""
        self.set_project(project)
        self._frame = (signal_rate_e_per_s, wavelengths_nm)
        if self._worker is None:
            self.status.setText(f"frame ready ({signal_rate_e_per_s.shape[1]}×{signal_rate_e_per_s.shape[0]} px)")
        self._update_buttons()

    def evs(self) -> list[float]:
        return ev_values(self.start.value(), self.stop.value(), self.step.value())

    def _range_edited(self) -> None:
        try:
            evs = self.evs()
        except WorkbenchError as exc:
            self.status.setText(str(exc))
            return
        if self._project is not None and evs != list(self._project.experiment.ev_biases):
            self.edited.emit("experiment", {"ev_biases": evs})

    def _update_buttons(self) -> None:
        running = self._worker is not None
        self.run_button.setEnabled(not running and self._frame is not None and self._project is not None)
        self.cancel_button.setEnabled(running)

    # ------------------------------------------------------------------------------ the job
    def run(self) -> None:
        """Start a sweep over the current range on the current frame (background thread)."""
        if self._worker is not None or self._frame is None or self._project is None:
            return
        try:
            evs = self.evs()
        except WorkbenchError as exc:
            self.status.setText(str(exc))
            return
        self._token = CancelToken()
        rate, wl = self._frame
        self._worker = create_worker(sweep_and_chart, self._project, rate, wl, evs, self._token,
                                     self.chart.size_px(), _start_thread=False, _ignore_errors=True)
        self._worker.yielded.connect(self._progress)
        self._worker.returned.connect(self._returned)
        self._worker.errored.connect(self._errored)
        self._worker.finished.connect(self._finished)
        self.progress.setRange(0, len(evs))
        self.progress.setValue(0)
        self.status.setText(f"sweeping {len(evs)} exposures…")
        self._worker.start()
        self._update_buttons()

    def cancel(self) -> None:
        """Stop the running sweep; nothing of it is kept."""
        if self._token is not None:
            self._token.cancel()

    def _progress(self, p) -> None:
        self.progress.setValue(int(p.done))
        self.status.setText(p.message)

    def _returned(self, result: tuple[list[EVPoint], np.ndarray]) -> None:
        points, chart_rgba = result
        if self._token is not None and self._token.cancelled:
            self.status.setText("sweep cancelled")
            self.sweep_cancelled.emit()
            return
        self.results = list(points)
        self.thumbnails.clear()
        for p in points:
            item = QListWidgetItem(QIcon(rgb_pixmap(p.thumbnail)),
                                   f"EV {p.ev:+g}\n{p.exposure_s * 1e3:.3g} ms, {100 * p.fraction_clipped:.0f} % clip")
            self.thumbnails.addItem(item)
        self.chart.show_rgba(chart_rgba)
        self.status.setText(f"{len(points)} exposures, EV {points[0].ev:+g} … {points[-1].ev:+g}")
        self.sweep_finished.emit(self.results)

    def _errored(self, exc: Exception) -> None:
        if isinstance(exc, JobCancelled):
            self.status.setText("sweep cancelled")
            self.sweep_cancelled.emit()
        else:
            self.status.setText(f"sweep failed: {exc}")
            self.sweep_failed.emit(str(exc))

    def _finished(self) -> None:
        self._worker = None
        self._token = None
        self._update_buttons()

    def shutdown(self) -> None:
        """The window is closing: stop a running sweep."""
        self.cancel()

    def closeEvent(self, event) -> None:
        self.shutdown()
        super().closeEvent(event)
