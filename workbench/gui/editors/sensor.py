"""Sensor editor: every SensorParams field (form generator), presets, the CFA tile, the QE curves
and an EMVA 1288 characterisation; the charts and the characterisation run in the window's side
process (gui.side_process). Its summary says which exposure rule the project's frames use and
which its exposure experiments use (they read the project's experiment block, not the sensor's)."""
from __future__ import annotations

import functools

from PySide6.QtCore import QRectF, QSize, Qt, Signal
from PySide6.QtGui import QColor, QPainter
from PySide6.QtWidgets import (QComboBox, QHBoxLayout, QLabel, QPushButton, QScrollArea, QTabWidget,
                               QVBoxLayout, QWidget)
from superqt.utils import create_worker

from workbench.gui import side_process
from workbench.gui.forms import ParamsForm
from workbench.gui.mplcanvas import BackgroundChart
from workbench.metrics.charts import characterise_and_draw
from workbench.resource_dir import RESOURCES
from workbench.sensor.auto_exposure import describe_exposure, exposure_rule
from workbench.sensor.cfa import cfa_layout
from workbench.sensor.charts import CHANNEL_COLOURS, draw_qe
from workbench.sensor.emva import draw_photon_transfer
from workbench.sensor.params import SENSOR_PRESETS, SensorParams


def spectrum_files() -> list[str]:
    """Spectral CSVs shipped in resources/sensors/ (names relative to resources/)."""
    return sorted(f"sensors/{p.name}" for p in (RESOURCES / "sensors").glob("*.csv"))


def qe_inputs(params: SensorParams) -> tuple:
    """The fields the QE chart depends on: a change elsewhere (gain, exposure, noise) keeps the chart."""
    return (params.cfa_pattern, params.filter_file, params.photodiode_qe_file, params.ir_cut_file)


def emva_summary(result: dict) -> str:
    """The measured figures, each beside the configured one, and the measurement's notes (a read
    noise hidden by the ADC's quantisation is measured through a finer one, or is a lower bound,
    marked ≥)."""
    conf = result["configured"]
    bound = "≥ " if result.get("read_noise_is_lower_bound") else ""
    lines = [f"K {result['conversion_gain_uV_per_e']:.3g} µV/e⁻ (configured {conf['conversion_gain_uV_per_e']:.3g}), "
             f"read noise {bound}{result['read_noise_e']:.3g} e⁻ (configured {conf['read_noise_e']:.3g}), "
             f"dark current {result['dark_current_e_per_s']:.3g} e⁻/s (configured "
             f"{conf['dark_current_e_per_s']:.3g}), saturation {result['saturation_capacity_e']:,.0f} e⁻, "
             f"DR {result['dynamic_range_dB']:.1f} dB"]
    lines += [f"Note: {note}" for note in result["notes"]]
    return "\n".join(lines)


class CfaTile(QWidget):
    """Two periods of the CFA tile drawn as coloured pixels with their channel letters."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.pattern = "GRBG"
        self.setMinimumSize(QSize(72, 72))
        self.setToolTip("CFA tile (two periods), read row by row")

    def set_pattern(self, pattern: str) -> None:
        self.pattern = pattern
        self.update()

    def paintEvent(self, _event) -> None:
        tile, names = cfa_layout(self.pattern)
        th, tw = tile.shape
        n = 2 * th
        side = min(self.width(), self.height()) / n
        p = QPainter(self)
        for r in range(n):
            for c in range(n):
                ch = names[tile[r % th, c % tw]]
                rect = QRectF(c * side, r * side, side, side)
                p.fillRect(rect, QColor(CHANNEL_COLOURS[ch]))
                p.setPen(QColor("black"))
                p.drawRect(rect)
                p.drawText(rect, Qt.AlignmentFlag.AlignCenter, ch)
        p.end()


class SensorEditor(QWidget):
    """edited("sensor", {field: value}) for every accepted change, presets included."""

    edited = Signal(str, dict)
    emva_finished = Signal(dict)

    def __init__(self, parent=None):
        super().__init__(parent)
        self._params = SensorParams()
        self._experiment = None             # the project's ExperimentParams: the experiments' exposure rule
        self._seed = 0
        self._worker = None
        self._qe_key: tuple | None = None
        self.emva_result: dict | None = None

        self.presets = QComboBox(self)
        self.presets.addItems(list(SENSOR_PRESETS))
        self.presets.setToolTip("sensor presets (workbench.sensor.params.SENSOR_PRESETS)")
        apply_preset = QPushButton("Apply preset", self)
        apply_preset.clicked.connect(lambda: self.apply_preset(self.presets.currentText()))
        self.cfa = CfaTile(self)
        self.summary = QLabel(self)
        self.summary.setWordWrap(True)
        header = QHBoxLayout()
        left = QVBoxLayout()
        row = QHBoxLayout()
        row.addWidget(QLabel("Preset:", self))
        row.addWidget(self.presets, 1)
        row.addWidget(apply_preset)
        left.addLayout(row)
        left.addWidget(self.summary)
        header.addLayout(left, 1)
        header.addWidget(self.cfa)

        files = spectrum_files()
        self.form = ParamsForm(SensorParams, self, choices={
            "filter_file": files, "photodiode_qe_file": files, "ir_cut_file": files})
        self.form.edited.connect(self._form_edited)
        scroll = QScrollArea(self)
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.form)

        self.qe_chart = BackgroundChart("the sensor's effective channel QE", self)
        self.emva_button = QPushButton("Characterise (EMVA 1288)", self)
        self.emva_button.setToolTip("photon-transfer measurement of this sensor in a background process")
        self.emva_button.clicked.connect(self.run_emva)
        self.emva_status = QLabel("not run", self)
        self.emva_status.setWordWrap(True)
        self.emva_chart = BackgroundChart("Characterise: the photon-transfer curve and SNR against signal "
                                          "appear here", self)
        emva = QWidget(self)
        ev = QVBoxLayout(emva)
        top = QHBoxLayout()
        top.addWidget(self.emva_button)
        top.addWidget(self.emva_status, 1)
        ev.addLayout(top)
        ev.addWidget(self.emva_chart, 1)

        self.tabs = QTabWidget(self)
        self.tabs.addTab(scroll, "Parameters")
        self.tabs.addTab(self.qe_chart, "QE curves")
        self.tabs.addTab(emva, "EMVA 1288")
        lay = QVBoxLayout(self)
        lay.addLayout(header)
        lay.addWidget(self.tabs, 1)
        self._refresh()

    # ----------------------------------------------------------------------------------------
    def set_project(self, project) -> None:
        """Show the project's sensor; emits nothing."""
        self._seed = project.seed
        if project.sensor != self._params or project.experiment != self._experiment:
            self._experiment = project.experiment
            if project.sensor != self._params:
                self._params = project.sensor
                self.form.set_params(project.sensor)
            self._refresh()

    def _refresh(self) -> None:
        p = self._params
        self.cfa.set_pattern(p.cfa_pattern)
        exposure = f"Exposure: {describe_exposure(p)}"
        if self._experiment is not None:
            rule = exposure_rule(self._experiment.auto_exposure_method, self._experiment.auto_exposure_level)
            exposure += f"; exposure experiments: {rule}, × 2^EV"
        self.summary.setText(f"{p.cols}×{p.rows} px, {p.pixel_pitch_um:g} µm; full well {p.full_well_e:,.0f} e⁻, "
                             f"read noise {p.read_noise_e:.3g} e⁻, {p.bit_depth or 'analog'}"
                             f"{' bit' if p.bit_depth else ''}\n{exposure}")
        if qe_inputs(p) != self._qe_key:
            self._qe_key = qe_inputs(p)
            self.qe_chart.set_draw(functools.partial(draw_qe, params=p))

    def _form_edited(self, changes: dict) -> None:
        self._params = self.form.params()
        self._refresh()
        self.edited.emit("sensor", changes)

    def apply_preset(self, name: str) -> None:
        """Emit the fields in which preset `name` differs from the shown sensor (one edit)."""
        preset = SENSOR_PRESETS[name].model_dump()
        current = self._params.model_dump()
        changes = {k: v for k, v in preset.items() if current[k] != v}
        if changes:
            self._params = SENSOR_PRESETS[name]
            self.form.set_params(self._params)
            self._refresh()
            self.edited.emit("sensor", changes)

    # ----------------------------------------------------------------------------------------
    def run_emva(self) -> None:
        """Characterise the shown sensor in the window's side process (a worker thread waits for it);
        the result and its chart appear when it returns."""
        if self._worker is not None:
            return
        params = self._params
        if params.noise_flag < 1:
            params = params.updated(noise_flag=2)
        self.emva_button.setEnabled(False)
        self.emva_status.setText("measuring the photon-transfer curve…")
        self._worker = create_worker(side_process.run, characterise_and_draw, params, self._seed, 128,
                                     self.emva_chart.size_px(), _start_thread=False, _ignore_errors=True)
        self._worker.returned.connect(self._emva_returned)
        self._worker.errored.connect(self._emva_errored)
        self._worker.finished.connect(self._emva_finished)
        self._worker.start()

    def _emva_returned(self, result_and_chart: tuple) -> None:
        result, rgba = result_and_chart
        self.emva_result = result
        self.emva_status.setText(emva_summary(result))
        self.emva_chart.set_image(functools.partial(draw_photon_transfer, result), rgba)
        self.emva_finished.emit(result)

    def _emva_errored(self, exc: Exception) -> None:
        self.emva_status.setText(f"EMVA characterisation failed: {exc}")

    def _emva_finished(self) -> None:
        self._worker = None
        self.emva_button.setEnabled(True)
