"""ISP editor: demosaic, illuminant correction, colour transform and output (form generator), and
the sensor→XYZ colour matrix the ISP fits for the project's sensor, with its condition number."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QLabel, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget

from workbench.gui.forms import ParamsForm
from workbench.isp.color import ColourFit, ColourFitError, fit_sensor_to_xyz
from workbench.isp.demosaic import DEMOSAIC_METHODS
from workbench.isp.params import ISPParams
from workbench.sensor.cfa import cfa_layout, channel_qe


def colour_fit_for(project) -> tuple[ColourFit | None, list[str], str]:
    """(the fit or None, channel names, a one-line explanation) for the project's sensor and ISP."""
    _, names = cfa_layout(project.sensor.cfa_pattern)
    if project.isp.colour_transform == "none":
        return None, names, "colour transform 'none': the sensor channels are shown as linear sRGB"
    wl = project.scene.wavelengths.grid()
    try:
        fit = fit_sensor_to_xyz(channel_qe(project.sensor, wl), wl, project.isp.max_condition)
    except ColourFitError as exc:
        return None, names, f"no colour matrix: {exc}"
    text = (f"condition number {fit.condition:.3g} (limit {project.isp.max_condition:.3g}); "
            f"fit RMS error {fit.residual_rms:.3g} (Y_white = 1)")
    if fit.ridge:
        text += f"; ridge λ = {fit.ridge:.3g}"
    return fit, names, "; ".join([text, *fit.notes])


class ISPEditor(QWidget):
    """edited("isp", {field: value}) for every accepted change."""

    edited = Signal(str, dict)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.form = ParamsForm(ISPParams, self, choices={"demosaic": list(DEMOSAIC_METHODS)})
        self.form.edited.connect(lambda changes: self.edited.emit("isp", changes))
        self.matrix = QTableWidget(0, 3, self)
        self.matrix.setHorizontalHeaderLabels(["X", "Y", "Z"])
        self.matrix.setToolTip("sensor → XYZ matrix (xyz = linear · M), least squares on the 24 Macbeth "
                               "patches under D65")
        self.matrix.setMaximumHeight(150)
        self.fit_text = QLabel(self)
        self.fit_text.setWordWrap(True)
        lay = QVBoxLayout(self)
        lay.addWidget(self.form)
        lay.addWidget(QLabel("<b>Colour matrix</b> (sensor → XYZ)", self))
        lay.addWidget(self.matrix)
        lay.addWidget(self.fit_text)
        lay.addStretch(1)
        self.fit: ColourFit | None = None

    def set_project(self, project) -> None:
        """Show the project's ISP and the colour matrix for its sensor; emits nothing."""
        self.form.set_params(project.isp)
        self.fit, names, text = colour_fit_for(project)
        self.fit_text.setText(text)
        m = np.zeros((0, 3)) if self.fit is None else np.asarray(self.fit.matrix)
        self.matrix.setRowCount(m.shape[0])
        self.matrix.setVerticalHeaderLabels(names[: m.shape[0]])
        for i in range(m.shape[0]):
            for j in range(3):
                self.matrix.setItem(i, j, QTableWidgetItem(f"{m[i, j]:.4f}"))
