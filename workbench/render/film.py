"""Film spectral response functions (SRFs) and their calibration to photons/s/sr/m²/nm.

Mitsuba's specfilm channel j is ∫ L(λ) s_j(λ) dλ with L in W/m²/sr/nm — not divided by ∫s_j.
We hand Mitsuba s'_j(λ) = s_j(λ) · λ/λ_j (λ_j: the centroid of s_j), so that
∫ L s'_j dλ · λ_j/(hc) = ∫ L_photons(λ) s_j(λ) dλ exactly: the photon conversion happens per
wavelength, not at the band centre. SRFs are piecewise linear between their samples, 0 outside.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import InvalidValueError
from workbench.units import photon_energy_J

EDGE_RAMP_NM = 0.1   # width of the linear ramp that stands in for a box band's sharp edge


@dataclass
class FilmSRFs:
    """K response curves on a common wavelength grid and how channels map back to a spectrum.

    wavelengths_nm: M sample wavelengths (increasing); responses: K×M unitless, ≥ 0.
    kind: 'bands', 'basis' or 'sensor'. output_wavelengths_nm: the wavelengths of the result.
    reconstruction: N_out×K matrix taking ∫ L_photons s_k dλ (per channel) to radiance on
    output_wavelengths_nm (photons/s/sr/m²/nm)."""

    wavelengths_nm: np.ndarray
    responses: np.ndarray
    kind: str
    output_wavelengths_nm: np.ndarray
    reconstruction: np.ndarray
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        wl = np.asarray(self.wavelengths_nm, dtype=np.float64)
        r = np.atleast_2d(np.asarray(self.responses, dtype=np.float64))
        if r.shape[1] != wl.size or np.any(np.diff(wl) <= 0):
            raise InvalidValueError(f"film SRFs: responses must be K×M on M increasing wavelengths, got "
                             f"{r.shape} on {wl.size} wavelengths")
        if not np.all(np.isfinite(r)) or np.any(r < 0) or np.any(r.max(axis=1) <= 0):
            raise InvalidValueError("film SRFs: every response must be finite, ≥ 0 and not all zero")
        self.wavelengths_nm, self.responses = wl, r
        if not self.names:
            self.names = [f"ch{k:03d}" for k in range(r.shape[0])]

    @property
    def integrals_nm(self) -> np.ndarray:
        """∫ s_k dλ (nm) of each response (exact for piecewise-linear curves)."""
        return np.trapezoid(self.responses, self.wavelengths_nm, axis=1)

    @property
    def centroids_nm(self) -> np.ndarray:
        """∫ λ s_k dλ / ∫ s_k dλ (nm)."""
        return np.trapezoid(self.responses * self.wavelengths_nm, self.wavelengths_nm, axis=1) / self.integrals_nm

    @property
    def range_nm(self) -> tuple[float, float]:
        """First and last wavelength (nm) where any response is > 0: what spectra must cover."""
        nz = np.nonzero(self.responses.max(axis=0) > 0)[0]
        return float(self.wavelengths_nm[nz[0]]), float(self.wavelengths_nm[nz[-1]])

    def mitsuba_film(self, width: int, height: int) -> dict:
        """A specfilm dict (float32, box filter) whose channels are the photon-weighted SRFs."""
        film = {"type": "specfilm", "width": int(width), "height": int(height),
                "component_format": "float32", "rfilter": {"type": "box"}}
        tilt = self.wavelengths_nm / self.centroids_nm[:, None]
        for k, (name, resp) in enumerate(zip(self.names, self.responses * tilt)):
            nz = np.nonzero(resp > 0)[0]
            lo, hi = max(nz[0] - 1, 0), min(nz[-1] + 1, resp.size - 1)
            pts = list(zip(self.wavelengths_nm[lo:hi + 1].tolist(), resp[lo:hi + 1].tolist()))
            film[f"band_{k:03d}_{name}"] = {"type": "spectrum", "value": pts}
        return film

    def channels_to_photon_integrals(self, channels: np.ndarray) -> np.ndarray:
        """Film output (…×K, W/m²/sr per channel) → ∫ L_photons s_k dλ (photons/s/sr/m²)."""
        return np.asarray(channels, dtype=np.float64) / photon_energy_J(self.centroids_nm)

    def channels_to_radiance(self, channels: np.ndarray) -> np.ndarray:
        """Film output (H×W×K) → radiance on output_wavelengths_nm (photons/s/sr/m²/nm), ≥ 0."""
        out = self.channels_to_photon_integrals(channels) @ self.reconstruction.T
        return np.maximum(out, 0.0)


def box_bands(wavelength_min_nm: float, wavelength_max_nm: float, band_count: int) -> FilmSRFs:
    """`band_count` adjacent equal box bands; output = band-mean radiance at the band centres
    (box_bands_between on equally spaced edges)."""
    return box_bands_between(np.linspace(wavelength_min_nm, wavelength_max_nm, band_count + 1))


def box_bands_between(edges_nm: np.ndarray) -> FilmSRFs:
    """Adjacent box bands between consecutive `edges_nm` (increasing); output = band-mean
    radiance at the band centres.

    Adjacent bands share linear edge ramps (EDGE_RAMP_NM wide, centred on the edge), so the
    SRFs sum to 1 across the range and each integrates to exactly the band width."""
    edges = np.asarray(edges_nm, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise InvalidValueError(f"box bands need ≥ 2 increasing edges, got {np.round(edges, 3).tolist()}")
    h = EDGE_RAMP_NM / 2
    wl = np.unique(np.concatenate([edges - h, edges + h]))
    resp = np.stack([np.interp(wl, [a - h, a + h, b - h, b + h], [0, 1, 1, 0], left=0, right=0)
                     for a, b in zip(edges[:-1], edges[1:])])
    width = np.diff(edges)
    centres = (edges[:-1] + edges[1:]) / 2
    return FilmSRFs(wl, resp, "bands", centres, np.diag(1.0 / width),
                    names=[f"{c:.0f}nm" for c in centres])


def raised_cosine_basis(wavelength_min_nm: float, wavelength_max_nm: float, basis_count: int,
                        output_step_nm: float = 10.0, samples_per_node: int = 16) -> FilmSRFs:
    """`basis_count` cos² bumps (a partition of unity) over the range; spectrum by projection.

    Channels are b_k = ∫ L φ_k dλ; the spectrum L ≈ Σ c_j φ_j with G c = b, G_kj = ∫ φ_k φ_j dλ
    (least-squares projection onto the basis), evaluated on the output grid. Negative lobes
    from the projection (sharp spectral features) are clipped to 0 by channels_to_radiance."""
    nodes = np.linspace(wavelength_min_nm, wavelength_max_nm, basis_count)
    step = nodes[1] - nodes[0]
    wl = np.linspace(wavelength_min_nm, wavelength_max_nm, (basis_count - 1) * samples_per_node + 1)
    phi = _cos2(wl, nodes, step)
    gram = np.trapezoid(phi[:, None, :] * phi[None, :, :], wl, axis=2)
    n_out = int(np.floor((wavelength_max_nm - wavelength_min_nm) / output_step_nm + 1e-9)) + 1
    out_wl = wavelength_min_nm + output_step_nm * np.arange(n_out)
    recon = _cos2(out_wl, nodes, step).T @ np.linalg.inv(gram)
    return FilmSRFs(wl, phi, "basis", out_wl, recon, names=[f"phi{n:.0f}nm" for n in nodes])


def _cos2(wl: np.ndarray, nodes: np.ndarray, step: float) -> np.ndarray:
    x = (np.asarray(wl)[None, :] - nodes[:, None]) / step
    return np.where(np.abs(x) < 1, np.cos(np.pi * x / 2) ** 2, 0.0)


def sensor_channels(wavelengths_nm: np.ndarray, qe: np.ndarray, names: list[str] | None = None) -> FilmSRFs:
    """The sensor's K channel QE curves (K×Nλ) as film SRFs.

    The result is not a spectrum: channel k of the output is the QE_k-weighted mean radiance
    ∫ L_photons QE_k dλ / ∫ QE_k dλ (photons/s/sr/m²/nm), reported at the channel centroid.
    A sensor turns it into electrons with that mean × ∫ QE_k dλ (film.integrals_nm)."""
    srf = FilmSRFs(wavelengths_nm, qe, "sensor", np.zeros(1), np.zeros((1, 1)), names=names or [])
    srf.output_wavelengths_nm = srf.centroids_nm
    srf.reconstruction = np.diag(1.0 / srf.integrals_nm)
    return srf


def sensor_wavelength_range(wavelengths_nm: np.ndarray, qe: np.ndarray,
                            rel_threshold: float = 0.01) -> tuple[float, float]:
    """Range (nm) where any channel's QE exceeds rel_threshold × its peak: model only that."""
    q = np.atleast_2d(np.asarray(qe, dtype=np.float64))
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    live = np.nonzero(np.any(q > rel_threshold * q.max(axis=1, keepdims=True), axis=0))[0]
    if live.size == 0:
        raise InvalidValueError("sensor QE is zero everywhere: cannot choose a wavelength range")
    return float(wl[live[0]]), float(wl[live[-1]])
