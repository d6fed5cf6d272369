"""Exposure-bias sweep of one frame (DESIGN.md §4, the paper's exposure experiment on one image).

From a frame's noise-free pixel signal (e⁻/s per pixel, the pipeline's 'signal' stage), the base
exposure is the experiment's auto-exposure (method and level of `project.experiment`, default
'mean' at 0.4 of the swing); each EV exposes for t = t_auto · 2^EV and runs the ISP. Only the
sensor and ISP run per EV, so a sweep costs a few frames of sensor + ISP time.

`ev_sweep_job` is a long job (workbench.jobs): it yields Progress per EV, checks the cancel token
before each EV (a cancelled sweep raises JobCancelled and returns nothing), and returns one
EVPoint per EV in the order given.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import ParameterError
from workbench.jobs import CancelToken, Job, Progress
from workbench.sensor.snr import snr_dB

THUMBNAIL_WIDTH_PX = 160


@dataclass(frozen=True)
class EVPoint:
    """One EV of the sweep.

    exposure_s: the exposure used (mean over the CFA tile for per-channel exposure).
    mean_level: mean DN / max DN, 0–1.  fraction_clipped: pixels at the largest code.
    snr_dB: 20·log10 of the mean unclipped pixel's electrons over its noise by the sensor's noise
        model (shot, dark current, read noise, DSNU, PRNU as noise_flag enables them); NaN when no
        pixel is unclipped or the sensor is noise-free.
    thumbnail: the sRGB image, subsampled to ≤ THUMBNAIL_WIDTH_PX wide, H×W×3 uint8."""

    ev: float
    exposure_s: float
    mean_dn: float
    mean_level: float
    fraction_clipped: float
    snr_dB: float
    thumbnail: np.ndarray


def ev_values(start: float, stop: float, step: float) -> list[float]:
    """start, start+step, … up to stop (inclusive, within rounding): −4, 4, 1 → −4 … +4."""
    if not step > 0:
        raise ParameterError("ev step", step, "must be > 0")
    if not stop >= start:
        raise ParameterError("ev range", (start, stop), "stop must be ≥ start")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    if n > 200:
        raise ParameterError("ev step", step, f"gives {n} exposures; at most 200 are allowed")
    return [round(start + i * step, 9) for i in range(n)]


def thumbnail(srgb: np.ndarray, width_px: int = THUMBNAIL_WIDTH_PX) -> np.ndarray:
    """Subsampled uint8 copy of an sRGB image in [0, 1]."""
    step = max(1, int(math.ceil(srgb.shape[1] / width_px)))
    return np.ascontiguousarray((np.clip(srgb[::step, ::step], 0, 1) * 255 + 0.5).astype(np.uint8))


def ev_sweep_job(project, signal_rate_e_per_s: np.ndarray, wavelengths_nm: np.ndarray,
                 evs: list[float], cancel: CancelToken | None = None,
                 thumbnail_width_px: int = THUMBNAIL_WIDTH_PX) -> Job[list[EVPoint]]:
    """Sweep `evs` on one frame's pixel signal (see the module docstring); thumbnails are at most
    `thumbnail_width_px` wide (the sensor width keeps the full image)."""
    from workbench.isp import sensor_image_to_srgb
    from workbench.sensor import resolve_exposure, signal_rate_to_sensor_image
    exp = project.experiment
    base = project.sensor.updated(auto_exposure_method=exp.auto_exposure_method,
                                  auto_exposure_level=exp.auto_exposure_level, exposure_s=None)
    points = []
    for i, ev in enumerate(evs):
        if cancel is not None:
            cancel.check()
        yield Progress(i, len(evs), f"EV {ev:+g}")
        sensor = base.updated(ev_bias=ev)
        exposure_s = resolve_exposure(signal_rate_e_per_s, sensor)
        image = signal_rate_to_sensor_image(signal_rate_e_per_s, sensor, exposure_s, wavelengths_nm=wavelengths_nm)
        isp = sensor_image_to_srgb(image, project.isp)
        clipped = image.dn >= image.max_dn
        t = float(np.mean(image.exposure_s))
        unclipped = image.electrons[~clipped]
        points.append(EVPoint(ev=float(ev), exposure_s=t, mean_dn=float(image.dn.mean()),
                              mean_level=float(image.dn.mean() / image.max_dn),
                              fraction_clipped=float(clipped.mean()),
                              snr_dB=snr_dB(float(unclipped.mean()) if unclipped.size else 0.0, sensor, t),
                              thumbnail=thumbnail(isp.srgb, thumbnail_width_px)))
    yield Progress(len(evs), len(evs), "done")
    return points


def draw_ev_sweep(fig, points: list[EVPoint]) -> None:
    """Mean level, clipped fraction (left axis, 0–1) and SNR (right axis, dB) against EV."""
    ax = fig.add_subplot()
    ev = [p.ev for p in points]
    ax.plot(ev, [p.mean_level for p in points], "o-", label="mean level (DN / max)")
    ax.plot(ev, [p.fraction_clipped for p in points], "s-", color="tab:red", label="clipped fraction")
    ax.set(xlabel="exposure bias (EV)", ylabel="fraction", ylim=(-0.02, 1.02))
    ax2 = ax.twinx()
    ax2.plot(ev, [p.snr_dB for p in points], "^--", color="tab:green", label="SNR (dB)")
    ax2.set_ylabel("SNR of the mean unclipped pixel (dB)")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=7, loc="upper left")
    ax.set_title("Exposure-bias sweep")
