"""The sensor's charts (matplotlib, Qt-free): effective channel QE with the curves it is made of."""
from __future__ import annotations

import numpy as np

from workbench.sensor.cfa import cfa_layout, channel_qe
from workbench.sensor.params import SensorParams
from workbench.spectra import load_spectrum_csv

CHANNEL_COLOURS = {"R": "#d62728", "G": "#2ca02c", "B": "#1f77b4", "C": "#b0b0b0", "W": "#f2f2f2",
                   "M": "#808080"}
QE_WAVELENGTHS_NM = np.arange(350.0, 1101.0, 5.0)


def draw_qe(fig, params: SensorParams, wavelengths_nm: np.ndarray = QE_WAVELENGTHS_NM) -> None:
    """Effective QE per CFA channel (solid), the colour filters (dotted), the photodiode QE and the
    IR-cut transmittance (dashed)."""
    ax = fig.add_subplot()
    _, names = cfa_layout(params.cfa_pattern)
    qe = channel_qe(params, wavelengths_nm)
    for k, ch in enumerate(names):
        ax.plot(wavelengths_nm, qe[:, k], color=CHANNEL_COLOURS[ch] if ch != "W" else "k", label=ch)
    if params.filter_file is not None:
        filters, filter_names = load_spectrum_csv(params.filter_file, wavelengths_nm)
        for ch in names:
            if ch in filter_names:
                ax.plot(wavelengths_nm, filters[:, filter_names.index(ch)], ":", lw=0.9,
                        color=CHANNEL_COLOURS[ch] if ch != "W" else "k", label=f"{ch} filter")
    for name, label in ((params.photodiode_qe_file, "photodiode QE"), (params.ir_cut_file, "IR cut")):
        if name is not None:
            ax.plot(wavelengths_nm, load_spectrum_csv(name, wavelengths_nm)[0][:, 0], "--", lw=0.8,
                    color="0.4" if label == "IR cut" else "0.7", label=label)
    ax.set(xlabel="wavelength (nm)", ylabel="QE / transmittance", ylim=(0, 1.02),
           title=f"{params.cfa_pattern}: effective channel QE")
    ax.legend(fontsize=6, loc="upper right", ncol=2)
