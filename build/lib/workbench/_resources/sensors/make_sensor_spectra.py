"""Generate the sensor spectral data in this folder (run: python resources/sensors/make_sensor_spectra.py).

Smooth analytic models, 350–1100 nm in 5 nm steps, written as CSV (first column wavelength_nm,
then one column per curve). They are generic shapes with the features real parts have, not the
data of any one product:

* bayer_dye_filters.csv — R, G, B pigment/dye colour-filter transmittances with the NIR leak of
  dye filters (all three become transparent again beyond ~800 nm), plus C (clear, as in RCCC/RCCB)
  and W (white resin of RGBW; slightly lower and with a UV edge).
* silicon_photodiode_qe.csv — photodiode QE of a front-side silicon pixel: optical-stack
  transmission × (1 − e^(−αd)) collection in a 5 µm epi layer × e^(−α·0.1 µm) surface loss,
  with the absorption coefficient α(λ) of crystalline silicon at 300 K (tabulated values from
  M. A. Green, Sol. Energy Mater. Sol. Cells 92 (2008) 1305, interpolated in log α).
  Peaks ≈0.65 near 500–550 nm, 0.60 at 600 nm, ≈0.19 at 850 nm, →0 at 1100 nm.
* ir_cut_650.csv — IR-cut (hot-mirror) filter: passes 400–650 nm (~0.95), cut by 700 nm.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
WAVELENGTHS_NM = np.arange(350.0, 1100.0 + 1e-9, 5.0)

# Silicon absorption coefficient (1/cm) at 300 K, Green 2008 (selected wavelengths, nm).
_SI_ALPHA_WL_NM = np.array([350, 370, 380, 390, 400, 450, 500, 550, 600, 650, 700, 750, 800,
                            850, 900, 950, 1000, 1050, 1100], dtype=float)
_SI_ALPHA_PER_CM = np.array([1.04e6, 6.7e5, 2.9e5, 1.5e5, 9.52e4, 2.55e4, 1.11e4, 6.39e3, 4.14e3,
                             2.81e3, 1.90e3, 1.30e3, 8.50e2, 5.35e2, 3.06e2, 1.57e2, 6.4e1, 1.63e1,
                             3.5e0])


def _logistic(x: np.ndarray, centre: float, width: float) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-(x - centre) / width))


def _gauss(x: np.ndarray, centre: float, sigma: float) -> np.ndarray:
    return np.exp(-0.5 * ((x - centre) / sigma) ** 2)


def colour_filters(wl: np.ndarray) -> dict[str, np.ndarray]:
    """Bayer dye filters with NIR leak, clear and white."""
    uv = _logistic(wl, 385.0, 8.0)          # resin/dye absorption in the near UV
    nir = _logistic(wl, 800.0, 22.0)         # dyes turn transparent in the NIR
    red = 0.92 * _logistic(wl, 592.0, 11.0) + 0.04 * _gauss(wl, 420.0, 25.0)
    green = 0.86 * _gauss(wl, 535.0, 38.0) + 0.05 * _logistic(wl, 620.0, 30.0) * (1 - nir)
    blue = 0.88 * _gauss(wl, 455.0, 32.0) + 0.03 * _logistic(wl, 560.0, 40.0) * (1 - nir)
    out = {
        "R": red * uv,
        "G": (green * (1 - nir) + 0.90 * nir) * uv,
        "B": (blue * (1 - nir) + 0.90 * nir) * uv,
        "C": 0.98 * _logistic(wl, 365.0, 6.0),
        "W": 0.95 * _logistic(wl, 380.0, 8.0),
    }
    return {k: np.clip(v, 0.0, 1.0) for k, v in out.items()}


def silicon_qe(wl: np.ndarray, epi_um: float = 5.0, dead_um: float = 0.1,
               stack_transmission: float = 0.72) -> np.ndarray:
    """Photodiode QE from the silicon absorption depth (see module docstring)."""
    log_alpha = np.interp(wl, _SI_ALPHA_WL_NM, np.log(_SI_ALPHA_PER_CM))
    alpha_per_um = np.exp(log_alpha) * 1e-4
    qe = stack_transmission * np.exp(-alpha_per_um * dead_um) * (1.0 - np.exp(-alpha_per_um * epi_um))
    qe[wl >= 1100.0] = 0.0                   # below the silicon band gap (1.12 eV ≈ 1107 nm)
    return qe


def ir_cut(wl: np.ndarray) -> np.ndarray:
    """Hot-mirror IR-cut filter: 50 % at 675 nm, < 1 % by 700 nm, UV edge at 390 nm."""
    return 0.95 * (1.0 - _logistic(wl, 675.0, 5.0)) * _logistic(wl, 390.0, 5.0)


def _write(name: str, columns: dict[str, np.ndarray]) -> None:
    header = "wavelength_nm," + ",".join(columns)
    data = np.column_stack([WAVELENGTHS_NM, *columns.values()])
    np.savetxt(HERE / name, data, delimiter=",", header=header, comments="", fmt="%.6g")


def main() -> None:
    wl = WAVELENGTHS_NM
    _write("bayer_dye_filters.csv", colour_filters(wl))
    _write("silicon_photodiode_qe.csv", {"QE": silicon_qe(wl)})
    _write("ir_cut_650.csv", {"IRCUT": ir_cut(wl)})


if __name__ == "__main__":
    main()
