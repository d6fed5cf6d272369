"""Metrics panel: the current frame's read-outs (exposure, gain, electrons per channel, clipping,
pixel signal dynamic range, SNR at the road users) and the camera's measurements on test charts (system
MTF, SNR against signal, ΔE2000; workbench.metrics), re-measured after each edit in the window's side
process (gui.side_process: kept alive; a worker thread waits for it, so its Python never holds the
window's GIL),
with their charts, one to a tab so each has the dock's width (it is 538 px at 1280×800), legends
below the axes. "Pin as A" keeps the current design as A: the table then shows A, the current
design B, the change and, for the measurements, the verdict (study.compare_verdict: better only
beyond the two designs' measured uncertainties), the charts draw both, named by what differs
(project.difference_labels), and an A | B | B − A strip compares the sRGB frames on one colour
scale. ΔE2000 is shown for held-out patches (each through the colour matrix fitted to the other 23)
beside the fitted (training) patches. The table's metric names wrap, so its value columns, B − A
included, stay in view at the dock's width.

Measurements run one at a time; an edit during a measurement queues one more run of the newest
project (older requests are dropped), so results never arrive out of order."""
from __future__ import annotations

import functools
import time

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (QCheckBox, QHBoxLayout, QHeaderView, QLabel, QPushButton, QSplitter, QTableWidget,
                               QTableWidgetItem, QTabWidget, QVBoxLayout, QWidget)
from superqt.utils import create_worker

from workbench.gui import side_process
from workbench.gui.mplcanvas import BackgroundChart, ChartImage, render_rgba
from workbench.metrics.charts import CHART_TITLES, draw_chart

DEBOUNCE_MS = 300
ELAPSED_STEP_MS = 500
MAX_CHANGES_SHOWN = 4
MAX_VERDICT_CHARS = 24                # a longer verdict ('not comparable: …') is cut, whole in its tooltip
CHART_TABS = {"mtf": "MTF", "snr": "SNR", "de": "ΔE"}
COLUMNS = ("metric", "A", "B", "B − A", "A vs B")
# (key, label, format) of the rows: frame read-outs, then the camera's summary measurements
READOUT_ROWS = (("exposure_s", "exposure (ms)", lambda v: f"{1e3 * v:.3g}"),
                ("analog_gain", "analog gain", lambda v: f"{v:.3g}"),
                ("clipped_pct", "clipped pixels (%)", lambda v: f"{v:.2f}"),
                ("pixel_signal_dynamic_range_dB", "pixel signal dynamic range (dB)", lambda v: f"{v:.1f}"),
                ("road_users", "road users in view", lambda v: f"{v:d}"),
                ("road_user_snr_median", "SNR at road users (median)", lambda v: f"{v:.1f}"),
                ("road_user_low_snr_pct", "road users below SNR 10 (%)", lambda v: f"{v:.0f}"))
SUMMARY_ROWS = (("mtf50_cy_px", "MTF50 sRGB (cy/px)", lambda v: f"{v:.3f}"),
                ("mtf50_sd_cy_px", "MTF50 sRGB ± 1σ (cy/px)", lambda v: f"{v:.3f}"),
                ("mtf50_lp_mm", "MTF50 sRGB (lp/mm)", lambda v: f"{v:.1f}"),
                ("mtf_nyquist", "MTF at Nyquist", lambda v: f"{v:.3f}"),
                ("snr_at_10cd_m2_10ms_dB", "SNR, 10 cd/m² for 10 ms (dB)", lambda v: f"{v:.1f}"),
                ("snr_at_10pct_full_well_dB", "SNR at 10 % of saturation (dB)", lambda v: f"{v:.1f}"),
                ("noise_equivalent_exposure_lux_s", "noise-equivalent exposure (mlx·s)", lambda v: f"{1e3 * v:.3g}"),
                ("saturation_e", "electrons at saturation (e⁻)", lambda v: f"{v:.4g}"),
                ("dynamic_range_dB", "sensor dynamic range (dB)", lambda v: f"{v:.1f}"),
                ("delta_e_held_out_mean", "ΔE2000 mean, held-out patches", lambda v: f"{v:.2f}"),
                ("delta_e_held_out_max", "ΔE2000 max, held-out patches", lambda v: f"{v:.2f}"),
                ("delta_e_mean", "ΔE2000 mean, fitted (training) patches", lambda v: f"{v:.2f}"),
                ("delta_e_max", "ΔE2000 max, fitted (training) patches", lambda v: f"{v:.2f}"))


def flat_readouts(readouts: dict | None) -> dict:
    """Read-outs with the per-channel electrons as rows of their own ('electrons R', …)."""
    if not readouts:
        return {}
    out = {k: v for k, v in readouts.items() if k != "mean_electrons"}
    out.update({f"electrons {ch}": v for ch, v in readouts.get("mean_electrons", {}).items()})
    return out


def measure_and_draw(project, pinned: dict | None, chart_px: tuple[int, int], chart: str, label: str | None):
    """metrics.charts.measure_and_draw in the window's side process; this (worker) thread only waits."""
    from workbench.metrics.charts import measure_and_draw as job
    return side_process.run(job, project, pinned, chart_px, chart, label)


def draw_ab(fig, a: np.ndarray, b: np.ndarray, labels: tuple[str, str] = ("A", "B")) -> None:
    """A | B | B − A of two sRGB frames, titled by `labels`; the difference (luminance) on a
    symmetric, shared scale. A figure under 2.4 times as wide as high (a docked panel) puts the
    difference below A and B."""
    w_in, h_in = fig.get_size_inches()
    layout = [["a", "b", "d"]] if w_in > 2.4 * h_in else [["a", "b"], ["d", "d"]]
    named = fig.subplot_mosaic(layout)
    axes = [named["a"], named["b"], named["d"]]
    for ax, image, label in zip(axes, (a, b), labels):
        ax.imshow(np.clip(image, 0, 1))
        ax.set_title(label, fontsize=8)
    if a.shape == b.shape:
        w = np.array([0.2126, 0.7152, 0.0722], np.float32)
        diff = (np.asarray(b, np.float32) - np.asarray(a, np.float32)) @ w
        lim = max(float(np.percentile(np.abs(diff), 99.5)), 1e-3)
        im = axes[2].imshow(diff, cmap="RdBu_r", vmin=-lim, vmax=lim)
        fig.colorbar(im, ax=axes[2], fraction=0.046, shrink=0.8)
        axes[2].set_title("B − A (sRGB luminance)", fontsize=8)
    else:
        axes[2].text(0.5, 0.5, f"sizes differ:\n{a.shape[1]}×{a.shape[0]} vs {b.shape[1]}×{b.shape[0]}",
                     ha="center", va="center", fontsize=8, transform=axes[2].transAxes)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])


class MetricsPanel(QWidget):
    """Read-outs and measurements of the current design, A/B against a pinned one.

    measured(dict) when a measurement of the current project arrives (with 'seconds')."""

    edited = Signal(str, dict)          # the editor protocol; this panel edits nothing
    measured = Signal(dict)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._project = None
        self._frame = None
        self._readouts: dict = {}
        self.metrics: dict | None = None
        self._measured = None                        # the project self.metrics belongs to
        self.pinned: dict | None = None              # {'metrics', 'readouts', 'srgb', 'project'}
        self._worker = None
        self._queued = None
        self._ab_worker = None
        self._ab_queued = False
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(DEBOUNCE_MS)
        self._timer.timeout.connect(lambda: self.measure())
        self._started = 0.0
        self._elapsed = QTimer(self)               # the status counts the seconds of a running measurement
        self._elapsed.setInterval(ELAPSED_STEP_MS)
        self._elapsed.timeout.connect(self._show_elapsed)

        self.live = QCheckBox("measure after every edit", self)
        self.live.setChecked(True)
        self.live.setToolTip("re-measure MTF, SNR and ΔE on test charts after each edit (a few seconds, "
                             "on a worker thread)")
        self.measure_button = QPushButton("Measure now", self)
        self.measure_button.clicked.connect(lambda: self.measure(force=True))
        self.pin_button = QPushButton("Pin as A", self)
        self.pin_button.setToolTip("keep the current design as A; edit to make B and compare")
        self.pin_button.clicked.connect(self.pin)
        self.clear_button = QPushButton("Clear A", self)
        self.clear_button.clicked.connect(self.clear_pin)
        self.status = QLabel("no measurement yet", self)
        self.status.setWordWrap(True)
        self.changes = QLabel(self)                 # what differs between A and B (project_differences)
        self.changes.setWordWrap(True)
        self.changes.setVisible(False)
        self.table = QTableWidget(0, len(COLUMNS), self)
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.table.setWordWrap(True)
        self.table.verticalHeader().hide()
        self.table.verticalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)     # names wrap; the values keep their width
        self.chart_views = {key: BackgroundChart(f"{CHART_TITLES[key]} appears here after a measurement", self)
                            for key in CHART_TABS}
        self.ab = ChartImage("Pin a design as A, then edit: A, B and their difference appear here", self)
        charts = QTabWidget(self)
        for key, title in CHART_TABS.items():
            charts.addTab(self.chart_views[key], title)
        charts.addTab(self.ab, "A | B | B − A")
        self.charts = charts

        buttons = QHBoxLayout()
        for w in (self.measure_button, self.pin_button, self.clear_button):
            buttons.addWidget(w)
        buttons.addStretch(1)
        split = QSplitter(Qt.Orientation.Vertical, self)
        split.addWidget(self.table)
        split.addWidget(charts)
        split.setStretchFactor(1, 2)
        lay = QVBoxLayout(self)
        lay.addWidget(self.live)
        lay.addLayout(buttons)
        lay.addWidget(self.status)
        lay.addWidget(self.changes)
        lay.addWidget(split, 1)
        self._update_buttons()
        self._fill_table()

    # -------------------------------------------------------------------------------- inputs
    def set_project(self, project) -> None:
        """A new current design: re-measure it (debounced) when live measuring is on and the panel
        is on screen (a hidden panel measures when it is shown: no CPU for numbers nobody sees)."""
        changed = project is not self._project and project != self._project
        self._project = project
        if changed:
            self._show_changes()
        if changed and self.live.isChecked() and self.on_screen():
            self._timer.start()
        self._update_buttons()

    def labels(self) -> tuple[str, str]:
        """The names of A and B on the charts: by what differs (project.difference_labels)."""
        from workbench.project import difference_labels
        a = None if self.pinned is None else self.pinned.get("design")
        if a is None or self._project is None:
            return "A", "B"
        return difference_labels(a, self._project)

    def _show_changes(self) -> None:
        """Above the A/B table: the parameters in which the current design B differs from the pinned A."""
        from workbench.project import project_differences
        a = None if self.pinned is None else self.pinned.get("design")
        if a is None or self._project is None:
            self.changes.setVisible(False)
            return
        diff = project_differences(a, self._project)
        text = ("A → B: " + "; ".join(f"{f} {va} → {vb}" for f, va, vb in diff[:MAX_CHANGES_SHOWN])
                + (f"; … {len(diff) - MAX_CHANGES_SHOWN} more" if len(diff) > MAX_CHANGES_SHOWN else "")
                if diff else "B is the pinned design A (no parameter differs)")
        self.changes.setText(text)
        self.changes.setToolTip("\n".join(f"{f}: {va} → {vb}" for f, va, vb in diff))
        self.changes.setVisible(True)

    def on_screen(self) -> bool:
        """Whether any of the panel can be seen: Qt keeps the widgets of a dock's hidden tabs
        'visible', parked outside the window, so isVisible() alone is true for every tab."""
        return self.isVisible() and not self.visibleRegion().isEmpty()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        # once laid out; with self as context, a panel deleted first never gets the call
        QTimer.singleShot(0, self, lambda: self.set_on_screen(self.on_screen()))

    def set_on_screen(self, shown: bool) -> None:
        """The dock came on screen (its tab chosen, the dock shown or floated) or left it: a design
        not yet measured is measured now."""
        if shown and self.live.isChecked() and self._project is not None and self._measured != self._project:
            self._timer.start()

    def set_frame(self, frame) -> None:
        """A new frame of the current design: its read-outs into the table, A/B strip redrawn."""
        self._frame = frame
        self._readouts = flat_readouts(getattr(frame, "readouts", None))
        self._fill_table()
        if self.pinned is not None:
            self._draw_ab()

    # ------------------------------------------------------------------------------- A and B
    def pin(self) -> None:
        """Keep the current design's measurements, read-outs and sRGB frame as A."""
        if self.metrics is None and self._frame is None:
            self.status.setText("nothing to pin yet: wait for a frame or a measurement")
            return
        self.pinned = {"metrics": self.metrics, "readouts": dict(self._readouts),
                       "srgb": None if self._frame is None else np.array(self._frame.srgb),
                       "project": getattr(self._project, "name", "A"), "design": self._project}
        self.status.setText(f"pinned '{self.pinned['project']}' as A: edit the design to compare")
        self._fill_table()
        self._update_buttons()
        self._show_changes()
        self._draw_ab()

    def clear_pin(self) -> None:
        self.pinned = None
        self._show_changes()
        self.ab.clear()
        self.ab.setText("Pin a design as A, then edit: A, B and their difference appear here")
        self._fill_table()
        self._update_buttons()

    def _draw_ab(self) -> None:
        if self.pinned is None or self.pinned["srgb"] is None or self._frame is None:
            return
        if self._ab_worker is not None:
            self._ab_queued = True
            return
        a, b, labels = self.pinned["srgb"], np.array(self._frame.srgb), self.labels()
        page = self.ab if self.ab.isVisible() else self.chart_views["mtf"]   # a hidden tab has no size of its own yet
        self._ab_worker = create_worker(render_rgba, lambda fig: draw_ab(fig, a, b, labels), *page.size_px(),
                                        _start_thread=False, _ignore_errors=True)
        self._ab_worker.returned.connect(self.ab.show_rgba)
        self._ab_worker.finished.connect(self._ab_finished)
        self._ab_worker.start()

    def _ab_finished(self) -> None:
        self._ab_worker = None
        if self._ab_queued:
            self._ab_queued = False
            self._draw_ab()

    # ---------------------------------------------------------------------------- measuring
    def measure(self, force: bool = False) -> None:
        """Measure the current design on a worker (queued behind a running one); a design already
        measured is measured again only when forced (Measure now)."""
        if self._project is None:
            return
        if not force and self.metrics is not None and self._measured == self._project:
            return
        if self._worker is not None:
            self._queued = self._project
            return
        project = self._project
        label_a, label_b = self.labels()
        pinned = None if self.pinned is None or self.pinned["metrics"] is None else {**self.pinned["metrics"],
                                                                                    "label": label_a}
        chart = self.front_chart()
        self._worker = create_worker(measure_and_draw, project, pinned, self.chart_views[chart].size_px(), chart,
                                     None if pinned is None else label_b, _start_thread=False, _ignore_errors=True)
        self._worker.returned.connect(
            lambda result, p=project: self._returned(p, result, chart, pinned, None if pinned is None else label_b))
        self._worker.errored.connect(self._errored)
        self._worker.finished.connect(self._finished)
        self._started = time.perf_counter()
        self._show_elapsed()
        self._elapsed.start()
        self._worker.start()
        self._update_buttons()

    def _show_elapsed(self) -> None:
        """The running measurement's status: what is measured and for how long so far."""
        if self._worker is not None and self._project is not None:
            self.status.setText(f"measuring {self._project.name} on test charts… "
                                f"{time.perf_counter() - self._started:.0f} s")

    def front_chart(self) -> str:
        """The chart tab in front (the MTF's when the A | B strip is): drawn with the measurement."""
        return next((key for key, view in self.chart_views.items() if self.charts.currentWidget() is view), "mtf")

    def _returned(self, project, result, chart: str, pinned: dict | None, label: str | None) -> None:
        metrics, rgba, seconds = result
        if project is not self._project and project != self._project:
            return                                    # an older design; the queued run follows
        self.metrics = {**metrics, "seconds": seconds}
        self._measured = project
        designs = [metrics] if pinned is None else [pinned, {**metrics, "label": label}]
        for key, view in self.chart_views.items():    # the others are drawn when their tab is shown
            draw = functools.partial(draw_chart, designs=designs, chart=key)
            if key == chart:
                view.set_image(draw, rgba)
            else:
                view.set_draw(draw)
        self.status.setText(f"measured {project.name} in {seconds:.1f} s (side process)")
        self._fill_table()
        self.measured.emit(self.metrics)

    def _errored(self, exc: Exception) -> None:
        self.status.setText(f"measurement failed: {exc}")

    def _finished(self) -> None:
        self._elapsed.stop()
        self._worker = None
        queued, self._queued = self._queued, None
        if queued is not None:
            self.measure()
        self._update_buttons()

    def _update_buttons(self) -> None:
        self.measure_button.setEnabled(self._project is not None)
        self.pin_button.setEnabled(self.metrics is not None or self._frame is not None)
        self.clear_button.setEnabled(self.pinned is not None)

    # -------------------------------------------------------------------------------- table
    def rows(self) -> list[tuple]:
        """(label, format, A value, B value, verdict) of every row the table shows (A None when nothing
        is pinned; the verdict '' for a frame read-out)."""
        from workbench.metrics.study import compare_verdict
        a_read = self.pinned["readouts"] if self.pinned else {}
        a_sum = (self.pinned["metrics"] or {}).get("summary", {}) if self.pinned else {}
        b_sum = (self.metrics or {}).get("summary", {})
        keys = list(READOUT_ROWS) + [(k, k, lambda v: f"{v:.4g}") for k in self._readouts
                                     if k.startswith("electrons ")]
        out = [(label, fmt, a_read.get(k), self._readouts.get(k), "") for k, label, fmt in keys
               if k in self._readouts or k in a_read]
        a_sigma = (self.pinned["metrics"] or {}).get("uncertainty", {}) if self.pinned else {}
        b_sigma = (self.metrics or {}).get("uncertainty", {})
        out += [(label, fmt, a_sum.get(k), b_sum.get(k),
                 compare_verdict(k, a_sum.get(k), b_sum.get(k), a_sigma.get(k), b_sigma.get(k)))
                for k, label, fmt in SUMMARY_ROWS if k in b_sum or k in a_sum]
        return out

    def _fill_table(self) -> None:
        rows = self.rows()
        self.table.setRowCount(len(rows))
        for i, (label, fmt, a, b, verdict) in enumerate(rows):
            self.table.setItem(i, 0, QTableWidgetItem(label))
            change = None
            if isinstance(a, (int, float)) and isinstance(b, (int, float)):
                change = b - a
            for j, v in enumerate((a, b, change), start=1):
                text = "—" if v is None else (fmt(v) if not (j == 3 and isinstance(v, int)) else f"{v:+d}")
                if j == 3 and v is not None and isinstance(v, float):
                    text = ("+" if v >= 0 else "") + fmt(v)
                item = QTableWidgetItem(text)
                item.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                self.table.setItem(i, j, item)
            item = QTableWidgetItem(verdict if len(verdict) <= MAX_VERDICT_CHARS
                                    else verdict[:MAX_VERDICT_CHARS - 1] + "…")
            item.setToolTip(verdict)
            self.table.setItem(i, 4, item)
        label_a, label_b = self.labels()
        for column, text, tip in ((1, "A", label_a), (2, "B" if self.pinned else "current", label_b)):
            self.table.horizontalHeaderItem(column).setText(text)
            self.table.horizontalHeaderItem(column).setToolTip(tip)
        for column in (1, 3, 4):
            self.table.setColumnHidden(column, self.pinned is None)

    def shutdown(self) -> None:
        """The window is closing: no new measurement starts (the window stops the side process)."""
        self._timer.stop()
        self._queued = None
        self._ab_queued = False
