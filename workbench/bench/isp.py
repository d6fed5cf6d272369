"""`workbench bench isp`: ISP speed per stage and method on a 640×480 Bayer frame, and its error
(our bilinear against colour-demosaicing's; ΔE2000 of a Macbeth chart through the pipeline)."""
from __future__ import annotations

import numpy as np

from workbench.bench import BenchResult, register_bench
from workbench.bench.timing import median_times_ms
from workbench.isp.color import fit_sensor_to_xyz, macbeth_responses, srgb_encode
from workbench.isp.demosaic import DEMOSAIC_METHODS, demosaic_bilinear
from workbench.isp.params import ISPParams
from workbench.isp.process import sensor_image_to_srgb, linear_to_xyz
from workbench.sensor.image import SensorImage
from workbench.spectra import DEFAULT_WAVELENGTHS_NM

RGGB = np.array([[0, 1], [1, 2]])


def _gaussian_rgb_qe(wl: np.ndarray) -> np.ndarray:
    """A typical RGB camera QE: Gaussians at 600/535/455 nm (σ 35/35/30 nm), peaks 0.5/0.6/0.5."""
    return np.stack([0.5 * np.exp(-0.5 * ((wl - 600) / 35) ** 2), 0.6 * np.exp(-0.5 * ((wl - 535) / 35) ** 2),
                     0.5 * np.exp(-0.5 * ((wl - 455) / 30) ** 2)], axis=1)


def _sensor_image(linear: np.ndarray, qe: np.ndarray, wl: np.ndarray, max_dn: float = 255.0) -> SensorImage:
    h, w, _ = linear.shape
    idx = np.tile(RGGB, (h // 2 + 1, w // 2 + 1))[:h, :w]
    dn = np.rint(np.take_along_axis(linear, idx[..., None], axis=2)[..., 0] * max_dn).astype(np.float32)
    zeros = np.zeros_like(dn)
    return SensorImage(electrons=zeros, volts=zeros, dn=dn, cfa_tile=RGGB, channel_names=["R", "G", "B"],
                       pattern="RGGB", qe=qe, wavelengths_nm=wl, exposure_s=0.01, max_dn=max_dn)


def _macbeth_delta_e(qe: np.ndarray, wl: np.ndarray, patch_px: int = 16) -> tuple[float, float]:
    import colour
    S, s_white, X, x_white = macbeth_responses(qe, wl)
    img = (S / s_white.max()).reshape(4, 6, 3).repeat(patch_px, 0).repeat(patch_px, 1)
    res = sensor_image_to_srgb(_sensor_image(img, qe, wl, max_dn=4095.0), ISPParams(illuminant_correction="none"))
    m = patch_px // 4
    means = np.array([res.srgb[r * patch_px + m:(r + 1) * patch_px - m,
                               c * patch_px + m:(c + 1) * patch_px - m].reshape(-1, 3).mean(0)
                      for r in range(4) for c in range(6)])
    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    de = colour.delta_E(colour.XYZ_to_Lab(colour.sRGB_to_XYZ(means), d65),
                        colour.XYZ_to_Lab(X / x_white[1], d65), method="CIE 2000")
    return float(de.mean()), float(de.max())


@register_bench("isp", help="ISP stage timings on 640×480 and demosaic / colour errors")
def bench_isp(args) -> BenchResult:
    quick = bool(getattr(args, "quick", False))
    h, w, repeats = (120, 160, 5) if quick else (480, 640, 30)
    wl = DEFAULT_WAVELENGTHS_NM
    qe = _gaussian_rgb_qe(wl)
    rng = np.random.default_rng(0)
    # a smooth random scene (blurred noise) so demosaic and colour work on realistic data
    coarse = rng.random((h // 8 + 1, w // 8 + 1, 3))
    scene = np.clip(coarse.repeat(8, 0).repeat(8, 1)[:h, :w], 0.0, 1.0)
    image = _sensor_image(scene, qe, wl)
    raw = image.dn / np.float32(image.max_dn)
    linear, _ = demosaic_bilinear(raw, RGGB, 3)
    fit = fit_sensor_to_xyz(qe, wl)
    rows = []

    def row(stage, fn, reps=repeats, **extra):
        wall, cpu = median_times_ms(fn, reps)
        rows.append({"stage": stage, "size": f"{w}x{h}", "median_ms": wall, "cpu_ms": cpu, **extra})

    import colour_demosaicing
    ref = colour_demosaicing.demosaicing_CFA_Bayer_bilinear(raw, "RGGB")
    err = float(np.abs(linear[1:-1, 1:-1] - ref[1:-1, 1:-1]).max())
    row("demosaic bilinear (ours)", lambda: demosaic_bilinear(raw, RGGB, 3), max_err_vs_colour_demosaicing=err)
    row("demosaic bilinear (colour-demosaicing)",
        lambda: colour_demosaicing.demosaicing_CFA_Bayer_bilinear(raw, "RGGB"))
    for name in DEMOSAIC_METHODS:
        if name != "bilinear":
            row(f"demosaic {name}", lambda n=name: DEMOSAIC_METHODS[n](raw, RGGB, 3, ["R", "G", "B"]),
                reps=max(3, repeats // 6))
    row("sensor→XYZ matrix", lambda: linear_to_xyz(linear, fit.matrix))
    row("sRGB encode", lambda: srgb_encode(linear))
    for correction in ("none", "gray_world"):
        params = ISPParams(illuminant_correction=correction)
        row(f"sensor_image_to_srgb bilinear + matrix + {correction} + sRGB", lambda p=params: sensor_image_to_srgb(image, p))
    de_mean, de_max = _macbeth_delta_e(qe, wl)
    notes = [f"Macbeth chart under D65, Gaussian RGB QE, full pipeline: ΔE2000 mean {de_mean:.2f}, "
             f"max {de_max:.2f} (colour fit condition {fit.condition:.3g})",
             "cpu_ms = median process CPU time, all threads (robust to other processes on a shared machine)"]
    return BenchResult(title="ISP: time per stage and error", rows=rows, notes=notes,
                       extra={"delta_e_2000_mean": de_mean, "delta_e_2000_max": de_max})
